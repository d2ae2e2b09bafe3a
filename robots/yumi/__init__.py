"""The ABB IRB 14000 YuMi: URDF path, joint groups, home configuration and frame names.

Everything is keyed by name, never by index: Pinocchio orders joints by its own tree traversal.

Example:
    >>> from robots import yumi
    >>> yumi.ARM_JOINTS["r"][2]
    'yumi_joint_7_r'
    >>> yumi.TCP_FRAME["l"]
    'gripper_l_tcp'

"""

from __future__ import annotations

import math
from pathlib import Path
from types import MappingProxyType
from typing import Literal

from robots.yumi import specs

ArmSide = Literal["r", "l"]
"""``"r"``: the robot's right arm (at -y); ``"l"``: its left arm (at +y)."""

ARM_SIDES: tuple[ArmSide, ...] = ("r", "l")
URDF_PATH: Path = Path(__file__).resolve().parent / "yumi.urdf"
SRDF_PATH: Path = Path(__file__).resolve().parent / "yumi.srdf"

ARM_JOINTS: MappingProxyType[str, tuple[str, ...]] = MappingProxyType({
    side: tuple(specs.arm_joint_name(j.abb_axis, side) for j in specs.ARM_JOINTS)
    for side in ARM_SIDES
})
"""Arm joint names in chain order (ABB axes 1, 2, 7, 3, 4, 5, 6), per side."""

GRIPPER_JOINTS: MappingProxyType[str, tuple[str, str]] = MappingProxyType({
    side: (f"gripper_{side}_joint", f"gripper_{side}_joint_m") for side in ARM_SIDES
})
"""The two prismatic finger joints of each gripper; each opens 0 .. 0.025 m."""

TCP_FRAME: MappingProxyType[str, str] = MappingProxyType(
    {side: f"gripper_{side}_tcp" for side in ARM_SIDES}
)
"""Tool centre point between the fingers, 114.2 mm along the flange z axis (ABB's default)."""

FLANGE_FRAME: MappingProxyType[str, str] = MappingProxyType(
    {side: f"gripper_{side}_base" for side in ARM_SIDES}
)
"""ABB's tool0 on each arm."""

MAX_ACCELERATION_RAD_S2: MappingProxyType[str, float] = MappingProxyType({
    specs.arm_joint_name(j.abb_axis, side):
        specs.MAX_ACCELERATION_RAD_S2[specs.joint_class(j.abb_axis)]
    for side in ARM_SIDES
    for j in specs.ARM_JOINTS
})
"""Stated acceleration limit of each arm joint in [rad/s^2] (ABB publishes none; see specs.py)."""

MAX_JERK_RAD_S3: MappingProxyType[str, float] = MappingProxyType({
    specs.arm_joint_name(j.abb_axis, side): specs.MAX_JERK_RAD_S3[specs.joint_class(j.abb_axis)]
    for side in ARM_SIDES
    for j in specs.ARM_JOINTS
})
"""Stated jerk limit of each arm joint in [rad/s^3]."""

FINGER_TRAVEL_M: float = specs.FINGER_TRAVEL_M
FINGER_MAX_FORCE_N: float = specs.FINGER_MAX_FORCE_N
FINGER_MAX_SPEED_M_S: float = specs.FINGER_MAX_SPEED_M_S


def _home() -> dict[str, float]:
    home: dict[str, float] = {}
    for side in ARM_SIDES:
        by_axis = dict(zip((1, 2, 3, 4, 5, 6, 7), specs.HOME_ABB_ORDER_DEG[side], strict=True))
        for joint in specs.ARM_JOINTS:
            home[specs.arm_joint_name(joint.abb_axis, side)] = math.radians(by_axis[joint.abb_axis])
        for finger in GRIPPER_JOINTS[side]:
            home[finger] = 0.0
    return home


HOME: MappingProxyType[str, float] = MappingProxyType(_home())
"""ABB's calibration pose (facts §4) with closed grippers, in [rad] and [m], keyed by joint name."""

__all__ = [
    "ARM_JOINTS",
    "ARM_SIDES",
    "FINGER_MAX_FORCE_N",
    "FINGER_MAX_SPEED_M_S",
    "FINGER_TRAVEL_M",
    "FLANGE_FRAME",
    "GRIPPER_JOINTS",
    "HOME",
    "MAX_ACCELERATION_RAD_S2",
    "MAX_JERK_RAD_S3",
    "SRDF_PATH",
    "TCP_FRAME",
    "URDF_PATH",
    "ArmSide",
]
