"""The object catalog of the YuMi scene: a sponge, a spray bottle and a mug, with their grasps.

Plus objects presented only as distractors, never targets: a wooden block the sponge's size
(:data:`DISTRACTOR_TYPES`, the look-alike the experiments test with) and everyday table clutter
unlike it (:data:`CLUTTER_TYPES`: a drink can, a notebook, a marker, a glue stick).

Pure data and geometry (numpy only), so a perception model reads what it must output without
the simulator: each type's shape, colours and grasp (the TCP pose in the object frame, the
opening, the symmetry). What a type is made of (primitives, grasp, physics) is
:mod:`perception.objects.object_spec`, whose names this module re-exports;
:mod:`perception.objects.grasps` chooses among symmetric grasps; the simulator builds its bodies
and judges its picks from these same specs.

Every object frame sits at the centre of the object's footprint on the table, z up, so an object
resting on the table at (x, y) with yaw ψ has ``T_world_object = (x, y, 0) · Rz(ψ)``. The object's
+x marks its front: the spray bottle's nozzle, the mug's handle.
"""

from __future__ import annotations

import dataclasses
import math
from types import MappingProxyType
from typing import NamedTuple

from perception.errors import InvalidInputError
from perception.objects.object_spec import (
    FINGER_HALF_WIDTH_M,
    FINGER_LENGTH_M,
    FINGER_THICKNESS_M,
    FINGERTIP_BEYOND_TCP_M,
    MAX_OPENING_M,
    MAX_PAYLOAD_KG,
    MAX_PRIMITIVES,
    MIN_FINGERTIP_HEIGHT_M,
    GraspSpec,
    ObjectSpec,
    Primitive,
    PrimitiveKind,
    Symmetry,
    clear_of_table,
    lowest_fingertip_z_m,
)
from perception.poses import Pose

__all__ = [  # the names of perception.objects.object_spec that importers have always found here
    "BLOCK",
    "BOTTLE_TWIN",
    "CLUTTER_TYPES",
    "COLOUR_TWIN",
    "DISTRACTOR_TYPES",
    "DRINK_CAN",
    "FINGERTIP_BEYOND_TCP_M",
    "FINGER_HALF_WIDTH_M",
    "FINGER_LENGTH_M",
    "FINGER_THICKNESS_M",
    "GLUE_STICK",
    "LOOK_ALIKE_TYPES",
    "MARKER",
    "MAX_OPENING_M",
    "MAX_PAYLOAD_KG",
    "MAX_PRIMITIVES",
    "MIN_FINGERTIP_HEIGHT_M",
    "MUG",
    "MUG_TWIN",
    "NOTEBOOK",
    "OBJECT_TYPES",
    "SHAPE_TWINS",
    "SPONGE",
    "SPRAY_BOTTLE",
    "GraspSpec",
    "ObjectSpec",
    "ObstacleShape",
    "Primitive",
    "PrimitiveKind",
    "Symmetry",
    "catalog_names",
    "clear_of_table",
    "get_object_spec",
    "lowest_fingertip_z_m",
    "obstacle_shapes",
]


def _ring(
    outer_radius_m: float, wall_m: float, height_m: float, segments: int,
    rgba: tuple[float, float, float, float],
) -> tuple[Primitive, ...]:
    """Build a tube wall of ``segments`` boxes around a circle, closed at the outer surface."""
    middle = outer_radius_m - wall_m / 2
    chord = 2.0 * outer_radius_m * math.tan(math.pi / segments)
    angles = [2.0 * math.pi * k / segments for k in range(segments)]  # a face at -x
    return tuple(
        Primitive(PrimitiveKind.BOX, (wall_m, chord, height_m),
                  (middle * math.cos(a), middle * math.sin(a), height_m / 2), rgba, (0.0, 0.0, a))
        for a in angles
    )


_BOX, _CYL = PrimitiveKind.BOX, PrimitiveKind.CYLINDER
_DOWN, _FORWARD = (0.0, 0.0, -1.0), (1.0, 0.0, 0.0)
_YELLOW, _GREEN = (0.98, 0.82, 0.16, 1.0), (0.10, 0.45, 0.20, 1.0)
_WHITE, _BLUE, _RED = (0.93, 0.94, 0.96, 1.0), (0.10, 0.32, 0.80, 1.0), (0.75, 0.12, 0.10, 1.0)
_WOOD = (0.80, 0.62, 0.40, 1.0)

