"""The object catalog of the YuMi scene: a sponge, a spray bottle and a mug, with their grasps.

Plus a wooden block, presented only as a distractor (:data:`DISTRACTOR_TYPES`).

Pure data and geometry (numpy only), so a perception model reads what it must output without
the simulator: each type's shape, colours and grasp (the TCP pose in the object frame, the
opening, the symmetry). :mod:`perception.grasps` chooses among symmetric grasps; the simulator
builds its bodies and judges its picks from these same specs.

Every object frame sits at the centre of the object's footprint on the table, z up, so an object
resting on the table at (x, y) with yaw ψ has ``T_world_object = (x, y, 0) · Rz(ψ)``. The object's
+x marks its front: the spray bottle's nozzle, the mug's handle.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from types import MappingProxyType
from typing import NamedTuple

import numpy as np

from perception.errors import InvalidInputError
from perception.poses import Pose, rot_rpy
from robots.yumi import specs as yumi_specs

FINGERTIP_BEYOND_TCP_M = (
    yumi_specs.FINGER_JOINT_Z_M + yumi_specs.FINGER_BOX.size[2] - yumi_specs.TCP_Z_M
)
"""How far the fingertips reach past the TCP along the approach axis [m] (about 21.5 mm)."""
FINGER_HALF_WIDTH_M = 0.5 * yumi_specs.FINGER_BOX.size[1]
FINGER_THICKNESS_M = yumi_specs.FINGER_BOX.size[0]
FINGER_LENGTH_M = yumi_specs.FINGER_BOX.size[2]
MAX_OPENING_M = 2.0 * yumi_specs.FINGER_TRAVEL_M
MIN_FINGERTIP_HEIGHT_M = 0.005
"""Fingertips must stay this far above the table at the grasp [m]."""
MAX_PAYLOAD_KG = 0.5
MAX_PRIMITIVES = 16
"""PyBullet builds at most 16 shapes into one compound (``MAX_COMPOUND_COLLISION_SHAPES``)."""


class PrimitiveKind(enum.Enum):
    """Shape of one primitive; a cylinder runs along its own z axis."""

    BOX = "box"
    CYLINDER = "cylinder"


@dataclass(frozen=True)
class Primitive:
    """One box or cylinder of an object, in the object frame.

    Attributes:
        kind: Box or cylinder.
        size_m: Edge lengths of the primitive's bounding box in its own frame [m]: a box's
            (x, y, z), a cylinder's (2 r, 2 r, length).
        position_m: Centre in the object frame [m].
        rgba: Colour, each channel in [0, 1].
        rpy_rad: Orientation in the object frame (URDF roll, pitch, yaw) [rad].

    """

    kind: PrimitiveKind
    size_m: tuple[float, float, float]
    position_m: tuple[float, float, float]
    rgba: tuple[float, float, float, float]
    rpy_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if min(self.size_m) <= 0.0:
            raise InvalidInputError("size_m", self.size_m, "three edge lengths > 0 m")
        if self.kind is PrimitiveKind.CYLINDER and self.size_m[0] != self.size_m[1]:
            raise InvalidInputError("size_m", self.size_m, "a cylinder's (2 r, 2 r, length)")
        if not all(0.0 <= c <= 1.0 for c in self.rgba):
            raise InvalidInputError("rgba", self.rgba, "four channels in [0, 1]")

    @property
    def volume_m3(self) -> float:
        """Volume [m^3]."""
        x, y, z = self.size_m
        return math.pi * x * y * z / 4.0 if self.kind is PrimitiveKind.CYLINDER else x * y * z

    @property
    def pose(self) -> Pose:
        """``T_object_primitive``."""
        return Pose(np.array(self.position_m, dtype=float), rot_rpy(self.rpy_rad))


class Symmetry(enum.Enum):
    """An object's symmetry about its vertical axis, as far as grasping is concerned."""

    NONE = "none"  # one grasp (which may still be turned within ``max_turn_rad``)
    TWO_FOLD = "two_fold"  # the same after a half turn
    CONTINUOUS = "continuous"  # the same after any turn


