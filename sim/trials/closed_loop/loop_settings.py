"""What a closed loop is set to do, and what its records keep (issue 36).

The settings of :mod:`sim.trials.closed_loop.loop`'s loop (a run's ``run.json`` keeps them), the
reaction to each re-prediction and the records of re-predictions and disturbances: data only,
so that run settings and reports read them without the loop's machinery.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from perception.poses import Pose
from sim.errors import InvalidInputError
from sim.tasks.disturbance import DisturbanceDraw
from sim.trials.pick_results import pose_json

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
        footprint_radius_m: A re-prediction counts only while the camera sees all of the
            disk this wide [m] about the grasp followed: where the arm hides any of it, the
            model cannot see whether the target is still there, and the plan stands
            (``hidden``). 4.5 cm: below the reach of every task's target from its centre
            (the sponge's corners 4.8 cm, the spray bottle's 4.7, the mug's handle 6.7;
            ``perception.objects.catalog``), so the disk is where any target shows itself.

    """

    loop: Loop = Loop.OPEN
    replan_hz: float = 10.0
    move_threshold_m: float = 0.01
    turn_threshold_deg: float = 10.0
    footprint_radius_m: float = 0.045

    def __post_init__(self) -> None:
        if not isinstance(self.loop, Loop):
            raise InvalidInputError("loop", self.loop, "open or closed")
        if not (math.isfinite(self.replan_hz) and 0.0 < self.replan_hz <= MAX_REPLAN_HZ):
            raise InvalidInputError("replan_hz", self.replan_hz,
                                    f"a rate in (0, {MAX_REPLAN_HZ:g}] Hz")
        for name in ("move_threshold_m", "turn_threshold_deg", "footprint_radius_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise InvalidInputError(name, value, "a finite value >= 0")

    def to_json(self) -> dict[str, Any]:
        """The settings as a record keeps them (open loop: just that)."""
        if self.loop is Loop.OPEN:
            return {"loop": "open"}
        return {"loop": "closed", "replan_hz": self.replan_hz,
                "move_threshold_m": self.move_threshold_m,
                "turn_threshold_deg": self.turn_threshold_deg,
                "footprint_radius_m": self.footprint_radius_m}


class Reaction(enum.Enum):
    """What the arm did with one re-prediction."""

    HELD = "held"  # the grasp within the thresholds of the one followed: the plan stands
    RETARGETED = "retargeted"  # re-planned and re-targeted from the moving state
    KEPT = "kept"  # the grasp moved, no re-plan was found, the plan followed runs clear: it stands
    STOPPED = "stopped"  # no re-plan, and the plan followed runs into what is seen: the arm brakes
    UNSEEN = "unseen"  # the model gave nothing the robot can act on: the last plan stands
    HIDDEN = "hidden"  # the arm hides the target followed: what the model says of it is not heeded
    TIMED_OUT = "timed_out"  # the approach ran past its time: no more looks, the plan followed runs


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


def reactions(records: Sequence[dict[str, Any]]) -> dict[str, int]:
    """How many re-predictions of ``records`` (picks' ``repredictions``) led to each reaction."""
    counts = {reaction.value: 0 for reaction in Reaction}
    for record in records:
        counts[record["reaction"]] += 1
    return counts
