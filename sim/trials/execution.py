"""Runs a pick plan in the simulator and judges it by physics.

The robot tracks each segment at the physics rate. Until the gripper closes, any contact of the
robot with the table or with an object other than the target ends the pick as ``COLLIDED``
(the plan promised a clear path). After the lift the robot holds still for ``hold_s``: the pick
succeeds if the target's lowest point stayed at least ``lift_success_m`` above where it started
and the target stayed pinched between both fingers the whole time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from control.pick import GripperCommand, PickPlan
from sim.errors import InvalidInputError
from sim.trials.records import TrialOutcome
from sim.world.world_config import MAX_WAIT_S
from sim.world.yumi_world import World

TOUCH_DISTANCE_M = 1e-4
"""Contact points closer than this count as touching [m]."""

StepWatch = Callable[[int], bool]
"""Called after each physics step of a segment; True stops the robot (it touched something)."""

@dataclass(frozen=True)
class FollowedApproach:
    """How an approach tracked by an :data:`ApproachFollower` ended.

    Args:
        plan: The plan followed at the approach's end: its later segments are run next.
        touched: The contact watch stopped the robot.
        halted: Why the arm stopped short of a pre-grasp it could descend from, the outcome
            that ends the pick then (e.g. no re-plan reached the moved target); None: it
            reached one.

    """

    plan: PickPlan
    touched: bool = False
    halted: tuple[TrialOutcome, str] | None = None


ApproachFollower = Callable[[PickPlan, StepWatch], FollowedApproach]
"""Tracks a plan's approach in its own way (re-targeting it, moving the target; see
:mod:`sim.trials.closed_loop.loop`): given the plan and the contact watch, says how it ended."""


@dataclass(frozen=True)
class ExecutionSettings:
    """How a pick is executed and judged.

    Args:
        lift_success_m: Rise of the target's lowest point that counts as lifted [m].
        hold_s: How long the target must stay lifted and pinched [s].
        close_timeout_s: Longest wait for the fingers to stop after closing [s].
        check_every_steps: Physics steps between two success checks during the hold.

    """

    lift_success_m: float = 0.05
    hold_s: float = 1.0
    close_timeout_s: float = 1.5
    check_every_steps: int = 6

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lift_success_m) and self.lift_success_m > 0.0):
            raise InvalidInputError("lift_success_m", self.lift_success_m, "a finite rise > 0 m")
        for name in ("hold_s", "close_timeout_s"):  # each a wait of the physics: bounded
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 < value <= MAX_WAIT_S):
                raise InvalidInputError(name, value, f"a time in (0, {MAX_WAIT_S}] s")
        if self.check_every_steps < 1:
            raise InvalidInputError("check_every_steps", self.check_every_steps, ">= 1")


@dataclass(frozen=True)
class ExecutionResult:
    """What happened when a plan ran: outcome, why, and how high the target rose [m]."""

    outcome: TrialOutcome
    reason: str
    lift_m: float


class _ContactWatch:
    """Per-step check that the robot touches nothing it should not before the grasp."""

    def __init__(self, world: World, forbidden: dict[int, str]) -> None:
        self.world, self.forbidden = world, forbidden
        self.hit: str | None = None

    def __call__(self, step: int) -> bool:
        client, robot = self.world.client, self.world.robot.body_id
        for body, name in self.forbidden.items():
            # PyBullet also reports points a little apart (inside its contact margin): a touch
            # is a point at (or within 0.1 mm of) contact.
            points = [p for p in client.getContactPoints(bodyA=robot, bodyB=body)
                      if p[8] < TOUCH_DISTANCE_M]
            if points:
                index = points[0][3]
                link = self.world.description.base_link if index < 0 else \
                    client.getJointInfo(robot, index)[12].decode()
                self.hit = f"{link} touched {name}"
                return True
        return False


def execute_pick(
    world: World,
    plan: PickPlan,
    target_body: int,
    opening_m: float,
    settings: ExecutionSettings,
    follow: ApproachFollower | None = None,
) -> ExecutionResult:
    """Runs ``plan`` on ``world`` and judges whether ``target_body`` was picked.

    ``follow`` tracks the approach instead of tracking it as planned: a closed loop may hand
    back another plan, whose later segments are then run, and the target may have moved on the
    way, so its rise is then measured from where it rests when the approach ends.
    """
    robot, arm = world.robot, plan.arm
    start_bottom = world.object_bottom_z_m(target_body)
    forbidden = {world.table_id: "the table"}
    forbidden |= {b: f"the {s.name}" for b, s in world.objects.items() if b != target_body}
    watch = _ContactWatch(world, forbidden)
    segments = plan.segments
    if follow is not None:
        robot.open_gripper(arm, opening_m)  # the approach's gripper command
        followed = follow(plan, watch)
        if followed.touched or followed.halted is not None:
            outcome, why = followed.halted or (TrialOutcome.COLLIDED, str(watch.hit))
            return ExecutionResult(outcome, f"approach: {why}",
                                   world.object_bottom_z_m(target_body) - start_bottom)
        plan = followed.plan
        start_bottom, segments = world.object_bottom_z_m(target_body), plan.segments[1:]
    joints = world.description.arm(arm).joints
    for segment in segments:
        if segment.name == "retreat":
            break
        if segment.gripper_before is GripperCommand.OPEN:
            robot.open_gripper(arm, opening_m)
        elif segment.gripper_before is GripperCommand.CLOSE:
            if not _close(world, arm, settings):
                return ExecutionResult(TrialOutcome.MISSED, "the gripper closed on nothing",
                                       world.object_bottom_z_m(target_body) - start_bottom)
            watch.forbidden = {}  # once holding the target, contacts are judged by the lift
        trajectory = segment.trajectory
        report = robot.track(joints, trajectory.positions, trajectory.velocities,
                             on_step=watch if watch.forbidden else None)
        if report.stopped_early:
            return ExecutionResult(TrialOutcome.COLLIDED, f"{segment.name}: {watch.hit}",
                                   world.object_bottom_z_m(target_body) - start_bottom)
    return _hold(world, arm, target_body, start_bottom, settings)


def _close(world: World, arm: str, settings: ExecutionSettings) -> bool:
    """Closes the gripper until the fingers stop; False if they met nothing."""
    robot = world.robot
    robot.close_gripper(arm)
    steps = round(settings.close_timeout_s / world.config.time_step_s)
    previous = robot.gripper_opening_m(arm)
    still = 0
    for _ in range(steps):
        world.step()
        opening = robot.gripper_opening_m(arm)
        still = still + 1 if abs(opening - previous) < 2e-5 else 0
        previous = opening
        if still >= 12:  # 50 ms without motion: the fingers are squeezing, or shut
            break
    return previous > 1e-3


def _hold(
    world: World, arm: str, target: int, start_bottom_m: float, settings: ExecutionSettings
) -> ExecutionResult:
    robot = world.robot
    rise = world.object_bottom_z_m(target) - start_bottom_m
    pinched = target in robot.gripper_contacts(arm).held
    if rise < settings.lift_success_m:
        outcome = TrialOutcome.GRASP_SLIPPED if pinched else TrialOutcome.MISSED
        return ExecutionResult(outcome, f"the target rose {100 * rise:.1f} cm after the lift "
                               f"(needs {100 * settings.lift_success_m:.0f} cm)", rise)
    steps = round(settings.hold_s / world.config.time_step_s)
    lowest_rise = rise
    for step in range(1, steps + 1):
        world.step()
        if step % settings.check_every_steps and step != steps:
            continue
        rise = world.object_bottom_z_m(target) - start_bottom_m
        lowest_rise = min(lowest_rise, rise)
        if target not in robot.gripper_contacts(arm).held or rise < settings.lift_success_m:
            held_s = step * world.config.time_step_s
            return ExecutionResult(TrialOutcome.GRASP_SLIPPED,
                                   f"the target slipped after {held_s:.2f} s of the hold", rise)
    return ExecutionResult(TrialOutcome.SUCCESS,
                           f"lifted {100 * lowest_rise:.1f} cm and held {settings.hold_s:.1f} s",
                           lowest_rise)