@dataclass(frozen=True)
class GraspSpec:
    """How the YuMi gripper takes an object, in the object frame.

    The TCP frame's z axis is the approach direction (into the object) and its x axis the
    direction the fingers close along; y = z × x.

    Attributes:
        tcp_position_m: TCP at the grasp, in the object frame [m].
        approach_axis: TCP z axis in the object frame (unit).
        closing_axis: TCP x axis in the object frame (unit, orthogonal to ``approach_axis``).
        opening_m: Finger gap to approach with [m], at most 0.05.
        pregrasp_distance_m: How far back along the approach the pre-grasp pose lies [m].
        symmetry: The object's symmetry about its vertical axis.
        max_turn_rad: For an object without symmetry, how far the grasp may be turned about the
            object's vertical axis and stay good (the mug's rim: anywhere but at the handle).
            Must be 0 for symmetric objects, whose symmetry sets the turns.

    """

    tcp_position_m: tuple[float, float, float]
    approach_axis: tuple[float, float, float]
    closing_axis: tuple[float, float, float]
    opening_m: float
    pregrasp_distance_m: float
    symmetry: Symmetry
    max_turn_rad: float = 0.0

    def __post_init__(self) -> None:
        z, x = np.array(self.approach_axis), np.array(self.closing_axis)
        if abs(np.linalg.norm(z) - 1) > 1e-9 or abs(np.linalg.norm(x) - 1) > 1e-9:
            raise InvalidInputError("approach_axis/closing_axis", (z, x), "unit vectors")
        if abs(float(z @ x)) > 1e-9:
            raise InvalidInputError("closing_axis", self.closing_axis, "orthogonal to approach")
        if not 0.0 < self.opening_m <= MAX_OPENING_M:
            raise InvalidInputError("opening_m", self.opening_m, f"in (0, {MAX_OPENING_M}] m")
        if self.pregrasp_distance_m <= 0.0:
            raise InvalidInputError("pregrasp_distance_m", self.pregrasp_distance_m, "> 0 m")
        limit = 0.0 if self.symmetry is not Symmetry.NONE else math.pi
        if not 0.0 <= self.max_turn_rad <= limit:
            raise InvalidInputError(
                "max_turn_rad", self.max_turn_rad,
                f"in [0, {limit:.4f}] rad for symmetry {self.symmetry.value}",
            )

    @property
    def T_object_grasp(self) -> Pose:
        """The TCP pose at the grasp in the object frame."""
        z, x = np.array(self.approach_axis), np.array(self.closing_axis)
        rotation = np.column_stack([x, np.cross(z, x), z])  # columns: TCP x, y, z
        return Pose(np.array(self.tcp_position_m, dtype=float), rotation)

    def object_frame(self, T_world_grasp: Pose) -> Pose:
        """The object frame a grasp ``T_world_grasp`` of this spec takes it in.

        Turned as the grasp is: for a symmetric object, the frame of the equivalent turn.
        """
        return T_world_grasp.compose(self.T_object_grasp.inverse())

    def lowest_finger_point_z_m(self) -> float:
        """Height of the lowest fingertip corner above the table at the grasp [m]."""
        return lowest_fingertip_z_m(self.T_object_grasp, self.opening_m)


def lowest_fingertip_z_m(T_tcp: Pose, opening_m: float) -> float:
    """The lowest z of the open gripper's fingertip corners with its TCP at ``T_tcp`` [m]."""
    x, y, z = T_tcp.rotation.T
    outer = opening_m / 2 + FINGER_THICKNESS_M  # outer finger faces, from the TCP
    tip = T_tcp.position + FINGERTIP_BEYOND_TCP_M * z
    corners = [tip + sx * outer * x + sy * FINGER_HALF_WIDTH_M * y
               for sx in (-1.0, 1.0) for sy in (-1.0, 1.0)]
    return float(min(c[2] for c in corners))


