"""A classical perception plug-in: finds the catalog's objects by colour and depth, no learning.

Run it in pick trials (this folder on ``PYTHONPATH``, as a module that is not installed)::

    PYTHONPATH=examples/plugins gva trials --model colour_detector:ColourDetector --task single

Each frame goes through five steps, one function each:

1. Lift the depth image into world points; keep the pixels that see something above the table.
2. Label each kept pixel with the object type of the nearest catalog colour, compared by
   chromaticity (``rgb / sum(rgb)``), which dimming the light leaves unchanged.
3. Group each type's points into objects on the table plane: one object, one cluster.
4. Measure each object's pose on the table from the shape the catalog gives it: the sponge's
   top face (centre, long axis), the mug's rim (a circle) and handle, the bottle's body (a
   circle of known radius: the camera sees only its near side).
5. Turn each pose into the catalog's grasp (:func:`perception.grasps.grasp_pose`) and return
   the targets the condition asks for, in the task's target order.

It imports nothing but ``perception``, numpy and the standard library: what a real robot's
detector would know is the catalog (shapes and colours) and the calibrated camera.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from perception.camera import RgbdFrame
from perception.catalog import DISTRACTOR_TYPES, OBJECT_TYPES, Pose, get_object_spec
from perception.grasps import grasp_pose
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

ABOVE_TABLE_M = 0.004
"""Points lower than this are the table (z = 0); every object shows more than this [m]."""
ABOVE_OBJECTS_M = 0.03
"""Points this far above the tallest catalog object are not an object on the table [m]."""
MAX_CHROMA_DISTANCE = 0.12
"""Pixels farther than this from every catalog colour, in chromaticity, are left unlabelled."""
LINK_M = 0.012
"""Points of one object lie closer than this to a neighbour on the table plane (1 cm: 2-3 px)."""
SIZE_TOLERANCE_M = 0.01
"""Pieces of one object (split by an occluder) span at most its footprint plus this [m]."""
MIN_OBJECT_PX = 12
"""Fewer pixels than this are noise (an edge, a highlight), not an object (a bottle has ~200)."""
TOP_BAND_M = 0.0015
"""An object's top face (the sponge's, the mug's rim): points this close to its catalog height;
wider, the sides the camera sees would pull the centre toward it [m]."""
MUG_RIM_RADIUS_M = 0.0375
"""The middle of the mug's 5 mm wall (catalog: 40 mm outer radius) [m]."""
MUG_HANDLE_FROM_M = 0.047
"""Mug points farther than this from its axis are the handle (the wall reaches 41.4 mm) [m]."""
BOTTLE_RADIUS_M = 0.019
"""The spray bottle's body (catalog: a 38 mm cylinder, 125 mm tall) [m]."""
BOTTLE_BODY_TOP_M = 0.125
"""The top of the bottle's body; above it the shoulder and head are narrower or off-axis [m]."""
CIRCLE_FIT_STEPS = 10
"""Gauss-Newton steps of the known-radius circle fit (it converges in three or four)."""

SEARCHED_TYPES = OBJECT_TYPES + DISTRACTOR_TYPES
"""Every colour the catalog has: distractors are found too, so their pixels are not a target's."""


@dataclass(frozen=True)
class Detection:
    """One object found on the table: its type and its pose there (object frame, z = 0)."""

    object_type: str
    x_m: float
    y_m: float
    yaw_rad: float

    def target(self) -> Target:
        """The catalog's grasp of this object, as a trial's target."""
        spec = get_object_spec(self.object_type)
        grasp = grasp_pose(spec, Pose.from_xy_yaw(self.x_m, self.y_m, self.yaw_rad))
        return Target(grasp.position, grasp.rotation, self.object_type)


class ColourDetector(PerceptionModel):
    """Finds sponges, spray bottles and mugs by their catalog colours and their depth."""

    name = "colour-detector"
    label_kind = LabelKind.GRASP_POSE
    inputs = frozenset({ModelInput.RGB, ModelInput.DEPTH, ModelInput.CAMERA})

    def predict_frame(self, frame: RgbdFrame, condition: Condition = NO_CONDITION
                      ) -> Prediction:
        """The grasps of the objects ``condition`` asks for; raises if it asks for none seen."""
        chosen = choose(detect(frame), condition)
        centres = [[d.x_m, d.y_m, 0.5 * get_object_spec(d.object_type).height_m] for d in chosen]
        return Prediction(targets=tuple(d.target() for d in chosen),
                          attention_px=frame.camera.project(np.array(centres)))


