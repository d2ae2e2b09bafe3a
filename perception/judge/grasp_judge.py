"""Judges a predicted grasp against the true one without physics, as a pick trial would.

A mean position error cannot see why picks fail: a sponge turned 40 degrees off is 0.5 cm from
its true grasp and is missed; a mug rim grasp 1.5 cm off is held. What decides a pick is the
error in the grasp's own frame (along the closing axis the fingers have a few millimetres to
spare, across it centimetres) and the turn about the approach axis, against each object's
tolerance. :func:`grasp_error` measures the former, taken modulo the object's symmetry (any
equivalent grasp the simulator would accept counts as the truth); :func:`judge_grasp` reads the
latter from a :class:`~perception.judge.grasp_tolerance.ToleranceMap` measured by physics
(``benchmarks/bench_grasp_tolerance.py``) and predicts the pick. Numpy and the catalog only, so
an offline evaluation, a training's held-out check and a trial record all judge alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from perception.judge.grasp_tolerance import ToleranceMap, default_tolerance_map
from perception.objects.catalog import ObjectSpec, Symmetry
from perception.poses import Pose, rot_z


@dataclass(frozen=True)
class GraspError:
    """A predicted grasp's error in the frame of the (nearest equivalent) true grasp.

    Attributes:
        closing_m: Offset along the true TCP's x, the axis the fingers close along [m].
        across_m: Offset along the true TCP's y, across the fingers [m].
        approach_m: Offset along the true TCP's z [m]; positive: deeper into the object.
        yaw_rad: Turn about the approach axis [rad], in [0, π/2]: a parallel gripper turned
            half a turn makes the same grasp, so 90 degrees is the worst.
        tilt_rad: Angle between the predicted and the true approach axes [rad].

    """

    closing_m: float
    across_m: float
    approach_m: float
    yaw_rad: float
    tilt_rad: float

    @property
    def position_m(self) -> float:
        """Distance between the grasp positions [m]."""
        return math.hypot(self.closing_m, self.across_m, self.approach_m)

    def to_record(self) -> dict[str, float]:
        """JSON-ready, in millimetres and degrees as a reader compares them with a tolerance."""
        return {"closing_mm": round(1000 * self.closing_m, 3),
                "across_mm": round(1000 * self.across_m, 3),
                "approach_mm": round(1000 * self.approach_m, 3),
                "yaw_deg": round(math.degrees(self.yaw_rad), 3),
                "tilt_deg": round(math.degrees(self.tilt_rad), 3)}


@dataclass(frozen=True)
class GraspVerdict:
    """What the judge says of one predicted grasp.

    Attributes:
        object_type: The target's catalog type.
        error: The error in the true grasp's frame.
        success_rate: The tolerance map's estimate of the chance the pick holds, in [0, 1].
        predicted_success: Whether the judge predicts a success (``success_rate`` >= the
            map's threshold).
        probability: The chance a real run's pick holds: ``success_rate`` read through the
            map's calibration (:class:`~perception.judge.grasp_tolerance.PlattScaling`), the rate
            itself where it has none. Not kept in trial records; the judge reads it again.

    """

    object_type: str
    error: GraspError
    success_rate: float
    predicted_success: bool
    probability: float

    def to_record(self) -> dict[str, Any]:
        """The verdict as a trial record's ``judge`` field keeps it."""
        return {"object_type": self.object_type, **self.error.to_record(),
                "success_rate": round(self.success_rate, 4),
                "predicted_success": self.predicted_success}


def yaw_of(rotation: np.ndarray) -> float:
    """The heading of a frame's x axis about the world's z [rad] (its yaw, for z up)."""
    return math.atan2(float(rotation[1, 0]), float(rotation[0, 0]))


def _turned_about_axis(pose: Pose, axis_xy: np.ndarray, turn_rad: float) -> Pose:
    """``pose`` turned ``turn_rad`` about the vertical line through ``axis_xy``."""
    turn = rot_z(turn_rad)
    origin = np.array([axis_xy[0], axis_xy[1], 0.0])
    return Pose(origin + turn @ (pose.position - origin), turn @ pose.rotation)


def equivalent_truths(spec: ObjectSpec, truth: Pose, predicted: Pose,
                      object_yaw_rad: float | None = None) -> tuple[Pose, ...]:
    """The grasps the object's symmetry makes equal to ``truth`` that ``predicted`` may aim at.

    Equivalent grasps are turns of the true one about the object's vertical axis:

    * a continuous symmetry (the bottle's side grasp): the one turned to approach along the
      predicted approach direction, so an offset or a turn about the approach axis is measured
      as itself, and a grasp from another bearing around the bottle is no error;
    * a grasp that may turn short of a handle (the mug's rim): the true one, and the rim grasp
      at the predicted grasp's bearing about the mug's axis, clamped to ``max_turn_rad`` (this
      needs the object's yaw; without it only the true grasp): a prediction on the far side
      of the seam where the handle faces the robot aims at a good grasp too;
    * none else: the sponge's half turn is the gripper's own, which :func:`grasp_error` folds.

    The first is the one to report where nothing else decides.
    """
    grasp = spec.grasp
    turns = grasp.symmetry is Symmetry.CONTINUOUS or (
        grasp.symmetry is Symmetry.NONE and grasp.max_turn_rad > 0.0 and object_yaw_rad is not None)
    if not turns:
        return (truth,)
    T_world_turned_object = grasp.object_frame(truth)  # turned to the true grasp
    axis_xy = T_world_turned_object.position[:2]
    if grasp.symmetry is Symmetry.CONTINUOUS:
        def heading(pose: Pose) -> float:
            return math.atan2(float(pose.rotation[1, 2]), float(pose.rotation[0, 2]))

        turn = math.remainder(heading(predicted) - heading(truth), 2.0 * math.pi)
        return (_turned_about_axis(truth, axis_xy, turn),)

    def bearing(pose: Pose) -> float:
        offset = pose.position[:2] - axis_xy
        return math.atan2(float(offset[1]), float(offset[0]))

    assert object_yaw_rad is not None
    taken = math.remainder(yaw_of(T_world_turned_object.rotation) - object_yaw_rad, 2.0 * math.pi)
    turn = math.remainder(bearing(predicted) - bearing(truth), 2.0 * math.pi)
    turn = min(grasp.max_turn_rad, max(-grasp.max_turn_rad, taken + turn)) - taken
    return (truth, _turned_about_axis(truth, axis_xy, turn))


def error_from(reference: Pose, predicted: Pose) -> GraspError:
    """The error of ``predicted`` in the frame of the grasp ``reference``."""
    offset = reference.rotation.T @ (predicted.position - reference.position)  # (3,) TCP frame
    relative = reference.rotation.T @ predicted.rotation  # predicted axes in the true TCP frame
    closing = relative[:, 0]
    yaw = abs(math.remainder(math.atan2(float(closing[1]), float(closing[0])), math.pi))
    tilt = math.acos(max(-1.0, min(1.0, float(relative[2, 2]))))
    return GraspError(float(offset[0]), float(offset[1]), float(offset[2]), yaw, tilt)


def grasp_error(spec: ObjectSpec, truth: Pose, predicted: Pose,
                object_yaw_rad: float | None = None) -> GraspError:
    """The error of ``predicted`` in the frame of the true grasp (its first equivalent).

    ``object_yaw_rad``: the object's yaw on the table, which only the mug needs (its rim grasp
    may turn, short of the handle); a trial record keeps it with the scene's objects.
    """
    return error_from(equivalent_truths(spec, truth, predicted, object_yaw_rad)[0], predicted)


def judge_grasp(spec: ObjectSpec, truth: Pose, predicted: Pose,
                object_yaw_rad: float | None = None,
                tolerance: ToleranceMap | None = None) -> GraspVerdict:
    """Predicts whether the pick of ``predicted`` holds the object whose true grasp is ``truth``.

    Of the grasps equivalent to ``truth`` (:func:`equivalent_truths`), the one the map rates
    best: a grasp holds when it is within tolerance of any good grasp. ``tolerance``: the map to
    judge by; the one shipped with gva when None.
    """
    tolerance = tolerance or default_tolerance_map()
    best: GraspVerdict | None = None
    for reference in equivalent_truths(spec, truth, predicted, object_yaw_rad):
        error = error_from(reference, predicted)
        rate = tolerance.success_rate(spec.name, error.closing_m, error.across_m,
                                      error.approach_m, error.yaw_rad)
        if best is None or rate > best.success_rate:
            best = GraspVerdict(spec.name, error, rate, rate >= tolerance.threshold,
                                tolerance.probability(rate))
    assert best is not None  # equivalent_truths gives the truth at least
    return best
