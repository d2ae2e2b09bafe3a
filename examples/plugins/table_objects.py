"""What the two classical detectors of this folder share: the table, the catalog's fits, the task.

``colour_detector.py`` names objects by colour, ``shape_detector.py`` by shape; both then stand on
the same ground: the table's plane fitted through the calibrated depth, the mug's and bottle's
circle fits of known radius, the catalog grasp of each detection, and the choice of the targets
a task's condition asks for. A detector subclasses :class:`TableDetector` and implements
``detect(frame)``. Like the detectors, it imports nothing but ``perception``, numpy and the
standard library.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from perception.camera import RgbdFrame
from perception.interface import (
    NO_CONDITION,
    Condition,
    ConditionKind,
    InvalidPredictionError,
    LabelKind,
    ModelInput,
    PerceptionModel,
    Prediction,
    Target,
)
from perception.objects.catalog import OBJECT_TYPES, get_object_spec
from perception.objects.grasps import grasp_pose
from perception.poses import Pose

TABLE_BAND_M = 0.01
"""Points within this of z = 0 are the table's candidates when its plane is fitted [m]."""
TABLE_INLIER_M = 0.003
"""The plane is refitted on the points within this of the first fit (depth noise ~1.5 mm) [m]."""
CIRCLE_FIT_STEPS = 10
"""Gauss-Newton steps of the known-radius circle fit (it converges in three or four)."""
MUG_HANDLE_FROM_M = 0.047
"""Mug points farther than this from its axis are the handle (the wall reaches 41.4 mm) [m]."""


@dataclass(frozen=True)
class Detection:
    """One object found on the table: its type and its pose there (object frame, z = 0)."""

    object_type: str
    x_m: float
    y_m: float
    yaw_rad: float

    def target(self) -> Target:
        """The catalog's grasp of this object, as a trial's target."""
        pose = Pose.from_xy_yaw(self.x_m, self.y_m, self.yaw_rad)
        grasp = grasp_pose(get_object_spec(self.object_type), pose)
        return Target(grasp.position, grasp.rotation, self.object_type)


class TableDetector(PerceptionModel):
    """A detector of the catalog's objects on the table: ``detect`` them, choose, grasp."""

    label_kind = LabelKind.GRASP_POSE
    inputs = frozenset({ModelInput.RGB, ModelInput.DEPTH, ModelInput.CAMERA})

    def detect(self, frame: RgbdFrame) -> list[Detection]:
        """Every object the detector finds in ``frame``."""
        raise NotImplementedError

    def predict_frame(self, frame: RgbdFrame, condition: Condition = NO_CONDITION
                      ) -> Prediction:
        """The grasps of the objects ``condition`` asks for; raises if it asks for none seen."""
        chosen = choose(self.detect(frame), condition, self.name)
        centres_m = [(d.x_m, d.y_m, 0.5 * get_object_spec(d.object_type).height_m) for d in chosen]
        return Prediction(targets=tuple(d.target() for d in chosen),
                          attention_px=frame.camera.project(np.array(centres_m)))


def heights_above_table(points: np.ndarray) -> np.ndarray:
    """Each point's (N, 3) height above the table's plane, fitted to this frame's points.

    A hand-eye error of a fraction of a degree tilts the table by 2-4 mm across the image,
    which measured from z = 0 would lift patches of table into objects. Least squares on the
    points near z = 0, then again on those near the first fit (objects' points drop out).
    """
    xy1 = np.column_stack([points[:, :2], np.ones(len(points))])
    heights = points[:, 2]
    with np.errstate(invalid="ignore"):  # NaN where the depth image has no return
        near = np.abs(heights) < TABLE_BAND_M
        for _ in range(2):
            if np.count_nonzero(near) < 3:  # no table in view: z = 0 is all there is
                return heights
            plane = np.linalg.lstsq(xy1[near], points[near, 2], rcond=None)[0]
            heights = points[:, 2] - xy1 @ plane
            near = np.abs(heights) < TABLE_INLIER_M
    return heights


def circle_centre(xy: np.ndarray, radius_m: float, start_xy: np.ndarray) -> np.ndarray:
    """The centre of the circle of ``radius_m`` nearest the points (N, 2), by Gauss-Newton.

    A bottle's body is seen on its near half only: the centroid of a half circle seen side-on
    lies pi/4 of the radius toward the camera, which is where a caller starts it.
    """
    centre = np.array(start_xy, dtype=float)
    for _ in range(CIRCLE_FIT_STEPS):
        offsets = xy - centre
        distances = np.maximum(np.linalg.norm(offsets, axis=1), 1e-9)
        jacobian = -offsets / distances[:, None]  # of each point's distance, by the centre
        step, *_ = np.linalg.lstsq(jacobian, radius_m - distances, rcond=None)
        centre += step
    return centre


def handle_yaw_rad(points: np.ndarray, centre: np.ndarray | tuple[float, float],
                   away: np.ndarray) -> float:
    """Which way the mug's handle (its +x) points; away from the camera when none is seen."""
    offsets = points[:, :2] - np.asarray(centre)
    handle = offsets[np.linalg.norm(offsets, axis=1) > MUG_HANDLE_FROM_M]
    direction = handle.mean(axis=0) if len(handle) else away
    return math.atan2(direction[1], direction[0])


def choose(detections: list[Detection], condition: Condition, name: str) -> list[Detection]:
    """The detections ``condition`` names, in the task's target order (``name``: the model's).

    None: every object of a target type, by catalog type order, then from the robot's right
    (-y) to its left. An object type: that type's object (the nearest the robot if several).
    A side: the leftmost (+y, ``"left"``) or the rightmost object of a target type. A sentence
    or a picture is refused: reading them is what a learned Query is for.
    """
    if condition.kind in (ConditionKind.TEXT, ConditionKind.IMAGE):
        raise InvalidPredictionError(f"{name} reads one-hot conditions (an object type, a side), "
                                     f"not a {condition.kind.value} condition")
    found = sorted((d for d in detections if d.object_type in OBJECT_TYPES),
                   key=lambda d: (OBJECT_TYPES.index(d.object_type), d.y_m))
    if condition.kind is ConditionKind.OBJECT_TYPE:
        found = sorted((d for d in found if d.object_type == condition.value),
                       key=lambda d: math.hypot(d.x_m, d.y_m))[:1]
    elif condition.kind is ConditionKind.SIDE:
        found = sorted(found, key=lambda d: d.y_m)
        found = found[-1:] if condition.value == "left" else found[:1]
    if not found:
        wanted = condition.value if condition.kind is ConditionKind.OBJECT_TYPE else "object"
        raise InvalidPredictionError(f"{name} found no {wanted} on the table")
    return found
