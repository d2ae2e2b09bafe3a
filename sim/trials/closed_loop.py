"""Closed-loop picks (issue 36): the model re-predicts while the arm approaches.

An open-loop pick plans once from the first image and runs blind. In closed loop the head
camera renders every ``1 / replan_hz`` s of the approach (its depth self-filtered: the arm is in
view), the model predicts again, and when the grasp moved beyond the thresholds the pick is
planned again for the moving arm and its approach re-targeted from the arm's state as it is
(:meth:`control.planner.PickPlanner.replan`: ruckig from position, velocity and acceleration,
every sample collision-checked against the latest depth image's obstacles). A re-plan that
fails keeps the plan being followed, and the record says so. Once the arm rests at its
pre-grasp the loop ends: the descent follows the last plan (the hand is over the target and
hides it from the head camera).

A task's disturbance (:mod:`sim.tasks.disturbance`) moves the target at a drawn moment of the
approach, in open and in closed loop alike, so the two are compared on the same picks.
"""

from __future__ import annotations

import enum
import math
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from control.pick import PickPlan
from control.retarget import JointState, trajectory_state
from perception.camera import RgbdFrame
from perception.catalog import ObjectSpec
from perception.grasp_judge import GraspVerdict, judge_grasp, yaw_of
from perception.interface import PerceptionModel, Prediction
from perception.poses import Pose
from robots import yumi
from sim.errors import InvalidInputError
from sim.tasks.disturbance import DisturbanceDraw
from sim.tasks.scene_sampling import Scene
from sim.trials.execution import StepWatch
from sim.trials.pick_results import (
    PlannedPick,
    Sighting,
    as_recorded,
    grasp_angle_rad,
    pose_json,
)
from sim.world.yumi_world import World

MOVE_CLEARANCE_M = 0.10
"""Nearest a moved target's centre comes to another object's [m]: the objects reach 4.5-7 cm
from their centres (the mug's handle 6.7 cm), so two at 10 cm may touch but do not overlap."""
MAX_REPLAN_HZ = 60.0
"""Fastest re-prediction rate [Hz]: a quarter of the 240 Hz physics, and above what a cycle
(render, inference, plan) sustains on one core."""


class Loop(enum.Enum):
    """Whether a pick looks again while the arm moves."""

    OPEN = "open"  # one image, one plan, run blind (the paper's)
    CLOSED = "closed"  # re-predict during the approach, re-target when the grasp moved


