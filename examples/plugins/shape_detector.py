"""A classical perception plug-in that sees no colour: it finds the catalog's objects by shape.

Run it in pick trials, with this folder on ``PYTHONPATH`` (a module that is not installed)::

    PYTHONPATH=examples/plugins gva trials --model shape_detector:ShapeDetector --task single

The colour detector beside it (``colour_detector.py``) names objects by their colour; this one
reads only the depth image and the calibration. Each frame goes through four steps:

1. Lift the depth image into world points; fit the table's plane to those near z = 0 (a camera
   mount a little off tilts it by millimetres across the image); keep the pixels that rise
   above it.
2. Group the risen pixels into objects: neighbours in the image whose points lie close in space
   are one object; pieces that an occluder (or the object's own overhang) split apart are
   joined where together they have a catalog type's shape.
3. Name each object by its shape as the catalog gives it: of the types whose footprint holds
   what is seen of the object, the one whose height is nearest the object's top. Measure its
   pose on the table from that type's shape: the sponge's top face (a rectangle), the mug's rim
   (a circle) and handle (taken to point away from the camera, behind the mug, where none of it
   is seen), the spray bottle's body (a circle of known radius, seen from one side).
4. Turn each pose into the catalog's grasp (:func:`perception.objects.grasps.grasp_pose`) and return
   the targets the condition asks for, in the task's target order.

Where shape alone cannot tell types apart (what this plug-in is the reference for):

* A shape twin (``bottle_twin``, ``mug_twin``) is its type's shape in another colour: it is
  taken for a spray bottle or a mug, always: it is an extra target where every target is asked
  for, and it is picked in the target's place where it is nearer the robot (a type asked for)
  or further to the side asked for.
* The wooden block is the sponge's height and width and 5 mm shorter (85 against 90 mm): one
  pixel is 5 mm on the table, and a top face partly hidden measures shorter still, so the block
  is taken for a sponge too.
* Among the other catalog types, height and footprint alone tell each apart (the notebook and
  the marker, both 15 mm high, by their widths), so the round-or-square outline decides how a
  pose is measured, never the name.

It imports nothing but ``perception``, numpy, the standard library and ``table_objects`` (the
table, the fits and the task's choice, shared with ``colour_detector.py``).
"""

from __future__ import annotations

import functools
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
    MUG,
    OBJECT_TYPES,
    SPRAY_BOTTLE,
    ObjectSpec,
    PrimitiveKind,
    catalog_names,
    get_object_spec,
)

ABOVE_TABLE_M = 0.004
"""Points lower than this above the table's plane are the table; every object rises higher [m]."""
LINK_M = 0.015
"""Neighbouring pixels whose points lie closer than this are one object: a pixel is ~5 mm on the
table, and the steep side of a bottle seen at a slant spreads neighbours to ~1 cm [m]."""
MIN_PIECE_PX = 4
"""Smaller groups of pixels are noise (a speck at an edge), not part of an object."""
MIN_OBJECT_PX = 12
"""Fewer pixels than this are noise, not an object (a sponge seen whole has ~150)."""
TOP_POINTS = 3
"""An object's top is the height of its third-highest point: one noisy pixel does not lift it."""
HEIGHT_TOLERANCE_M = 0.012
"""An object whose top is farther than this from every catalog type's height is none of them:
tops measure 1-3 mm high (noise lifts the highest points), and the sponge's height lies 15 mm
from the nearest other types' (the notebook's, the colour twin's) [m]."""
FOOTPRINT_TOLERANCE_M = 0.012
"""What is seen of an object fits in its type's footprint, give or take this: two pixels [m]."""
YAW_STEP_DEG = 1.0
"""Resolution of the search for the smallest rectangle around a set of points [deg]."""
TOP_BAND_M = 0.004
"""Points this close below an object's catalog height are its top face (depth noise ~1.5 mm);
a wider band takes in the sides the camera sees, which pull the centre toward it [m]."""
MIN_FACE_PX = 5
"""A face (the sponge's top, the mug's rim, the bottle's body) needs this many to be measured."""
PROBE_M = 0.01
"""How far past a face's end to look for what hides it, and how much nearer hides it [m]."""
MUG_RIM_RADIUS_M = float(np.hypot(*MUG.primitives[0].position_m[:2]))
"""The middle of the mug's wall (its first primitives are the ring's segments) [m]."""
BOTTLE_RADIUS_M = 0.5 * SPRAY_BOTTLE.primitives[0].size_m[0]
"""The radius of the spray bottle's body, the cylinder the gripper closes on [m]."""
BOTTLE_BODY_TOP_M = SPRAY_BOTTLE.primitives[0].size_m[2]
"""The top of the bottle's body; above it, the shoulder and head are narrower or off-axis [m]."""


class ShapeDetector(TableDetector):
    """Finds sponges, spray bottles and mugs by their shapes in the depth image; no colour."""

    name = "shape-detector"

    def detect(self, frame: RgbdFrame) -> list[Detection]:
        """See :func:`detect`."""
        return detect(frame)


