"""What the pick stack needs to know about a robot, as data (issue 39).

The planner, the world and the trials read a robot through a :class:`RobotDescription`: its
URDF and SRDF, its arms (joints, tool frame, gripper, the limits the URDF does not state) and its
home pose. ``robots/yumi`` builds :data:`robots.yumi.YUMI` from the YuMi's fact sheet; a second
robot is a second instance, and :func:`robots.get_robot` finds either by name. Plain data with
checks, no Pinocchio or PyBullet: ``perception`` reads it too.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

from robots.errors import InvalidInputError


def _positive(owner: str, **values: float) -> None:
    for name, value in values.items():
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise InvalidInputError(f"{owner}.{name}", value, "a finite number > 0")


def _names(where: str, names: tuple[str, ...]) -> None:
    if not names or len(set(names)) != len(names) or not all(
            isinstance(n, str) and n for n in names):
        raise InvalidInputError(where, names, "distinct non-empty names")


@dataclass(frozen=True)
class FingerGeometry:
    """A parallel gripper's fingers, in the tool frame (z: approach, x: the fingers close).

    Args:
        tip_beyond_tcp_m: How far the fingertips reach past the TCP along z [m].
        length_m: A finger's length along z [m].
        half_width_m: Half a finger's width along y [m].
        thickness_m: A finger's thickness along the closing axis x [m].

    """

    tip_beyond_tcp_m: float
    length_m: float
    half_width_m: float
    thickness_m: float

    def __post_init__(self) -> None:
        _positive("fingers", length_m=self.length_m, half_width_m=self.half_width_m,
                  thickness_m=self.thickness_m)
        if not math.isfinite(self.tip_beyond_tcp_m):
            raise InvalidInputError("fingers.tip_beyond_tcp_m", self.tip_beyond_tcp_m,
                                    "a finite length [m]")


@dataclass(frozen=True)
class GripperDescription:
    """A parallel gripper: its finger joints, how far and how hard it closes, what it lifts.

    Args:
        finger_joints: The prismatic finger joints; each one's position is half the gap [m].
        max_opening_m: The gap between the fingers at full stroke [m].
        max_force_n: Each finger's force limit [N].
        max_speed_m_s: Each finger's speed limit [m/s].
        max_payload_kg: The heaviest object the arm may lift with it [kg].
        fingers: The fingers' shape, for grasp checks and the depth obstacles.
        neighbour_spacing_m: The least distance between object centres a scene keeps for
            this hand [m], where its body beside a target reaches neighbours a task's own
            spacing allows; None: the task's spacing serves.

    """

    finger_joints: tuple[str, ...]
    max_opening_m: float
    max_force_n: float
    max_speed_m_s: float
    max_payload_kg: float
    fingers: FingerGeometry
    neighbour_spacing_m: float | None = None

    def __post_init__(self) -> None:
        _names("gripper.finger_joints", self.finger_joints)
        _positive("gripper", max_opening_m=self.max_opening_m, max_force_n=self.max_force_n,
                  max_speed_m_s=self.max_speed_m_s, max_payload_kg=self.max_payload_kg)
        if self.neighbour_spacing_m is not None:
            _positive("gripper", neighbour_spacing_m=self.neighbour_spacing_m)


@dataclass(frozen=True)
class ArmDescription:
    """One arm: its joints base to tip, its frames, its gripper and its stated limits.

    Args:
        name: How plans and records name the arm (``"r"``, ``"l"``, ``"panda"``).
        joints: The arm's joint names, base to tip.
        tcp_frame: The tool frame grasps are given for (z: approach, x: the fingers close).
        flange_frame: The tool flange (ISO 9409), where a gripper mounts.
        shoulder_frame: Its distance to a grasp orders the arms a planner tries.
        gripper: The gripper on the flange.
        max_acceleration_rad_s2: Per joint name [rad/s^2]: a URDF states no acceleration.
        max_jerk_rad_s3: Per joint name [rad/s^3].

    """

    name: str
    joints: tuple[str, ...]
    tcp_frame: str
    flange_frame: str
    shoulder_frame: str
    gripper: GripperDescription
    max_acceleration_rad_s2: Mapping[str, float]
    max_jerk_rad_s3: Mapping[str, float]

    def __post_init__(self) -> None:
        _names(f"arm {self.name!r} joints", self.joints)
        for limits in ("max_acceleration_rad_s2", "max_jerk_rad_s3"):
            given = getattr(self, limits)
            missing = [j for j in self.joints if j not in given]
            if missing:
                raise InvalidInputError(f"arm {self.name!r} {limits}", sorted(given),
                                        f"a limit for every joint (missing {missing})")
            _positive(f"arm {self.name!r} {limits}", **{j: given[j] for j in self.joints})
            object.__setattr__(self, limits, MappingProxyType(
                {j: float(given[j]) for j in self.joints}))


@dataclass(frozen=True)
class CameraMount:
    """Where the robot's RGB-D camera sits and what it looks at, in the world frame [m].

    Args:
        position_m: The optical centre.
        target_m: A point on the optical axis (the workspace's middle, on the table).
        focus_window_px: The attention heatmap's focus in this camera's 128 x 128 px images
            (``KqvConfig.focus_window_px``: a model reads each heatmap within this half-width of
            its densest part): the reach of an object's farthest part from its densest square
            plus half that square, derived from how this camera sees the catalog objects
            (docs/decisions/distractor.md). 0: none derived for this camera; models read the
            whole heatmap, as the paper.
        focus_box_px: The side of that densest square (``KqvConfig.focus_box_px``): one
            object's span in these images; 0 where no focus is derived.

    """

    position_m: tuple[float, float, float]
    target_m: tuple[float, float, float]
    focus_window_px: int = 0
    focus_box_px: int = 0

    def __post_init__(self) -> None:
        for name in ("position_m", "target_m"):
            value = getattr(self, name)
            if len(value) != 3 or not all(math.isfinite(v) for v in value):
                raise InvalidInputError(f"camera.{name}", value, "three finite coordinates [m]")
        for name in ("focus_window_px", "focus_box_px"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 0:
                raise InvalidInputError(f"camera.{name}", value, "an integer >= 0 [px]")
        if (self.focus_window_px == 0) != (self.focus_box_px == 0):
            raise InvalidInputError("camera.focus_box_px", self.focus_box_px,
                                    "0 with no focus window, >= 1 with one (focus_window_px "
                                    f"is {self.focus_window_px})")
        if self.position_m == self.target_m:
            raise InvalidInputError("camera.target_m", self.target_m, "a point other than the "
                                    "camera's position")


@dataclass(frozen=True)
class RobotDescription:
    """A robot as the pick stack reads it.

    Args:
        name: The robot's name (``"yumi"``), as run records and datasets state it.
        urdf_path: Its URDF, loaded with a fixed base at the world origin, on the table top.
        srdf_path: Its SRDF (``disable_collisions`` pairs), or None.
        base_link: The URDF's root link, which stands on the table.
        footprint_m: The x and y ranges its base covers on the table [m]: the table must be
            under it, and what a depth camera sees there is the robot, not an obstacle.
        camera: The RGB-D camera the robot sees its workspace through.
        arms: Its arms; a planner picks among them.
        home: Every arm and finger joint's home position [rad] or [m], by joint name.

    """

    name: str
    urdf_path: Path
    srdf_path: Path | None
    base_link: str
    footprint_m: tuple[tuple[float, float], tuple[float, float]]
    camera: CameraMount
    arms: tuple[ArmDescription, ...]
    home: Mapping[str, float] = field(repr=False)

    def __post_init__(self) -> None:
        if not self.name or not isinstance(self.name, str):
            raise InvalidInputError("robot.name", self.name, "a non-empty name")
        ranges = self.footprint_m
        if len(ranges) != 2 or not all(len(r) == 2 and math.isfinite(r[0]) and
                                       math.isfinite(r[1]) and r[0] < r[1] for r in ranges):
            raise InvalidInputError(f"robot {self.name!r} footprint_m", ranges,
                                    "((x_low, x_high), (y_low, y_high)) [m], each low < high")
        if not self.arms:
            raise InvalidInputError(f"robot {self.name!r} arms", self.arms, "at least one arm")
        _names(f"robot {self.name!r} arm names", self.arm_names)
        moving = [j for arm in self.arms for j in (*arm.joints, *arm.gripper.finger_joints)]
        _names(f"robot {self.name!r} joints", tuple(moving))
        missing = [j for j in moving if j not in self.home]
        if missing:
            raise InvalidInputError(f"robot {self.name!r} home", sorted(self.home),
                                    f"a position for every arm and finger joint (missing "
                                    f"{missing})")
        object.__setattr__(self, "home", MappingProxyType(
            {j: float(v) for j, v in self.home.items()}))

    @property
    def arm_names(self) -> tuple[str, ...]:
        """The arms' names, in the order :attr:`arms` gives them."""
        return tuple(arm.name for arm in self.arms)

    @property
    def max_opening_m(self) -> float:
        """The widest finger gap every hand opens to [m]: a grip must fit whichever arm picks."""
        return min(a.gripper.max_opening_m for a in self.arms)

    @property
    def neighbour_spacing_m(self) -> float | None:
        """The least distance between object centres its hands need [m]; None: any task's."""
        needs = [a.gripper.neighbour_spacing_m for a in self.arms
                 if a.gripper.neighbour_spacing_m is not None]
        return max(needs) if needs else None

    def arm(self, name: str) -> ArmDescription:
        """The arm called ``name``."""
        for arm in self.arms:
            if arm.name == name:
                return arm
        raise InvalidInputError("arm", name, f"one of {', '.join(self.arm_names)} "
                                f"(the {self.name}'s arms)")


__all__ = ["ArmDescription", "CameraMount", "FingerGeometry", "GripperDescription",
           "RobotDescription"]
