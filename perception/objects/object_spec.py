"""What an object type is: its primitives (boxes, cylinders), its physics and its grasp.

The building blocks of :mod:`perception.objects.catalog`, which holds the object types
themselves, and the YuMi gripper's dimensions that a grasp is checked against (fingertips clear
of the table, an opening within the stroke). Pure data and geometry (numpy only). Every object
frame sits at the centre of the object's footprint on the table, z up.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from perception.errors import InvalidInputError
from perception.poses import Pose, rot_rpy
from robots.description import FingerGeometry
from robots.yumi import smart_gripper

CATALOG_GRIPPER = smart_gripper("r")
"""The gripper the catalog's grasps are stated for and checked against: the YuMi's Smart
Gripper, the hand of the paper whose objects the catalog holds. A fact of the catalog, not a
default robot: the constants below are this gripper's, and a run's own hand (its
:class:`~robots.description.RobotDescription`) reaches a catalog grasp through
:mod:`sim.world.grip`, which takes its stroke from the caller."""
FINGERTIP_BEYOND_TCP_M = CATALOG_GRIPPER.fingers.tip_beyond_tcp_m
"""How far the fingertips reach past the TCP along the approach axis [m] (about 21.5 mm)."""
FINGER_HALF_WIDTH_M = CATALOG_GRIPPER.fingers.half_width_m
FINGER_THICKNESS_M = CATALOG_GRIPPER.fingers.thickness_m
FINGER_LENGTH_M = CATALOG_GRIPPER.fingers.length_m
MAX_OPENING_M = CATALOG_GRIPPER.max_opening_m
MIN_FINGERTIP_HEIGHT_M = 0.005
"""Fingertips must stay this far above the table at the grasp [m]."""
MAX_PAYLOAD_KG = CATALOG_GRIPPER.max_payload_kg
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
        return lowest_fingertip_z_m(self.T_object_grasp, self.opening_m, CATALOG_GRIPPER.fingers)


def lowest_fingertip_z_m(T_tcp: Pose, opening_m: float, fingers: FingerGeometry) -> float:
    """The lowest z of the open gripper's fingertip corners with its TCP at ``T_tcp`` [m]."""
    x, y, z = T_tcp.rotation.T
    outer = opening_m / 2 + fingers.thickness_m  # outer finger faces, from the TCP
    tip = T_tcp.position + fingers.tip_beyond_tcp_m * z
    corners = [tip + sx * outer * x + sy * fingers.half_width_m * y
               for sx in (-1.0, 1.0) for sy in (-1.0, 1.0)]
    return float(min(c[2] for c in corners))


def clear_of_table(T_world_tcp: Pose, opening_m: float, fingers: FingerGeometry
                   ) -> tuple[Pose, float]:
    """``T_world_tcp`` raised just enough that ``fingers``' tips keep clear of the table.

    A predicted grasp a few millimetres too low would put the fingertips into the table (z = 0),
    where no plan exists; the workcell knows its table, so the grasp is lifted along the world z
    until its lowest fingertip corner is :data:`MIN_FINGERTIP_HEIGHT_M` above it. Returns the
    pose and how far it was raised [m] (0 when it was clear already). The fingers are the hand's
    that picks (the Panda's tips end 9.5 mm past its TCP, the YuMi's 21.5 mm).
    """
    raise_m = max(0.0, MIN_FINGERTIP_HEIGHT_M
                  - lowest_fingertip_z_m(T_world_tcp, opening_m, fingers))
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
