"""A classical perception plug-in: finds the catalog's objects by colour and depth, no learning.

Run it in pick trials, with this folder on ``PYTHONPATH`` (a module that is not installed)::

    PYTHONPATH=examples/plugins gva trials --model colour_detector:ColourDetector --task single

Each frame goes through four steps:

1. Lift the depth image into world points; fit the table's plane to those near z = 0 (a camera
   mount a little off, as every hand-eye calibration is, tilts it by millimetres across the
   image); keep the pixels that see something above it.
2. Label each kept pixel with the object type of the nearest catalog colour, compared by
   chromaticity (``rgb / sum(rgb)``), which dimming the light leaves unchanged.
3. Group each type's points into objects on the table plane, and measure each object's pose
   there from its catalog shape: the sponge's top face (a rectangle), the mug's rim (a circle)
   and handle, the spray bottle's body (a circle of known radius, seen from one side only).
4. Turn each pose into the catalog's grasp (:func:`perception.objects.grasps.grasp_pose`) and return
   the targets the condition asks for, in the task's target order.

It imports nothing but ``perception``, numpy, the standard library and ``table_objects`` (the
table, the fits and the task's choice, shared with ``shape_detector.py``): all it knows is what a
real robot's detector would, the catalog's shapes and colours and the calibrated camera.
"""

from __future__ import annotations

import math

import numpy as np
from table_objects import (
    Detection,
    TableDetector,
    circle_centre,
    handle_yaw_rad,
    heights_above_table,
)

from perception.camera import RgbdFrame
from perception.objects.catalog import (
    DISTRACTOR_TYPES,
    MUG,
    OBJECT_TYPES,
    SPRAY_BOTTLE,
    ObjectSpec,
    get_object_spec,
)

ABOVE_TABLE_M = 0.004
"""Points lower than this above the table's plane are the table; every object rises higher [m]."""
MAX_CHROMA_DISTANCE = 0.12
"""Pixels farther than this from every catalog colour (in chromaticity) belong to no object."""
LINK_M = 0.012
"""Points of one object lie closer than this to a neighbour on the table (1 cm is 2-3 px) [m]."""
SPAN_TOLERANCE_M = 0.01
"""Pieces of one object that an occluder split fit in its footprint, give or take this [m]."""
MIN_OBJECT_PX = 12
"""Fewer pixels than this are noise (an edge, a highlight), not an object (a sponge has ~150)."""
MIN_FACE_PX = 5
"""A face (the sponge's top, the mug's rim, the bottle's body) needs this many to be measured."""
TOP_BAND_M = 0.0015
"""Points this close to an object's catalog height are its top face; a wider band takes in
the sides the camera sees, which pull the centre toward it [m]."""
PROBE_M = 0.01
"""How far past a face's end to look for what hides it, and how much nearer hides it [m]."""
YAW_STEP_DEG = 1.0
"""Resolution of the search for a box's sides [deg]."""
MUG_RIM_RADIUS_M = float(np.hypot(*MUG.primitives[0].position_m[:2]))
"""The middle of the mug's wall (its first primitives are the ring's segments) [m]."""
BOTTLE_RADIUS_M = 0.5 * SPRAY_BOTTLE.primitives[0].size_m[0]
"""The radius of the spray bottle's body, the cylinder the gripper closes on [m]."""
BOTTLE_BODY_TOP_M = SPRAY_BOTTLE.primitives[0].size_m[2]
"""The top of the bottle's body; above it, the shoulder and head are narrower or off-axis [m]."""
SEARCHED_TYPES = OBJECT_TYPES + DISTRACTOR_TYPES
"""Distractors are found too, so that their pixels are never taken for a target's."""


class ColourDetector(TableDetector):
    """Finds sponges, spray bottles and mugs by their catalog colours and their depth."""

    name = "colour-detector"

    def detect(self, frame: RgbdFrame) -> list[Detection]:
        """See :func:`detect`."""
        return detect(frame)


