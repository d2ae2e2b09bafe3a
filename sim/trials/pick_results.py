"""What the trial loop hands along: a pick's plan phase, the pick as it went, the trial's result.

Named results in memory; a trial's :class:`~sim.trials.records.TrialRecord` is where they become
JSON (:meth:`TrialResult.record_fields`), in the format ``trials.jsonl`` has always had: a
field is there when the pick got that far, absent otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from control.collision import AnyObstacle
from control.pick import PickPlan, PlanStatus
from perception.camera import RgbdFrame
from perception.judge.grasp_judge import GraspVerdict
from perception.poses import Pose
from sim.trials.records import TrialOutcome
from sim.world.grip import Grip

POSE_DECIMALS = 6
"""Decimals a record keeps of a pose's numbers (1 µm, 1e-6 of a rotation entry)."""


def pose_json(position: np.ndarray, rotation: np.ndarray | None) -> dict[str, Any]:
    """A pose as rounded JSON-able lists."""
    data: dict[str, Any] = {"position_m": [round(float(v), POSE_DECIMALS) for v in position]}
    if rotation is not None:
        data["rotation"] = [[round(float(v), POSE_DECIMALS) for v in row] for row in rotation]
    return data


def as_recorded(pose: Pose) -> Pose:
    """``pose`` rounded as :func:`pose_json` keeps it."""
    data = pose_json(pose.position, pose.rotation)
    return Pose(np.array(data["position_m"]), np.array(data["rotation"]))


def grasp_angle_rad(truth: np.ndarray, predicted: np.ndarray) -> float:
    """Angle between two TCP orientations, counting the gripper's half-turn symmetry."""
    flip = np.diag([-1.0, -1.0, 1.0])
    return min(float(np.linalg.norm(pin.log3(truth.T @ predicted @ f))) for f in (np.eye(3), flip))


@dataclass(frozen=True)
class PlannedPick:
    """The plan phase of one pick: what the robot decided from its sensors and the model.

    Each field is None where the phase ended before it (a bad prediction has no grip).

    Args:
        outcome: Why the pick ends here (a perception or planning failure); None with a plan.
        reason: The failure's reason.
        predicted: The model's grasp ``T_world_tcp`` for this pick, its rotation made exact.
        grip: How the gripper approaches and closes, from what the model stated.
        raised_m: How far the grasp was raised to keep the fingertips off the table [m].
        obstacles: What the planner was given besides the table (source and size), as the
            record keeps it.
        plan_status: The planner's answer.
        plan: The plan to run; None when the pick ends here.
        traceback: Where the model's predict raised, as Python prints it; None if it did not.
        obstacle_image: The frame's obstacle points per pixel (NaN elsewhere), which a closed
            loop remembers where a later frame cannot see; None without a depth plan.

    """

    outcome: TrialOutcome | None = None
    reason: str = ""
    predicted: Pose | None = None
    grip: Grip | None = None
    raised_m: float | None = None
    obstacles: dict[str, Any] | None = None
    plan_status: PlanStatus | None = None
    plan: PickPlan | None = None
    traceback: str | None = None
    obstacle_image: np.ndarray | None = None


