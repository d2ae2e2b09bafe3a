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

from robots.description import (
    ArmDescription,
    CameraMount,
    FingerGeometry,
    GripperDescription,
    RobotDescription,
)
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

def _footprint() -> tuple[tuple[float, float], tuple[float, float]]:
    """The x and y ranges of the body's boxes (the base slab, the torso, the feet) [m]."""
    boxes = specs.BODY_BOXES
    x = (min(b.lower[0] for b in boxes), max(b.upper[0] for b in boxes))
    y = (min(b.lower[1] for b in boxes), max(b.upper[1] for b in boxes))
    return x, y


HEAD_CAMERA = CameraMount(position_m=(0.09, 0.0, 0.52), target_m=(0.49, 0.0, 0.0),
                          focus_window_px=24, focus_box_px=18)
"""The head camera: 5 cm above the front edge of the body's top, between the shoulders, tilted
down toward x = 0.49 m on the table (why there: ``sim.world.head_camera.CameraConfig``). Its
heatmap focus (issue 49, docs/decisions/distractor.md): over the workspace (x 0.40-0.55 m, a
115.5 px focal length) the sponge, the longest target body seen from above, spans 15-18 px (the
18 px square), and the mug's handle reaches 12-15 px from its centre (15 + 9 = 24 px)."""

FINGERS = FingerGeometry(
    tip_beyond_tcp_m=specs.FINGER_JOINT_Z_M + specs.FINGER_BOX.size[2] - specs.TCP_Z_M,
    length_m=specs.FINGER_BOX.size[2], half_width_m=0.5 * specs.FINGER_BOX.size[1],
    thickness_m=specs.FINGER_BOX.size[0])
"""The YuMi's fingers in its TCP frame; the tips reach about 21.5 mm past the TCP."""



def smart_gripper(side: ArmSide) -> GripperDescription:
    """The Smart Gripper on arm ``side``: its finger joints, stroke, force, speed and payload.

    The same hand on either arm, but for its joints' names; the object catalog states its
    grasps for it (:data:`perception.objects.object_spec.CATALOG_GRIPPER`).
    """
    return GripperDescription(
        finger_joints=GRIPPER_JOINTS[side], max_opening_m=2.0 * FINGER_TRAVEL_M,
        max_force_n=FINGER_MAX_FORCE_N, max_speed_m_s=FINGER_MAX_SPEED_M_S,
        max_payload_kg=specs.PAYLOAD_KG, fingers=FINGERS)


YUMI = RobotDescription(
    name="yumi", urdf_path=URDF_PATH, srdf_path=SRDF_PATH, base_link="yumi_body",
    footprint_m=_footprint(),
    camera=HEAD_CAMERA,
    arms=tuple(ArmDescription(
        name=side, joints=ARM_JOINTS[side], tcp_frame=TCP_FRAME[side],
        flange_frame=FLANGE_FRAME[side], shoulder_frame=specs.arm_link_name(2, side),
        gripper=smart_gripper(side),
        max_acceleration_rad_s2={j: MAX_ACCELERATION_RAD_S2[j] for j in ARM_JOINTS[side]},
        max_jerk_rad_s3={j: MAX_JERK_RAD_S3[j] for j in ARM_JOINTS[side]},
    ) for side in ARM_SIDES),
    home=HOME)
"""The YuMi as the pick stack reads it (:class:`~robots.description.RobotDescription`): the two
arms, right first, each with its Smart Gripper; the names above are its parts."""

__all__ = [
    "ARM_JOINTS",
    "ARM_SIDES",
    "FINGERS",
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
    "YUMI",
    "ArmSide",
    "smart_gripper",
]