def detect(frame: RgbdFrame) -> list[Detection]:
    """Every catalog object seen in ``frame``, distractors included."""
    points = frame.points_world().reshape(-1, 3)
    points[:, 2] = heights_above_table(points)
    with np.errstate(invalid="ignore"):  # NaN where the depth image has no return
        above = points[:, 2] > ABOVE_TABLE_M
    points, labels = points[above], colour_labels(frame.rgb.reshape(-1, 3)[above])
    found = []
    for index, object_type in enumerate(SEARCHED_TYPES):
        for cluster in clusters(points[labels == index], object_type):
            found.append(measure(object_type, cluster, frame))
    return [d for d in found if d is not None]


def colour_labels(rgb: np.ndarray) -> np.ndarray:
    """Each pixel's index in :data:`SEARCHED_TYPES`, by its nearest catalog colour; -1: none."""
    palette = [(p.rgba[:3], index) for index, object_type in enumerate(SEARCHED_TYPES)
               for p in get_object_spec(object_type).primitives]
    colours, owners = np.array([c for c, _ in palette]), np.array([i for _, i in palette])
    distances = np.linalg.norm(chromaticity(rgb)[:, None] - chromaticity(colours), axis=-1)
    nearest = np.argmin(distances, axis=1)  # (N,) over the palette
    return np.where(distances.min(axis=1) < MAX_CHROMA_DISTANCE, owners[nearest], -1)


def chromaticity(rgb: np.ndarray) -> np.ndarray:
    """``rgb / sum(rgb)``, (N, 3): a colour without its brightness (white light only scales it)."""
    rgb = np.asarray(rgb, dtype=float)
    return rgb / np.maximum(rgb.sum(axis=1, keepdims=True), 1e-9)


def clusters(points: np.ndarray, object_type: str) -> list[np.ndarray]:
    """Points (N, 3) of one type grouped into objects by where they lie on the table.

    Points chained closer than :data:`LINK_M` are one object; pieces that an occluder cut
    apart are joined again where together they fit in the object's footprint.
    """
    span_m = 2 * footprint_radius_m(object_type) + SPAN_TOLERANCE_M
    pieces = sorted(linked_groups(points, LINK_M), key=len, reverse=True)
    objects: list[np.ndarray] = []
    for piece in pieces:
        fits = [i for i, o in enumerate(objects) if xy_span_m(np.vstack([o, piece])) <= span_m]
        if fits:
            objects[fits[0]] = np.vstack([objects[fits[0]], piece])
        else:
            objects.append(piece)
    return [o for o in objects if len(o) >= MIN_OBJECT_PX]


def linked_groups(points: np.ndarray, link_m: float) -> list[np.ndarray]:
    """The connected groups of points (N, 3), two linked when closer than ``link_m`` in x, y."""
    xy = points[:, :2]
    linked = np.linalg.norm(xy[:, None] - xy[None], axis=-1) < link_m  # (N, N)
    labels = np.arange(len(points))
    while True:  # each point takes the smallest label it links to, until none changes
        smallest = np.min(np.where(linked, labels, len(labels)), axis=1, initial=len(labels))
        if np.array_equal(smallest, labels):
            return [points[labels == label] for label in np.unique(labels)]
        labels = smallest[smallest]  # jump along chains: a few rounds suffice


def footprint_radius_m(object_type: str) -> float:
    """How far an object reaches from its axis on the table, from its catalog primitives."""
    return max(math.hypot(*p.position_m[:2]) + 0.5 * math.hypot(*p.size_m[:2])
               for p in get_object_spec(object_type).primitives)


def xy_span_m(points: np.ndarray) -> float:
    """The largest distance between two of the points (N, 3) on the table [m]."""
    return float(np.max(np.linalg.norm(points[:, None, :2] - points[None, :, :2], axis=-1)))