@dataclass(frozen=True)
class PickAttempt:
    """One pick of a trial as it went: what it was for, what was planned, how it ended.

    Args:
        target: The catalog type of the object the task wanted picked.
        truth: That object's canonical grasp when the image was taken: the referee's label,
            never handed to the plan phase.
        planned: The plan phase.
        outcome: How the pick ended.
        reason: Why, in words.
        lift_m: How far the target rose [m]; None if no plan ran.
        verdict: The grasp judge's prediction of the pick from its error alone
            (:mod:`perception.judge.grasp_judge`); None where the model gave no grasp.
        loop: The approach's re-predictions and the target's disturbance, as the record
            keeps them (:meth:`sim.trials.closed_loop.loop.ApproachLoop.to_record`); None for a
            plain open-loop pick.

    """

    target: str
    truth: Pose
    planned: PlannedPick
    outcome: TrialOutcome
    reason: str
    lift_m: float | None = None
    verdict: GraspVerdict | None = None
    loop: dict[str, Any] | None = None

    @property
    def position_error_m(self) -> float | None:
        """Distance between the predicted and the true grasp position [m]; None unpredicted.

        Measured from the prediction as the record keeps it (to 1 µm), so the numbers of
        earlier records are the numbers of new ones.
        """
        if self.planned.predicted is None:
            return None
        predicted = as_recorded(self.planned.predicted)
        return float(np.linalg.norm(predicted.position - self.truth.position))

    @property
    def rotation_error_rad(self) -> float | None:
        """Angle between the predicted and the true grasp [rad] (as recorded); None unpredicted."""
        if self.planned.predicted is None:
            return None
        return grasp_angle_rad(self.truth.rotation, as_recorded(self.planned.predicted).rotation)

    def to_record(self) -> dict[str, Any]:
        """The pick as an entry of a record's ``picks``: the fields it got to, and how it ended."""
        planned = self.planned
        data: dict[str, Any] = {"target": self.target,
                                "truth": pose_json(self.truth.position, self.truth.rotation)}
        if planned.predicted is not None:
            data |= {"predicted": pose_json(planned.predicted.position, planned.predicted.rotation),
                     "position_error_m": self.position_error_m,
                     "rotation_error_rad": self.rotation_error_rad}
        if planned.grip is not None:
            data["grip"] = planned.grip.to_record()
        if planned.raised_m is not None:
            data["raised_m"] = planned.raised_m
        if planned.obstacles is not None:
            data["obstacles"] = planned.obstacles
        if planned.plan_status is not None:
            data["plan_status"] = planned.plan_status.value
        if planned.plan is not None:
            data["arm"] = planned.plan.arm
        if self.verdict is not None:
            data["judge"] = self.verdict.to_record()
        data |= {"outcome": self.outcome.value, "reason": self.reason}
        if planned.traceback is not None:
            data["traceback"] = planned.traceback
        if self.lift_m is not None:
            data["lift_m"] = self.lift_m
        return data | (self.loop or {})


@dataclass(frozen=True)
class TrialResult:
    """How a trial went: its outcome, why, and every pick tried.

    Args:
        outcome: How the trial ended: success when every target was picked, else how the
            failed pick ended (or the failure that stopped the trial before a pick ended).
        reason: Why, in words.
        picks: The picks tried, in order; () when the trial stopped before a pick ended.

    """

    outcome: TrialOutcome
    reason: str
    picks: tuple[PickAttempt, ...] = ()

    def record_fields(self) -> dict[str, Any]:
        """What a :class:`~sim.trials.records.TrialRecord` keeps of the result.

        The outcome and reason, the last pick's fields at the top (the pick that decided the
        trial; its loop's re-predictions and disturbance stay in ``picks``), and every pick
        under ``picks``.
        """
        if not self.picks:
            return {"outcome": self.outcome, "reason": self.reason}
        picks = [pick.to_record() for pick in self.picks]
        kept_in_picks = ("outcome", "reason", "traceback", *(self.picks[-1].loop or ()))
        last = {k: v for k, v in picks[-1].items() if k not in kept_in_picks}
        return last | {"outcome": self.outcome, "reason": self.reason, "picks": picks}


@dataclass(frozen=True)
class PickObstacles:
    """What a pick is planned around besides the table, and what its record keeps of them.

    Args:
        obstacles: Everything the robot must not touch (other objects, unknown shapes).
        target: The target's own shapes: avoided on the approach, ignored from the descent on.
        record: Their source and size, as the pick's record keeps them.
        image: From depth, the frame's obstacle points per pixel, NaN elsewhere
            (:attr:`~control.depth_obstacles.DepthObstacles.obstacle_image`); None from truth.

    """

    obstacles: tuple[AnyObstacle, ...]
    target: tuple[AnyObstacle, ...]
    record: dict[str, Any]
    image: np.ndarray | None = None


@dataclass(frozen=True)
class Sighting:
    """What a pick starts from: the frame the robot sees, and the referee's note of the target.

    Args:
        frame: The head camera's RGB-D frame, all the robot acts on.
        body: The target's body id (the referee's, never the plan's).
        target: The target's catalog type.
        truth: Its canonical grasp when the frame was taken: the label the pick is judged by.
        object_yaw_rad: Its yaw then, which the judge needs for the mug's rim.

    """

    frame: RgbdFrame
    body: int
    target: str
    truth: Pose
    object_yaw_rad: float


def trial_result(picks: list[PickAttempt], total: int) -> TrialResult:
    """How a trial of ``total`` targets went, from the picks it tried (one at least)."""
    last = picks[-1]
    if total == 1:
        return TrialResult(last.outcome, last.reason, tuple(picks))
    if last.outcome is TrialOutcome.SUCCESS:  # the last of all the targets
        return TrialResult(TrialOutcome.SUCCESS, f"picked all {total} targets", tuple(picks))
    return TrialResult(last.outcome, f"pick {len(picks)} of {total} ({last.target}): "
                       f"{last.reason}", tuple(picks))
