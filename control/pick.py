"""What a pick is made of: the request, the arm it runs on, the timed plan, and the result.

The data of :mod:`control.planner`, kept apart so that an executor (the simulator, a real
robot's driver) needs only this module to run a plan.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import KW_ONLY, dataclass

import numpy as np
import pinocchio as pin

from control.collision import AnyObstacle
from control.errors import InvalidInputError
from control.trajectory import JointTrajectory
from robots.description import RobotDescription


class PlanStatus(enum.Enum):
    """Why a pick could or could not be planned."""

    SUCCESS = "success"
    UNREACHABLE = "unreachable"  # no arm has IK solutions for the pre-grasp, grasp and lift
    COLLISION = "collision"  # IK solutions exist, but every path through them collides
    START_IN_COLLISION = "start_in_collision"  # the start configuration already collides
    # a re-plan mid-motion (PickPlanner.replan): the motion from the moving state to the new
    # pre-grasp leaves a joint limit or collides
    RETARGET_FAILED = "retarget_failed"
    # A search stopped by its PlanBudget ends as what it found so far: COLLISION where IK gave
    # candidates (RETARGET_FAILED in a re-plan), else UNREACHABLE; its reason says so.


class GripperCommand(enum.Enum):
    """What the executor does with the gripper before it tracks a segment."""

    NONE = "none"
    OPEN = "open"
    CLOSE = "close"


@dataclass(frozen=True)
class ArmSpec:
    """What the planner needs to know about one arm.

    Args:
        joints: The arm's joint names, base to tip.
        tcp_frame: The tool frame grasps are given for.
        finger_joints: The gripper's joint names (set to the opening when checking collisions).
        max_acceleration: [rad/s^2] per joint name.
        max_jerk: [rad/s^3] per joint name.
        shoulder_frame: The frame whose distance to the grasp decides which arm is nearer.

    """

    joints: tuple[str, ...]
    tcp_frame: str
    finger_joints: tuple[str, ...]
    max_acceleration: Mapping[str, float]
    max_jerk: Mapping[str, float]
    shoulder_frame: str


@dataclass(frozen=True)
class PlanBudget:
    """The most work one planning call spends on a pick before it gives up (issue 65).

    A grasp no arm can take is searched exhaustively: every grasp (a bottle's 17 turned
    alternatives and its own), arm, pre-grasp back-off and IK solution, each candidate's
    approach and retreat through every via pose; up to 576 IK attempts and as many checked
    candidates on the YuMi, a weakly trained model's grasps 5.5-6 s a trial against 0.3-0.5 s.
    The search keeps its order and stops only once a count is spent (checked before each
    candidate, and before each arm and back-off's IK attempts), so a pick planned within the
    budget is planned exactly as without one.

    The defaults are about twice the most a planned pick has needed: 101 candidates and 136
    IK attempts (an oracle's spray bottle, YuMi ``multiple`` seed 0 trial 6, planned on its
    fourth alternative after 9.5 s), the Panda's most 87 and 104 (``multiple``, its sixth
    alternative), over 330 oracle picks at seed 0 (YuMi ``single``, ``selected-type``,
    ``selected-position``, ``single-moved``, ``multiple``; Panda ``single``, ``multiple``);
    all but 8 needed 16 candidates or fewer. 288 IK attempts are half a bottle's whole search
    on the YuMi; a grasp's own search over both arms and back-offs (32 attempts) always fits.

    Args:
        max_candidates: Candidate plans (IK solutions of pre-grasp, grasp and lift) whose
            segments are planned and checked.
        max_ik_attempts: Pre-grasp IK attempts (one per seed, for the grasp and its half
            turn), found or not; no arm and back-off begins its attempts past this many.

    """

    max_candidates: int = 200
    max_ik_attempts: int = 288

    def __post_init__(self) -> None:
        for name in ("max_candidates", "max_ik_attempts"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InvalidInputError(name, value, "an integer >= 1")


@dataclass(frozen=True)
class PickPlannerConfig:
    """Tunables of the pick planner.

    Args:
        pregrasp_distance_m: Default back-off of the pre-grasp along the approach axis [m].
        lift_height_m: How far the lift raises the grasp [m] (success asks for >= 0.05 m).
        transit_velocity_scale: Fraction of the joint velocity limits for approach and retreat.
        straight_velocity_scale: Fraction for descend and lift, which run close to objects.
        dt_s: Sampling period of the trajectories [s]; the simulator tracks one sample per step.
        ik_solutions_per_grasp: Distinct IK solutions tried per arm and gripper flip.
        max_straight_deviation_m: How far the TCP may leave the straight line in descend/lift
            before the segment is split into Cartesian waypoints [m].
        max_joint_jump_rad: Largest joint change allowed between the pre-grasp and grasp (or
            grasp and lift) solutions; a larger one means IK jumped to another branch.
        via_heights_m: Heights above the pre-grasp (or lift) pose of the via poses tried, in
            order, when the direct approach (or retreat) collides [m].
        pregrasp_scales: Fractions of the pre-grasp distance tried in order, per arm: near the
            robot a long back-off can put the wrist on the robot's own body, while far away a
            short one can bring the open fingers down next to the target.
        seed: Seeds the random IK restarts.
        budget: The most work one pick's planning spends (:class:`PlanBudget`); None searches
            every grasp, arm and IK solution however long it takes.

    """

    pregrasp_distance_m: float = 0.08
    lift_height_m: float = 0.10
    transit_velocity_scale: float = 1.0
    straight_velocity_scale: float = 0.4
    dt_s: float = 1.0 / 240.0
    ik_solutions_per_grasp: int = 4
    max_straight_deviation_m: float = 0.005
    max_joint_jump_rad: float = 1.0
    via_heights_m: tuple[float, ...] = (0.12, 0.22)
    pregrasp_scales: tuple[float, ...] = (1.0, 0.6)
    seed: int = 0
    budget: PlanBudget | None = PlanBudget()

    def __post_init__(self) -> None:
        if self.budget is not None and not isinstance(self.budget, PlanBudget):
            raise InvalidInputError("budget", self.budget, "a PlanBudget or None")
        positive = ("pregrasp_distance_m", "lift_height_m", "dt_s", "max_straight_deviation_m",
                    "max_joint_jump_rad")
        for name in positive:
            if getattr(self, name) <= 0.0:
                raise InvalidInputError(name, getattr(self, name), "a value > 0")
        if not self.pregrasp_scales or not all(0.0 < f <= 1.0 for f in self.pregrasp_scales):
            raise InvalidInputError("pregrasp_scales", self.pregrasp_scales,
                                    "a non-empty tuple of fractions in (0, 1]")
        for name in ("transit_velocity_scale", "straight_velocity_scale"):
            if not 0.0 < getattr(self, name) <= 1.0:
                raise InvalidInputError(name, getattr(self, name), "a fraction in (0, 1]")
        if self.ik_solutions_per_grasp < 1:
            raise InvalidInputError("ik_solutions_per_grasp", self.ik_solutions_per_grasp, ">= 1")


@dataclass(frozen=True)
class PickRequest:
    """One pick to plan.

    Args:
        T_world_grasp: TCP pose at the grasp (z axis = approach direction).
        q_start: Full start configuration of the robot.
        obstacles: Everything the robot must not touch: table, other objects.
        target_obstacles: The target's own shapes: avoided on the approach, ignored from the
            descend on (the fingers close around the target and carry it).
        alternatives: Other TCP poses that pick the target as well (e.g. a rotationally
            symmetric object's grasp turned about its axis), tried in order when the primary
            grasp fails on every arm.
        finger_opening_m: Finger joint value while approaching [m] (gap = 2 x this); None:
            each finger's upper limit, the hand fully open.
        pregrasp_distance_m: Back-off for this grasp; None takes the planner's default.
        arms: The arms that may pick (empty: every arm, nearer first); a re-plan mid-motion
            keeps to the arm that moves.

    """

    T_world_grasp: pin.SE3
    q_start: np.ndarray
    _: KW_ONLY
    obstacles: tuple[AnyObstacle, ...] = ()
    target_obstacles: tuple[AnyObstacle, ...] = ()
    alternatives: tuple[pin.SE3, ...] = ()
    finger_opening_m: float | None = None
    pregrasp_distance_m: float | None = None
    arms: tuple[str, ...] = ()


@dataclass(frozen=True)
class PlanSegment:
    """One timed segment of a plan, over the arm's joints."""

    name: str
    trajectory: JointTrajectory
    gripper_before: GripperCommand = GripperCommand.NONE


@dataclass(frozen=True)
class PickPlan:
    """A collision-checked pick for one arm."""

    arm: str
    segments: tuple[PlanSegment, ...]
    q_grasp: np.ndarray  # full configuration at the grasp
    T_world_grasp: pin.SE3  # the grasp actually used (possibly turned 180 deg about z)

    def segment(self, name: str) -> PlanSegment:
        """The segment called ``name``."""
        for segment in self.segments:
            if segment.name == name:
                return segment
        raise InvalidInputError("segment", name, ", ".join(s.name for s in self.segments))

    @property
    def duration_s(self) -> float:
        """Total duration of all segments [s]."""
        return sum(s.trajectory.duration_s for s in self.segments)


@dataclass(frozen=True)
class PlanResult:
    """A plan, or the reason there is none."""

    status: PlanStatus
    reason: str
    plan: PickPlan | None = None
    planning_time_s: float = 0.0
    candidates_tried: int = 0
    ik_attempts: int = 0  # pre-grasp IK attempts (see PlanBudget)

    @property
    def ok(self) -> bool:
        """Whether a plan was found."""
        return self.status is PlanStatus.SUCCESS


def build_arm_specs(robot: RobotDescription) -> dict[str, ArmSpec]:
    """The planner's view of each of ``robot``'s arms, by arm name."""
    return {
        arm.name: ArmSpec(arm.joints, arm.tcp_frame, arm.gripper.finger_joints,
                          arm.max_acceleration_rad_s2, arm.max_jerk_rad_s3, arm.shoulder_frame)
        for arm in robot.arms
    }