def detect(frame: RgbdFrame) -> list[Detection]:
    """Every object of a target type's shape seen in ``frame``.

    Objects of another catalog type's shape (a drink can, a notebook) are named too, and so
    never taken for a target; they are not measured.
    """
    points = frame.points_world()  # (H, W, 3)
    points[..., 2] = heights_above_table(points.reshape(-1, 3)).reshape(points.shape[:2])
    found = []
    for seen in objects(points):
        object_type = shape_type(seen)
        if object_type in OBJECT_TYPES:
            found.append(measure(object_type, seen, frame))
    return [d for d in found if d is not None]


def objects(points: np.ndarray) -> list[np.ndarray]:
    """The objects' points (N, 3), heights above the table, from the image's points (H, W, 3)."""
    with np.errstate(invalid="ignore"):  # NaN where the depth image has no return
        risen = points[..., 2] > ABOVE_TABLE_M
    labels = image_components(points, risen)
    pieces = [points[labels == label] for label in np.unique(labels[labels >= 0])]
    return join_pieces([p for p in pieces if len(p) >= MIN_PIECE_PX])


def image_components(points: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Labels (H, W) of the connected groups of ``keep`` pixels; -1 elsewhere.

    Two side-by-side (or one above the other) kept pixels are linked when their points lie
    closer than :data:`LINK_M`: an object in front of another touches it in the image, never
    in space.
    """
    height_px, width_px = keep.shape
    size = height_px * width_px
    links = []  # (a, b) flat indices of linked neighbours
    for dv, du in ((0, 1), (1, 0)):
        a = keep[:height_px - dv, :width_px - du] & keep[dv:, du:]
        gap = np.linalg.norm(points[:height_px - dv, :width_px - du] - points[dv:, du:], axis=-1)
        a &= gap < LINK_M
        v_px, u_px = np.nonzero(a)
        links.append(np.stack([v_px * width_px + u_px, (v_px + dv) * width_px + u_px + du], 1))
    pairs = np.concatenate(links)
    labels = np.arange(size)
    while True:  # each pixel takes the smallest label of its links, until none changes
        before = labels
        smallest = labels.copy()
        np.minimum.at(smallest, pairs[:, 0], labels[pairs[:, 1]])
        np.minimum.at(smallest, pairs[:, 1], labels[pairs[:, 0]])
        labels = smallest[smallest]  # jump along chains: a few rounds suffice
        if np.array_equal(labels, before):
            break
    return np.where(keep.reshape(-1), labels, -1).reshape(keep.shape)


def join_pieces(pieces: list[np.ndarray]) -> list[np.ndarray]:
    """Objects from the pieces (N, 3) of the image, joined where together they have a shape.

    The biggest piece first: a piece joins an object where together they have a catalog type's
    shape (within its footprint, of its height). An occluder in front cuts an object in two; an
    object's own overhang does too (the spray bottle's head in front of its body, a step in
    depth of several centimetres).
    """
    joined: list[np.ndarray] = []
    for piece in sorted(pieces, key=len, reverse=True):
        for index, whole in enumerate(joined):
            both = np.vstack([whole, piece])
            if shape_type(both) is not None:
                joined[index] = both
                break
        else:
            joined.append(piece)
    return [o for o in joined if len(o) >= MIN_OBJECT_PX]


def top_m(points: np.ndarray) -> float:
    """The height of an object's top above the table, from its points (N, 3) [m]."""
    heights = np.sort(points[:, 2])
    return float(heights[-min(TOP_POINTS, len(heights))])


def footprint_m(points: np.ndarray) -> tuple[float, float]:
    """(long, short) sides of the smallest rectangle around the points (N, 2+) on the table."""
    return rectangle(points[:, :2])[1]


def rectangle(xy: np.ndarray) -> tuple[float, tuple[float, float]]:
    """The smallest-area rectangle around the points (N, 2): its long side's yaw, its sides.

    The yaw [rad] and the (long, short) sides [m], by a search over yaw in
    :data:`YAW_STEP_DEG` steps.
    """
    yaws_rad = np.radians(np.arange(0.0, 180.0, YAW_STEP_DEG))
    along = np.ptp(xy @ np.stack([np.cos(yaws_rad), np.sin(yaws_rad)]), axis=0)  # (yaws,)
    across = np.ptp(xy @ np.stack([-np.sin(yaws_rad), np.cos(yaws_rad)]), axis=0)
    best = int(np.argmin(np.where(along >= across, along * across, np.inf)))
    return float(yaws_rad[best]), (float(along[best]), float(across[best]))