def detect(frame: RgbdFrame) -> list[Detection]:
    """Every catalog object seen in ``frame`` (distractors included)."""
    points = frame.points_world().reshape(-1, 3)
    rgb = frame.rgb.reshape(-1, 3).astype(float)
    tallest_m = max(get_object_spec(t).height_m for t in SEARCHED_TYPES)
    with np.errstate(invalid="ignore"):  # NaN where the depth image has no return
        seen = (points[:, 2] > ABOVE_TABLE_M) & (points[:, 2] < tallest_m + ABOVE_OBJECTS_M)
    labels = colour_labels(rgb[seen])
    detections = []
    for index, object_type in enumerate(SEARCHED_TYPES):
        for cluster in clusters(points[seen][labels == index], object_type):
            if len(cluster) >= MIN_OBJECT_PX:
                detections.append(measure(object_type, cluster, frame.camera.position_m))
    return detections


def colour_labels(rgb: np.ndarray) -> np.ndarray:
    """Each pixel's index into :data:`SEARCHED_TYPES` by its nearest catalog colour; -1: none."""
    palette, owners = [], []
    for index, object_type in enumerate(SEARCHED_TYPES):
        for primitive in get_object_spec(object_type).primitives:
            palette.append(primitive.rgba[:3])
            owners.append(index)
    distances = np.linalg.norm(chromaticity(rgb)[:, None] - chromaticity(np.array(palette)),
                               axis=-1)  # (N, colours)
    nearest = np.argmin(distances, axis=1)
    return np.where(distances.min(axis=1) < MAX_CHROMA_DISTANCE, np.array(owners)[nearest], -1)


def chromaticity(rgb: np.ndarray) -> np.ndarray:
    """``rgb / sum(rgb)``, (N, 3): a colour without its brightness (white light only scales it)."""
    return rgb / np.maximum(rgb.sum(axis=1, keepdims=True), 1e-9)


def clusters(points: np.ndarray, object_type: str) -> list[np.ndarray]:
    """Points (N, 3) of one type, grouped into objects by their positions on the table plane.

    Points chained closer than :data:`LINK_M` are one object; pieces an occluder cut apart are
    joined again where together they fit in the object's footprint.
    """
    if len(points) == 0:
        return []
    groups = linked_groups(points[:, :2], LINK_M)
    span_m = footprint_span_m(object_type) + SIZE_TOLERANCE_M
    merged: list[np.ndarray] = []
    for group in sorted((points[g] for g in groups), key=len, reverse=True):
        for i, kept in enumerate(merged):
            if xy_span_m(np.concatenate([kept, group])) <= span_m:
                merged[i] = np.concatenate([kept, group])
                break
        else:
            merged.append(group)
    return merged


def linked_groups(points_xy: np.ndarray, link_m: float) -> list[np.ndarray]:
    """Indices of the connected groups of points, two points linked when closer than ``link_m``."""
    linked = np.linalg.norm(points_xy[:, None] - points_xy[None], axis=-1) < link_m  # (N, N)
    labels = np.arange(len(points_xy))
    while True:  # every point takes the smallest label it is linked to, until none changes
        smallest = np.min(np.where(linked, labels[None, :], len(labels)), axis=1)
        if np.array_equal(smallest, labels):
            return [np.flatnonzero(labels == label) for label in np.unique(labels)]
        labels = smallest[smallest]  # jump along chains: converges in a few rounds


def footprint_span_m(object_type: str) -> float:
    """The widest distance across an object's footprint on the table, from its catalog shapes."""
    corners = []
    for primitive in get_object_spec(object_type).primitives:
        half = 0.5 * np.array(primitive.size_m)
        box = half * np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        corners.append(primitive.position_m + box @ primitive.pose.rotation.T)
    return xy_span_m(np.concatenate(corners))


def xy_span_m(points: np.ndarray) -> float:
    """The largest distance between two points (N, 3) on the table plane [m]."""
    xy = points[:, :2]
    return float(np.max(np.linalg.norm(xy[:, None] - xy[None], axis=-1)))