def clear_of_table(T_world_tcp: Pose, opening_m: float) -> tuple[Pose, float]:
    """``T_world_tcp`` raised just enough that the fingertips keep clear of the table.

    A predicted grasp a few millimetres too low would put the fingertips into the table (z = 0),
    where no plan exists; the workcell knows its table, so the grasp is lifted along the world z
    until its lowest fingertip corner is :data:`MIN_FINGERTIP_HEIGHT_M` above it. Returns the
    pose and how far it was raised [m] (0 when it was clear already).
    """
    raise_m = max(0.0, MIN_FINGERTIP_HEIGHT_M - lowest_fingertip_z_m(T_world_tcp, opening_m))
    if raise_m == 0.0:
        return T_world_tcp, 0.0
    return Pose(T_world_tcp.position + np.array([0.0, 0.0, raise_m]), T_world_tcp.rotation), raise_m


@dataclass(frozen=True)
class ObjectSpec:
    """One object type of the catalog: its shape, physics and grasp.

    Attributes:
        name: Catalog name (``"sponge"``, ``"spray_bottle"``, ``"mug"``).
        primitives: Boxes and cylinders in the object frame (collision and visual alike).
        mass_kg: Total mass [kg], spread uniformly over the primitives' volume.
        lateral_friction: Coulomb coefficient against the fingers and the table.
        spinning_friction_m: Torsional friction [m] (torque per newton of normal force).
        rolling_friction_m: Rolling friction [m].
        grasp: How the gripper takes it.

    """

    name: str
    primitives: tuple[Primitive, ...]
    mass_kg: float
    lateral_friction: float
    spinning_friction_m: float
    rolling_friction_m: float
    grasp: GraspSpec

    def __post_init__(self) -> None:
        if not 1 <= len(self.primitives) <= MAX_PRIMITIVES:
            raise InvalidInputError(
                "number of primitives", len(self.primitives),
                f"1 to {MAX_PRIMITIVES} (PyBullet's limit per compound shape)",
            )
        if not 0.0 < self.mass_kg <= MAX_PAYLOAD_KG:
            raise InvalidInputError("mass_kg", self.mass_kg, f"in (0, {MAX_PAYLOAD_KG}] kg")
        if self.lateral_friction <= 0.0:
            raise InvalidInputError("lateral_friction", self.lateral_friction, "> 0")
        if min(_primitive_bounds_z(p)[0] for p in self.primitives) < -1e-9:
            raise InvalidInputError("primitives", self.name, "all above the object frame's z = 0")
        lowest = self.grasp.lowest_finger_point_z_m()
        if lowest < MIN_FINGERTIP_HEIGHT_M:
            raise InvalidInputError(
                "grasp", f"fingertips at z = {lowest:.4f} m",
                f"fingertips >= {MIN_FINGERTIP_HEIGHT_M} m above the table"
            )

    @property
    def height_m(self) -> float:
        """Height of the object's top above the table [m]."""
        return max(_primitive_bounds_z(p)[1] for p in self.primitives)

    @property
    def center_of_mass_m(self) -> np.ndarray:
        """Centre of mass in the object frame at uniform density [m], (3,)."""
        volumes = np.array([p.volume_m3 for p in self.primitives])
        centres = np.array([p.position_m for p in self.primitives])  # (P, 3)
        return np.asarray(volumes @ centres / volumes.sum())


def _primitive_bounds_z(primitive: Primitive) -> tuple[float, float]:
    """Lowest and highest z of a primitive in the object frame (from its rotated bounding box)."""
    rotation = primitive.pose.rotation
    half_extent_z = float(np.abs(rotation[2]) @ (0.5 * np.array(primitive.size_m)))
    return primitive.position_m[2] - half_extent_z, primitive.position_m[2] + half_extent_z


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

_CATALOG = MappingProxyType({spec.name: spec for spec in (SPONGE, SPRAY_BOTTLE, MUG, BLOCK)})
OBJECT_TYPES: tuple[str, ...] = ("sponge", "spray_bottle", "mug")
"""Names of the object types a task targets, in a fixed order (a one-hot condition's order)."""
DISTRACTOR_TYPES: tuple[str, ...] = ("block",)
"""Catalog types presented only as distractors, never targets."""


def catalog_names() -> tuple[str, ...]:
    """Every type of the catalog, targets and distractors."""
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