# A kitchen sponge cut to 3.5 cm so the fingers (50 mm at most) close across it with 7.5 mm to
# spare per side. The TCP sits 2 mm below its top: fingertips 6.5 mm above the table, 23.5 mm of
# finger on the sponge.
SPONGE = ObjectSpec(
    name="sponge",
    primitives=(
        Primitive(_BOX, (0.090, 0.035, 0.022), (0.0, 0.0, 0.011), _YELLOW),
        Primitive(_BOX, (0.090, 0.035, 0.008), (0.0, 0.0, 0.026), _GREEN),  # scouring layer
    ),
    mass_kg=0.03, lateral_friction=1.2, spinning_friction_m=0.003, rolling_friction_m=0.0005,
    grasp=GraspSpec((0.0, 0.0, 0.028), _DOWN, (0.0, 1.0, 0.0), 0.05, 0.08, Symmetry.TWO_FOLD),
)

# A 38 mm bottle (6 mm to spare per side at full opening) with a trigger head. Taken from the
# side at the body's middle; the TCP stops 6 mm short of the axis so the gripper body (21 mm
# behind the TCP) keeps 8 mm from the bottle while the fingertips reach 15.5 mm past the axis.
SPRAY_BOTTLE = ObjectSpec(
    name="spray_bottle",
    primitives=(
        Primitive(_CYL, (0.038, 0.038, 0.125), (0.0, 0.0, 0.0625), _WHITE),  # body
        Primitive(_CYL, (0.026, 0.026, 0.012), (0.0, 0.0, 0.131), _WHITE),  # shoulder
        Primitive(_CYL, (0.016, 0.016, 0.010), (0.0, 0.0, 0.142), _BLUE),  # neck
        Primitive(_BOX, (0.050, 0.026, 0.026), (0.010, 0.0, 0.160), _BLUE),  # head
        Primitive(_BOX, (0.012, 0.012, 0.012), (0.041, 0.0, 0.166), _WHITE),  # nozzle
        Primitive(_BOX, (0.008, 0.014, 0.030), (0.028, 0.0, 0.138), _BLUE),  # trigger
    ),
    mass_kg=0.2, lateral_friction=1.0, spinning_friction_m=0.003, rolling_friction_m=0.0005,
    grasp=GraspSpec(
        (-0.006, 0.0, 0.07), _FORWARD, (0.0, 1.0, 0.0), 0.05, 0.08, Symmetry.CONTINUOUS
    ),
)

# An 8 cm mug with 5 mm walls (12 flat segments: PyBullet's compound shapes hold 16 primitives)
# and a handle at +x. Taken top-down on the rim, one finger inside and one outside, opened fully
# (50 mm: 22.5 mm to spare per side of the wall; at 40 mm, rim grasps 1.6 cm off toward the mug's
# axis picked 7 of 12 mugs, at 50 mm 12 of 12), the TCP 5 mm below the rim. The rim grasp may
# turn 145 deg either way from the side opposite the handle: the open outer finger (21 mm wide)
# then clears the handle (12 mm wide) by about 21 mm.
MUG = ObjectSpec(
    name="mug",
    primitives=(
        *_ring(0.040, 0.005, 0.090, 12, _RED),
        Primitive(_CYL, (0.071, 0.071, 0.006), (0.0, 0.0, 0.004), _RED),  # bottom, clear of table
        Primitive(_BOX, (0.030, 0.012, 0.008), (0.052, 0.0, 0.072), _RED),  # handle, upper arm
        Primitive(_BOX, (0.030, 0.012, 0.008), (0.052, 0.0, 0.022), _RED),  # handle, lower arm
        Primitive(_BOX, (0.008, 0.012, 0.058), (0.063, 0.0, 0.047), _RED),  # handle, grip
    ),
    mass_kg=0.3, lateral_friction=1.0, spinning_friction_m=0.003, rolling_friction_m=0.0005,
    grasp=GraspSpec((-0.0375, 0.0, 0.085), _DOWN, (-1.0, 0.0, 0.0), 0.05, 0.08, Symmetry.NONE,
                    max_turn_rad=math.radians(145.0)),
)

# A wooden toy block the sponge's size and shape, never a target: the yumi scene's distractor,
# a box on the table a model must not take for the sponge. Its grasp is the sponge's.
BLOCK = ObjectSpec(
    name="block",
    primitives=(Primitive(_BOX, (0.085, 0.035, 0.030), (0.0, 0.0, 0.015), _WOOD),),
    mass_kg=0.05, lateral_friction=1.0, spinning_friction_m=0.003, rolling_friction_m=0.0005,
    grasp=GraspSpec((0.0, 0.0, 0.028), _DOWN, (0.0, 1.0, 0.0), 0.05, 0.08, Symmetry.TWO_FOLD),
)