@functools.cache
def catalog_footprint_m(object_type: str) -> tuple[float, float]:
    """(long, short) sides of a catalog type's footprint, measured as a seen object's are.

    From the corners of its boxes and the rims of its cylinders (every 10 deg), placed in the
    object frame.
    """
    corners = []
    for primitive in get_object_spec(object_type).primitives:
        half = 0.5 * np.array(primitive.size_m)
        if primitive.kind is PrimitiveKind.CYLINDER:
            angles = np.radians(np.arange(0.0, 360.0, 10.0))
            ring = np.column_stack([half[0] * np.cos(angles), half[1] * np.sin(angles)])
            local = np.vstack([np.column_stack([ring, np.full(len(ring), z)])
                               for z in (-half[2], half[2])])
        else:
            local = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                              for sz in (-1, 1)]) * half
        pose = primitive.pose
        corners.append(local @ pose.rotation.T + pose.position)
    return footprint_m(np.vstack(corners))


def same_shape(type_a: str, type_b: str) -> bool:
    """Whether two catalog types have heights and footprints closer than this detector tells."""
    a_m, b_m = (get_object_spec(t).height_m for t in (type_a, type_b))
    sides_a, sides_b = (catalog_footprint_m(t) for t in (type_a, type_b))
    return abs(a_m - b_m) < HEIGHT_TOLERANCE_M and all(
        abs(a - b) < FOOTPRINT_TOLERANCE_M for a, b in zip(sides_a, sides_b, strict=True))


NAMED_TYPES = (*OBJECT_TYPES, *(t for t in catalog_names() if t not in OBJECT_TYPES and not any(
    same_shape(t, target) for target in OBJECT_TYPES)))
"""The types a shape names: the targets, and every other catalog type that is not a target's
shape (the shape twins and the block are; an object of their shape is taken for the target)."""


def shape_type(points: np.ndarray) -> str | None:
    """The catalog type an object (N, 3) is taken for; None: no catalog type's shape.

    Of the types whose footprint holds what is seen of the object (it may be partly hidden,
    never bigger), the one whose height is nearest the object's top.
    """
    seen_long, seen_short = footprint_m(points)
    top = top_m(points)
    best, best_gap = None, HEIGHT_TOLERANCE_M
    for object_type in NAMED_TYPES:
        long_m, short_m = catalog_footprint_m(object_type)
        if seen_long > long_m + FOOTPRINT_TOLERANCE_M or seen_short > short_m \
                + FOOTPRINT_TOLERANCE_M:
            continue
        gap = abs(top - get_object_spec(object_type).height_m)
        if gap < best_gap:
            best, best_gap = object_type, gap
    return best


def measure(object_type: str, points: np.ndarray, frame: RgbdFrame) -> Detection | None:
    """The pose on the table of one object from its points (N, 3); None if too little is seen."""
    spec = get_object_spec(object_type)
    away = points[:, :2].mean(axis=0) - np.array(frame.camera.position_m[:2])  # along the table
    away /= np.linalg.norm(away)
    if object_type == "spray_bottle":
        body = points[points[:, 2] < BOTTLE_BODY_TOP_M, :2]
        if len(body) < MIN_FACE_PX:
            return None
        x_m, y_m = circle_centre(body, BOTTLE_RADIUS_M,
                                 body.mean(axis=0) + math.pi / 4 * BOTTLE_RADIUS_M * away)
        return Detection(object_type, float(x_m), float(y_m), 0.0)  # any yaw: the same grasp
    top = points[points[:, 2] > spec.height_m - TOP_BAND_M, :2]
    if len(top) < MIN_FACE_PX:
        return None
    if object_type == "mug":
        centre = circle_centre(top, MUG_RIM_RADIUS_M, top.mean(axis=0))
        return Detection(object_type, float(centre[0]), float(centre[1]),
                         handle_yaw_rad(points, centre, away))
    return Detection(object_type, *box_pose(top, spec, frame))


def box_pose(top_xy: np.ndarray, spec: ObjectSpec, frame: RgbdFrame
             ) -> tuple[float, float, float]:
    """(x, y, yaw) of a box-shaped object from the points (N, 2) of its top face.

    The smallest rectangle around the points gives the sides (and the yaw of the long one).
    Along each side, where one end is hidden (something nearer covers the point just past it),
    the centre lies half the catalog length from the end that is seen; else midway.
    """
    yaw_rad, _ = rectangle(top_xy)
    axes = np.array([[math.cos(yaw_rad), math.sin(yaw_rad)],
                     [-math.sin(yaw_rad), math.cos(yaw_rad)]])  # rows: long, short side
    local = top_xy @ axes.T  # (N, 2)
    low, high = local.min(axis=0), local.max(axis=0)
    centre = 0.5 * (low + high)
    long_m, short_m = catalog_footprint_m(spec.name)
    for side, length_m in enumerate((long_m, short_m)):
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
    depth_m = (np.array(point_m) - np.array(camera.position_m)) @ camera.T_world_camera[:3, 2]
    return bool(0.0 < frame.depth_m[int(v_px), int(u_px)] < depth_m - PROBE_M)