def measure(object_type: str, points: np.ndarray, camera_m: tuple[float, ...]) -> Detection:
    """The pose on the table of one object of ``object_type`` from its points (N, 3)."""
    camera = np.asarray(camera_m)
    away = points[:, :2].mean(axis=0) - camera[:2]  # from the camera, along the table
    away /= np.linalg.norm(away)
    if object_type == "spray_bottle":
        return Detection(object_type, *bottle_centre(points, away), 0.0)  # any yaw: one grasp
    top = points[points[:, 2] > get_object_spec(object_type).height_m - TOP_BAND_M]
    if object_type == "mug":
        centre = circle_centre(top[:, :2], MUG_RIM_RADIUS_M, top[:, :2].mean(axis=0))
        return Detection(object_type, *centre, handle_yaw_rad(points, centre, away))
    return Detection(object_type, *box_top_pose(top, camera))


def bottle_centre(points: np.ndarray, away: np.ndarray) -> np.ndarray:
    """The axis of the bottle's body, from the near half of it the camera sees.

    The visible points' centroid lies ``pi / 4`` of the radius toward the camera (the mean
    depth of a half circle seen side-on); a known-radius circle fit then refines it.
    """
    body = points[points[:, 2] < BOTTLE_BODY_TOP_M, :2]
    start = body.mean(axis=0) + math.pi / 4 * BOTTLE_RADIUS_M * away
    return circle_centre(body, BOTTLE_RADIUS_M, start)


def box_top_pose(top: np.ndarray, camera: np.ndarray) -> tuple[float, float, float]:
    """(x, y, yaw) of a box from the points (N, 3) of its top face: centre and long axis.

    Each point is weighted by the patch of face its pixel covers, which grows with the cube of
    its range from the camera; unweighted, the nearer half's denser pixels pull the centre 2 mm
    toward the camera.
    """
    weights = np.linalg.norm(top - camera, axis=1) ** 3
    centre = np.average(top[:, :2], axis=0, weights=weights)
    _, axes = np.linalg.eigh(np.cov(top[:, :2].T, aweights=weights))
    long_axis = axes[:, -1]  # the eigenvector of the largest eigenvalue
    return float(centre[0]), float(centre[1]), math.atan2(long_axis[1], long_axis[0])


def circle_centre(xy: np.ndarray, radius_m: float, start_xy: np.ndarray) -> np.ndarray:
    """The centre of the circle of ``radius_m`` nearest the points (N, 2), by Gauss-Newton."""
    centre = np.array(start_xy, dtype=float)
    for _ in range(CIRCLE_FIT_STEPS):
        offsets = xy - centre
        distances = np.maximum(np.linalg.norm(offsets, axis=1), 1e-9)
        residuals = distances - radius_m
        jacobian = -offsets / distances[:, None]  # d residual / d centre
        step, *_ = np.linalg.lstsq(jacobian, -residuals, rcond=None)
        centre += step
    return centre


def handle_yaw_rad(points: np.ndarray, centre: np.ndarray, away: np.ndarray) -> float:
    """Which way the mug's handle (its +x) points; away from the camera when it is hidden."""
    offsets = points[:, :2] - centre
    handle = offsets[np.linalg.norm(offsets, axis=1) > MUG_HANDLE_FROM_M]
    direction = handle.mean(axis=0) if len(handle) else away
    return math.atan2(direction[1], direction[0])


def choose(detections: list[Detection], condition: Condition) -> list[Detection]:
    """The detections ``condition`` names, in the task's target order.

    None: every target-type object, by catalog type order, then from the robot's right (-y) to
    its left. An object type: that type's object (the nearest the robot if several). A side:
    the leftmost (+y, ``"left"``) or rightmost object.
    """
    found = sorted((d for d in detections if d.object_type in OBJECT_TYPES),
                   key=lambda d: (OBJECT_TYPES.index(d.object_type), d.y_m))
    if condition.kind is ConditionKind.OBJECT_TYPE:
        found = sorted((d for d in found if d.object_type == condition.value),
                       key=lambda d: math.hypot(d.x_m, d.y_m))[:1]
    elif condition.kind is ConditionKind.SIDE:
        by_y = sorted(found, key=lambda d: d.y_m)
        found = by_y[-1:] if condition.value == "left" else by_y[:1]
    if not found:
        wanted = condition.value if condition.kind is ConditionKind.OBJECT_TYPE else "object"
        raise InvalidPredictionError(f"colour-detector found no {wanted} on the table")
    return found