def _shape_twin(name: str, spec: ObjectSpec) -> ObjectSpec:
    """``spec``'s shape in unfinished wood, named ``name``: a look-alike, never a target.

    Wood is the one colour no palette gives a target (docs/tasks.md): a model that takes the
    twin for the type looks at shape alone. Same primitives, mass and grasp as the type, so it
    lies and is pushed as the type would be.
    """
    return ObjectSpec(
        name=name,
        primitives=tuple(dataclasses.replace(p, rgba=_WOOD) for p in spec.primitives),
        mass_kg=spec.mass_kg, lateral_friction=1.0, spinning_friction_m=0.003,
        rolling_friction_m=0.0005, grasp=spec.grasp,
    )


# Look-alikes, never targets: the block's kin for the other two types (shape twins, the
# types' shapes in wood), and a colour twin.
BOTTLE_TWIN = _shape_twin("bottle_twin", SPRAY_BOTTLE)
MUG_TWIN = _shape_twin("mug_twin", MUG)
# A 45 mm toy cube with a top layer: no target's shape (the sponge is 90 x 35 mm, the bottle and
# the mug round). A scene paints it in one of its targets' colours, the body in the target's
# first part's and the top in its last (sim.tasks.appearance: a sponge's foam and the scourer
# the camera sees from above, a bottle's body and head): a colour twin, the look-alike a colour
# threshold cannot tell from its target. Grey in the catalog.
COLOUR_TWIN = ObjectSpec(
    name="colour_twin",
    primitives=(
        Primitive(_BOX, (0.045, 0.045, 0.037), (0.0, 0.0, 0.0185), (0.5, 0.5, 0.5, 1.0)),
        Primitive(_BOX, (0.045, 0.045, 0.008), (0.0, 0.0, 0.041), (0.4, 0.4, 0.4, 1.0)),
    ),
    mass_kg=0.05, lateral_friction=1.0, spinning_friction_m=0.003, rolling_friction_m=0.0005,
    grasp=GraspSpec((0.0, 0.0, 0.04), _DOWN, (0.0, 1.0, 0.0), 0.05, 0.08, Symmetry.TWO_FOLD),
)

# Table clutter, never a target: objects a model learns to ignore, unlike the block in shape and
# unlike every target and the block in colour (no yellow, green, white, blue, red or wood; nor
# grey or black, which have white's chromaticity), so a model trained among them never saw the
# block. Each reaches at most 74 mm from its centre, as far as the mug's handle. Their grasps
# are top-down placeholders, only for the type to be valid: no trial picks them.
_TEAL, _PURPLE = (0.10, 0.60, 0.62, 1.0), (0.45, 0.20, 0.55, 1.0)
_DARK_VIOLET, _VIOLET = (0.20, 0.06, 0.30, 1.0), (0.30, 0.08, 0.42, 1.0)
_MAGENTA, _DARK_MAGENTA = (0.85, 0.20, 0.60, 1.0), (0.60, 0.10, 0.45, 1.0)
_AXIS_ALONG_X = (0.0, math.pi / 2, 0.0)  # a cylinder lying down, its axis along the object's x

# A full 330 ml drink can in teal print: 66 mm across, 115 mm tall, 0.35 kg (full, so an arm
# brushing it does not fling it). Wider than the 50 mm stroke: the gripper cannot take it.
DRINK_CAN = ObjectSpec(
    name="drink_can",
    primitives=(Primitive(_CYL, (0.066, 0.066, 0.115), (0.0, 0.0, 0.0575), _TEAL),),
    mass_kg=0.35, lateral_friction=0.6, spinning_friction_m=0.003, rolling_friction_m=0.0005,
    grasp=GraspSpec((0.0, 0.0, 0.13), _DOWN, (0.0, 1.0, 0.0), 0.05, 0.08, Symmetry.CONTINUOUS),
)

# A purple pocket notebook lying flat: 120 x 85 x 15 mm, 0.12 kg. Wider than the stroke either
# way, and far from the block's and the sponge's 85-90 x 35 mm footprint.
NOTEBOOK = ObjectSpec(
    name="notebook",
    primitives=(Primitive(_BOX, (0.120, 0.085, 0.015), (0.0, 0.0, 0.0075), _PURPLE),),
    mass_kg=0.12, lateral_friction=0.6, spinning_friction_m=0.003, rolling_friction_m=0.0005,
    grasp=GraspSpec((0.0, 0.0, 0.0275), _DOWN, (0.0, 1.0, 0.0), 0.05, 0.08, Symmetry.TWO_FOLD),
)