def measure(object_type: str, points: np.ndarray, frame: RgbdFrame) -> Detection | None:
    """The pose on the table of one object from its points (N, 3); None if too little is seen."""
    spec = get_object_spec(object_type)
    away = points[:, :2].mean(axis=0) - frame.camera.position_m[:2]  # along the table
    away /= np.linalg.norm(away)
    if object_type == "spray_bottle":
        face = points[points[:, 2] < BOTTLE_BODY_TOP_M, :2]  # its body
    else:
        face = points[points[:, 2] > spec.height_m - TOP_BAND_M, :2]  # its top
    if len(face) < MIN_FACE_PX:
        return None
    if object_type == "spray_bottle":  # any yaw gives the same grasp
        x_m, y_m = bottle_axis(face, away)
        return Detection(object_type, x_m, y_m, 0.0)
    if object_type == "mug":
        x_m, y_m = circle_centre(face, MUG_RIM_RADIUS_M, face.mean(axis=0))
        return Detection(object_type, x_m, y_m, handle_yaw_rad(points, (x_m, y_m), away))
    return Detection(object_type, *box_pose(face, spec, frame))


def bottle_axis(body_xy: np.ndarray, away: np.ndarray) -> np.ndarray:
    """Where the bottle's axis stands, from the points (N, 2) of the body's near half.

    Their centroid lies pi/4 of the radius toward the camera (the mean depth of a half circle
    seen side-on); a circle of the body's radius fitted from there takes out what is left.
    """
    start = body_xy.mean(axis=0) + math.pi / 4 * BOTTLE_RADIUS_M * away
    return circle_centre(body_xy, BOTTLE_RADIUS_M, start)


def box_pose(top_xy: np.ndarray, spec: ObjectSpec, frame: RgbdFrame
             ) -> tuple[float, float, float]:
    """(x, y, yaw) of a box-shaped object from the points (N, 2) of its top face.

    The smallest rectangle around the points gives the sides (and the yaw of the long one):
    they stay put where an occluder hides part of the face, where a principal axis would
    turn. Along each side, the centre lies half the catalog length from the end the camera
    sees if the other end is hidden; else midway between the ends.
    """
    yaws_rad = np.radians(np.arange(0.0, 180.0, YAW_STEP_DEG))
    along = np.ptp(top_xy @ np.stack([np.cos(yaws_rad), np.sin(yaws_rad)]), axis=0)  # (yaws,)
    across = np.ptp(top_xy @ np.stack([-np.sin(yaws_rad), np.cos(yaws_rad)]), axis=0)
    yaw_rad = float(yaws_rad[np.argmin(np.where(along >= across, along * across, np.inf))])
    axes = np.array([[math.cos(yaw_rad), math.sin(yaw_rad)],
                     [-math.sin(yaw_rad), math.cos(yaw_rad)]])  # rows: long, short side
    local = top_xy @ axes.T  # (N, 2)
    low, high = local.min(axis=0), local.max(axis=0)
    centre = 0.5 * (low + high)
    top_layer = max(spec.primitives, key=lambda p: p.position_m[2])
    for side, length_m in enumerate(sorted(top_layer.size_m[:2], reverse=True)):
        beyond = np.array([centre, centre])  # just past the low and the high end
        beyond[:, side] = low[side] - PROBE_M, high[side] + PROBE_M
        low_hidden, high_hidden = (hidden(frame, (*(b @ axes), spec.height_m)) for b in beyond)
        if high_hidden and not low_hidden:
            centre[side] = low[side] + length_m / 2
        elif low_hidden and not high_hidden:
            centre[side] = high[side] - length_m / 2
    x_m, y_m = centre @ axes
    return float(x_m), float(y_m), yaw_rad


def hidden(frame: RgbdFrame, point_m: tuple[float, float, float]) -> bool:
    """Whether the camera cannot see ``point_m``: something nearer covers it, or it is off-image."""
    camera = frame.camera
    u_px, v_px = np.rint(camera.project(np.array(point_m))[0])
    if not (0 <= u_px < camera.width_px and 0 <= v_px < camera.height_px):
        return True
    depth_m = (np.array(point_m) - camera.position_m) @ camera.T_world_camera[:3, 2]
    return bool(frame.depth_m[int(v_px), int(u_px)] < depth_m - PROBE_M)