@dataclass(frozen=True)
class LoopSettings:
    """How picks close the loop.

    Args:
        loop: Open (the default) or closed.
        replan_hz: Re-predictions per second of the approach, closed loop only.
        move_threshold_m: A new grasp this far [m] from the one followed re-targets the arm;
            nearer, the arm keeps its plan (the model's frame-to-frame jitter is a few mm).
        turn_threshold_deg: The same for its turn about the approach axis [deg].

    """

    loop: Loop = Loop.OPEN
    replan_hz: float = 10.0
    move_threshold_m: float = 0.01
    turn_threshold_deg: float = 10.0

    def __post_init__(self) -> None:
        if not isinstance(self.loop, Loop):
            raise InvalidInputError("loop", self.loop, "open or closed")
        if not (math.isfinite(self.replan_hz) and 0.0 < self.replan_hz <= MAX_REPLAN_HZ):
            raise InvalidInputError("replan_hz", self.replan_hz,
                                    f"a rate in (0, {MAX_REPLAN_HZ:g}] Hz")
        for name in ("move_threshold_m", "turn_threshold_deg"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise InvalidInputError(name, value, "a finite value >= 0")

    def to_json(self) -> dict[str, Any]:
        """The settings as a record keeps them (open loop: just that)."""
        if self.loop is Loop.OPEN:
            return {"loop": "open"}
        return {"loop": "closed", "replan_hz": self.replan_hz,
                "move_threshold_m": self.move_threshold_m,
                "turn_threshold_deg": self.turn_threshold_deg}


class Reaction(enum.Enum):
    """What the arm did with one re-prediction."""

    HELD = "held"  # the grasp within the thresholds of the one followed: the plan stands
    RETARGETED = "retargeted"  # re-planned and re-targeted from the moving state
    KEPT = "kept"  # the grasp moved, but no re-plan was found: the last good plan stands
    UNSEEN = "unseen"  # the model gave nothing the robot can act on: the last plan stands


@dataclass(frozen=True)
class Reprediction:
    """One re-prediction of a closed-loop approach, as the pick's record keeps it.

    Args:
        time_s: Since the approach began [s].
        reaction: What the arm did.
        reason: Why, in words (the planner's or the model's reason where it failed).
        predicted: The grasp the model gave; None where it gave none.
        truth: The target's true grasp then (the referee's).

    """

    time_s: float
    reaction: Reaction
    reason: str
    predicted: Pose | None
    truth: Pose

    def to_record(self) -> dict[str, Any]:
        """JSON-able: time, reaction, reason, the grasp predicted, its error then."""
        data: dict[str, Any] = {"time_s": round(self.time_s, 4),
                                "reaction": self.reaction.value, "reason": self.reason}
        if self.predicted is not None:
            data["predicted"] = pose_json(self.predicted.position, self.predicted.rotation)
            data["position_error_m"] = float(np.linalg.norm(
                self.predicted.position - self.truth.position))
        return data


@dataclass(frozen=True)
class Moved:
    """What a disturbance did to the target, as the pick's record keeps it."""

    time_s: float
    draw: DisturbanceDraw
    before: Pose
    after: Pose

    def to_record(self) -> dict[str, Any]:
        """JSON-able: when, what was drawn, where the target went."""
        shift = self.after.position - self.before.position
        return {"time_s": round(self.time_s, 4), "moved_m": round(float(np.hypot(*shift[:2])), 6),
                "before": pose_json(self.before.position, self.before.rotation),
                "after": pose_json(self.after.position, self.after.rotation)}


class LoopRunner(Protocol):
    """What a loop needs of the trial runner (:class:`~sim.trials.trial_runner.TrialRunner`).

    Its world and model, to see again, read and plan as the first image was; declared here so
    that the runner, which makes the loops, is not imported by them.
    """

    world: World
    model: PerceptionModel
    observer: Any  # a TrialObserver (or None): its ``saw`` gets each re-prediction

    def sight(self, body: int, self_filter: bool = False) -> Sighting:
        """The head camera's frame now and the referee's note of ``body``."""

    def read_grasp(self, prediction: Prediction, number: int, total: int) -> PlannedPick:
        """The grasp and grip a prediction states for a pick, or why none."""

    def plan_pick(self, frame: RgbdFrame, prediction: Prediction, number: int, total: int,
                  moving: JointState | None = None) -> PlannedPick:
        """The plan phase from a frame and a prediction; ``moving``: re-planned mid-motion."""

    def truth(self, body: int) -> Pose:
        """The canonical grasp of ``body`` where it lies now (the referee's)."""


class ApproachLoop:
    """Tracks a pick's approach with re-predictions and a disturbance: an ``ApproachFollower``.

    Made per pick by the trial runner; :attr:`repredictions`, :attr:`moved` and
    :attr:`followed` (the plan phase of the plan followed last) are read after the pick.
    """

    def __init__(self, runner: LoopRunner, scene: Scene, number: int, total: int, body: int,
                 first: PlannedPick, settings: LoopSettings,
                 disturbance: DisturbanceDraw | None) -> None:
        self.runner, self.scene, self.number, self.total = runner, scene, number, total
        self.body, self.settings, self.disturbance = body, settings, disturbance
        self.followed = first
        self.repredictions: list[Reprediction] = []
        self.moved: Moved | None = None
        self.end: tuple[Pose, float] | None = None  # the target's grasp and yaw at the end

    def __call__(self, plan: PickPlan, watch: StepWatch) -> tuple[PickPlan, bool]:
        """Runs the approach of ``plan``; (the plan followed at its end, stopped by ``watch``)."""
        world = self.runner.world
        dt_s = world.config.time_step_s
        approach = plan.segments[0].trajectory
        closed = self.settings.loop is Loop.CLOSED
        tick = max(1, round(1.0 / (self.settings.replan_hz * dt_s))) if closed else 0
        disturb_at = None if self.disturbance is None else round(
            self.disturbance.time_fraction * (len(approach.times_s) - 1))
        joints = yumi.ARM_JOINTS[plan.arm]
        if self.disturbance is not None and self.disturbance.slides:  # from the image on
            world.keep_sliding(self.body, self.disturbance.velocity_xy_m_s)
        try:
            return self._follow(plan, watch, tick, disturb_at, joints)
        finally:  # the belt stops before the fingers close: a sliding object has no friction
            if self.disturbance is not None and self.disturbance.slides:
                world.stop_sliding(self.body)
            self.end = (self.runner.truth(self.body),
                        yaw_of(world.object_pose(self.body).rotation))

    def judged(self, spec: ObjectSpec) -> GraspVerdict | None:
        """The grasp judge on the grasp followed last, against the target at the approach's end.

        In open loop with a disturbance: the first grasp against the moved target.
        """
        grasp = self.followed.predicted
        if grasp is None or self.end is None:
            return None
        truth, yaw_rad = self.end
        return judge_grasp(spec, truth, as_recorded(grasp), yaw_rad)

    def _follow(self, plan: PickPlan, watch: StepWatch, tick: int, disturb_at: int | None,
                joints: tuple[str, ...]) -> tuple[PickPlan, bool]:
        world, approach = self.runner.world, plan.segments[0].trajectory
        dt_s = world.config.time_step_s
        step = k = 0  # steps since the approach began; the sample of ``approach`` reached
        while k < len(approach.times_s) - 1:
            events = [e for e in (disturb_at, (step // tick + 1) * tick if tick else None)
                      if e is not None and e > step]
            run = min([len(approach.times_s) - 1 - k, *(e - step for e in events)])
            rows = slice(k + 1, k + 1 + run)
            report = world.robot.track(joints, approach.positions[rows],
                                       approach.velocities[rows], on_step=watch)
            step, k = step + report.steps, k + report.steps
            if report.stopped_early:
                return plan, True
            if step == disturb_at and self.moved is None and self.disturbance is not None \
                    and self.disturbance.moves:
                self._disturb(step * dt_s)
            if tick and step % tick == 0 and k < len(approach.times_s) - 1:
                replanned = self._repredict(step * dt_s, trajectory_state(approach, k))
                if replanned is not None:
                    plan, approach, k = replanned, replanned.segments[0].trajectory, 0
        return plan, False

    def _disturb(self, time_s: float) -> None:
        """Moves the target as drawn: teleported (:meth:`World.move_object`), unsettled.

        Where the drawn direction would bring it within :data:`MOVE_CLEARANCE_M` of another
        object (or off the table), the move is turned by a quarter, a half, three quarters,
        the first that keeps clear, so a move never lands on a neighbour; the record says
        where it went.
        """
        draw, world = self.disturbance, self.runner.world
        assert draw is not None
        before = world.object_pose(self.body)
        others = [world.object_pose(b).position[:2] for b in world.objects if b != self.body]
        shift = np.array([draw.dx_m, draw.dy_m])
        for quarter in range(4):
            c, s_ = math.cos(quarter * math.pi / 2), math.sin(quarter * math.pi / 2)
            turned = np.array([[c, -s_], [s_, c]]) @ shift
            landing = before.position[:2] + turned
            if all(np.linalg.norm(landing - o) >= MOVE_CLEARANCE_M for o in others) and \
                    world.on_table(landing):
                shift = turned
                break
        # no settling pause: the arm keeps moving while the target drops its 2 mm
        after = world.move_object(self.body, float(shift[0]), float(shift[1]), draw.dyaw_rad,
                                  settle_s=0.0)
        self.moved = Moved(time_s, draw, before, after)

    def _repredict(self, time_s: float, state: JointState) -> PickPlan | None:
        """One re-prediction; the new plan to follow if the arm re-targets, else None."""
        runner = self.runner
        sighting = runner.sight(self.body, self_filter=True)
        try:
            prediction = runner.model.predict_frame(sighting.frame, self.scene.given)
        except Exception as error:  # the model's failure: recorded, the arm keeps its plan
            last = traceback.extract_tb(error.__traceback__)[-1]
            return self._note(time_s, Reaction.UNSEEN, f"predict raised {type(error).__name__}: "
                              f"{error} (line {last.lineno})", None, sighting.truth)
        read = runner.read_grasp(prediction, self.number, self.total)
        if runner.observer is not None:
            runner.observer.saw(sighting.frame, prediction if read.predicted is not None else None)
        if read.outcome is not None or read.predicted is None:
            return self._note(time_s, Reaction.UNSEEN, read.reason, read.predicted,
                              sighting.truth)
        followed = self.followed.predicted
        assert followed is not None  # a followed plan was planned from a grasp
        moved_m = float(np.linalg.norm(read.predicted.position - followed.position))
        turned_deg = math.degrees(grasp_angle_rad(followed.rotation, read.predicted.rotation))
        if moved_m <= self.settings.move_threshold_m and \
                turned_deg <= self.settings.turn_threshold_deg:
            return self._note(time_s, Reaction.HELD, f"moved {100 * moved_m:.1f} cm, turned "
                              f"{turned_deg:.0f} deg", read.predicted, sighting.truth)
        planned = runner.plan_pick(sighting.frame, prediction, self.number, self.total,
                                   moving=state)
        if planned.plan is None:
            return self._note(time_s, Reaction.KEPT, planned.reason, read.predicted,
                              sighting.truth)
        self.followed = planned
        self._note(time_s, Reaction.RETARGETED, f"moved {100 * moved_m:.1f} cm, turned "
                   f"{turned_deg:.0f} deg", read.predicted, sighting.truth)
        return planned.plan

    def _note(self, time_s: float, reaction: Reaction, reason: str, predicted: Pose | None,
              truth: Pose) -> PickPlan | None:
        """Records one re-prediction; None: no new plan to follow."""
        self.repredictions.append(Reprediction(time_s, reaction, reason, predicted, truth))
        return None

    def to_record(self) -> dict[str, Any]:
        """What the pick's record keeps of the loop.

        Its re-predictions (closed loop), the disturbance, and ``executed``: the grasp run
        against the target's grasp at the approach's end.
        """
        data: dict[str, Any] = {}
        grasp = self.followed.predicted
        if grasp is not None and self.end is not None:
            data["executed"] = {
                "predicted": pose_json(grasp.position, grasp.rotation),
                "truth": pose_json(self.end[0].position, self.end[0].rotation),
                "position_error_m": float(np.linalg.norm(grasp.position
                                                         - self.end[0].position))}
        if self.settings.loop is Loop.CLOSED:
            data["repredictions"] = [r.to_record() for r in self.repredictions]
        if self.moved is not None:
            data["disturbance"] = self.moved.to_record()
        return data


def reactions(records: Sequence[dict[str, Any]]) -> dict[str, int]:
    """How many re-predictions of ``records`` (picks' ``repredictions``) led to each reaction."""
    counts = {reaction.value: 0 for reaction in Reaction}
    for record in records:
        counts[record["reaction"]] += 1
    return counts