# A dark violet marker pen lying on its side: 15 mm across, 130 mm long (a 95 mm barrel and a
# 35 mm cap of the same width, so it lies level), 15 g; the grasp closes across the barrel.
MARKER = ObjectSpec(
    name="marker",
    primitives=(
        Primitive(_CYL, (0.015, 0.015, 0.095), (-0.0175, 0.0, 0.0075), _DARK_VIOLET,
                  _AXIS_ALONG_X),  # barrel
        Primitive(_CYL, (0.015, 0.015, 0.035), (0.0475, 0.0, 0.0075), _VIOLET,
                  _AXIS_ALONG_X),  # cap
    ),
    mass_kg=0.015, lateral_friction=0.8, spinning_friction_m=0.002, rolling_friction_m=0.001,
    grasp=GraspSpec((0.0, 0.0, 0.0275), _DOWN, (0.0, 1.0, 0.0), 0.05, 0.08, Symmetry.TWO_FOLD),
)

# A magenta glue stick standing on its base: 30 mm across, 100 mm tall with its 25 mm cap,
# 40 g; the grasp closes across it 5 mm below the top.
GLUE_STICK = ObjectSpec(
    name="glue_stick",
    primitives=(
        Primitive(_CYL, (0.030, 0.030, 0.075), (0.0, 0.0, 0.0375), _MAGENTA),  # tube
        Primitive(_CYL, (0.030, 0.030, 0.025), (0.0, 0.0, 0.0875), _DARK_MAGENTA),  # cap
    ),
    mass_kg=0.04, lateral_friction=0.8, spinning_friction_m=0.003, rolling_friction_m=0.0005,
    grasp=GraspSpec((0.0, 0.0, 0.095), _DOWN, (0.0, 1.0, 0.0), 0.05, 0.08, Symmetry.CONTINUOUS),
)

_CATALOG = MappingProxyType({spec.name: spec for spec in (
    SPONGE, SPRAY_BOTTLE, MUG, BLOCK, DRINK_CAN, NOTEBOOK, MARKER, GLUE_STICK, BOTTLE_TWIN,
    MUG_TWIN, COLOUR_TWIN)})
OBJECT_TYPES: tuple[str, ...] = ("sponge", "spray_bottle", "mug")
"""Names of the object types a task targets, in a fixed order (a one-hot condition's order)."""
DISTRACTOR_TYPES: tuple[str, ...] = ("block",)
"""The experiments' look-alike distractor: the sponge's size and shape, never a target."""
LOOK_ALIKE_TYPES: tuple[str, ...] = ("bottle_twin", "mug_twin", "colour_twin")
"""Further look-alikes, never targets: the bottle's and the mug's shapes in the block's wood, and
a cube a scene paints in one of its targets' colours (``colour_twin``)."""
SHAPE_TWINS = {"sponge": "block", "spray_bottle": "bottle_twin", "mug": "mug_twin"}
"""Each target type's shape twin: its shape, not its colours."""
CLUTTER_TYPES: tuple[str, ...] = ("drink_can", "notebook", "marker", "glue_stick")
"""Everyday table clutter, presented only as distractors, never targets. Unlike the block in
shape and colour, so a model trained among clutter was never shown the block it is tested on."""


def catalog_names() -> tuple[str, ...]:
    """Every type of the catalog: targets, the block and the clutter."""
    return tuple(_CATALOG)


def get_object_spec(name: str) -> ObjectSpec:
    """Look up the catalog entry called ``name``."""
    try:
        return _CATALOG[name]
    except KeyError:
        raise InvalidInputError("object type", name, f"one of {', '.join(_CATALOG)}") from None


class ObstacleShape(NamedTuple):
    """One primitive of an object placed in the world, for a collision checker."""

    kind: PrimitiveKind
    size_m: tuple[float, float, float]  # a box's edges; a cylinder's (2 r, 2 r, length along z)
    pose: Pose  # T_world_primitive


def obstacle_shapes(spec: ObjectSpec, T_world_object: Pose) -> tuple[ObstacleShape, ...]:
    """Every primitive of ``spec`` placed at ``T_world_object``."""
    return tuple(
        ObstacleShape(p.kind, p.size_m, T_world_object.compose(p.pose)) for p in spec.primitives
    )
