"""The ABB IRB 14000 YuMi in numbers: the single source the URDF and SRDF are generated from.

Every number cites its section of ``shared/robots/yumi-facts.md`` (the project's fact sheet);
``robots/yumi/README.md`` lists the sources behind those sections. Lengths in [m], angles in
[rad], masses in [kg], forces in [N], torques in [N m].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

ARM_SIDES = ("r", "l")
"""Arm suffixes: ``r`` is the robot's right arm (mounted at -y), ``l`` its left (+y)."""


@dataclass(frozen=True)
class Box:
    """An axis-aligned box in a link frame, given by its bounds [m]."""

    lower: tuple[float, float, float]
    upper: tuple[float, float, float]

    @property
    def size(self) -> tuple[float, float, float]:
        """Edge lengths (x, y, z) in [m]."""
        return (
            self.upper[0] - self.lower[0],
            self.upper[1] - self.lower[1],
            self.upper[2] - self.lower[2],
        )

    @property
    def center(self) -> tuple[float, float, float]:
        """Centre in the link frame in [m]."""
        return (
            0.5 * (self.upper[0] + self.lower[0]),
            0.5 * (self.upper[1] + self.lower[1]),
            0.5 * (self.upper[2] + self.lower[2]),
        )


@dataclass(frozen=True)
class Cylinder:
    """A cylinder in a link frame: its centre [m], the link axis it runs along, radius, length."""

    center: tuple[float, float, float]
    axis: str  # "x", "y" or "z" of the link frame
    radius_m: float
    length_m: float

    @classmethod
    def spanning(cls, box: Box, axis: str, radius_m: float) -> Cylinder:
        """The cylinder that runs through a bounding box along ``axis``, with a tube's radius."""
        index = "xyz".index(axis)
        return cls(box.center, axis, radius_m, box.size[index])


@dataclass(frozen=True)
class ArmJoint:
    """One revolute joint of an arm, in chain order, with the link it moves."""

    abb_axis: int  # ABB's axis number; chain order is 1, 2, 7, 3, 4, 5, 6 (facts §0)
    origin_xyz: tuple[float, float, float]  # child frame in the parent frame (facts §1.2)
    origin_rpy: tuple[float, float, float]
    lower_rad: float
    upper_rad: float
    max_velocity_rad_s: float
    max_effort_nm: float
    link_box: Box | Cylinder  # collision and visual shape of the child link (facts §3.4)
    link_mass_kg: float


HALF_PI = math.pi / 2

# Arm mounts, body -> joint-1 frame (facts §1.1, confidence H). The two rpy triples are not exact
# mirrors of each other; the sheet says to keep them as listed.
ARM_MOUNT_XYZ = {"r": (0.05355, -0.07250, 0.41492), "l": (0.05355, 0.07250, 0.41492)}
ARM_MOUNT_RPY = {"r": (-0.9795, -0.5682, -2.3155), "l": (0.9781, -0.5716, 2.3180)}

# Elbow offset: ABB's controller uses 0.0405 m, the ROS models 0.04188 m; the fit to RobotStudio
# improves from 1.3 mm to 0.06 mm with 0.0405 (facts §1.3, confidence H).
ELBOW_OFFSET_M = 0.0405

# Effort limits: ABB publishes no joint torques (facts §1.2 says the ROS 300 N m is a placeholder).
# These are sized to about twice the largest static gravity torque of the arm with its 0.5 kg
# payload over random configurations (computed with Pinocchio from this model), so the simulated
# motors hold and track the arm like the real one without being unphysically strong.
_EFFORT_PROXIMAL_NM = 40.0
_EFFORT_WRIST_NM = 12.0

# Arm links are tubes about 0.09-0.10 m across (facts §3.4): each is a cylinder along the long
# side of its mesh bounding box. The boxes themselves overstate the tubes (they include motor
# bulges) so much that ABB's own calibration pose would self-collide.
TUBE_RADIUS_M = 0.046
WRIST_RADIUS_M = 0.040

# Link masses: no per-link data is public (facts §3.1); these split ABB's 38 kg robot weight
# (facts §5) by link size, leaving the rest to the body.
_span = Cylinder.spanning
ARM_JOINTS: tuple[ArmJoint, ...] = (
    ArmJoint(1, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), -2.94088, 2.94088, 3.14159, _EFFORT_PROXIMAL_NM,

             _span(Box((-0.061, -0.078, 0.000), (0.079, 0.062, 0.149)), "z", TUBE_RADIUS_M),
             2.0),
    ArmJoint(2, (0.03, 0.0, 0.1), (HALF_PI, 0.0, 0.0), -2.50455, 0.75922, 3.14159,
             _EFFORT_PROXIMAL_NM,
             _span(Box((-0.085, -0.048, -0.078), (0.048, 0.173, 0.054)), "y", TUBE_RADIUS_M),
             1.6),
    ArmJoint(7, (-0.03, 0.17283, 0.0), (-HALF_PI, 0.0, 0.0), -2.94088, 2.94088, 3.14159,
             _EFFORT_PROXIMAL_NM,
             _span(Box((-0.090, -0.079, 0.000), (0.047, 0.048, 0.127)), "z", TUBE_RADIUS_M),
             1.4),
    ArmJoint(3, (-ELBOW_OFFSET_M, 0.0, 0.07873), (HALF_PI, -HALF_PI, 0.0), -2.15548, 1.39626,
             3.14159, _EFFORT_PROXIMAL_NM,

             _span(Box((-0.048, -0.048, -0.078), (0.085, 0.165, 0.048)), "y", TUBE_RADIUS_M),
             1.1),
    ArmJoint(4, (0.0405, 0.16461, 0.0), (-HALF_PI, 0.0, 0.0), -5.06145, 5.06145, 6.98132,
             _EFFORT_WRIST_NM,
             _span(Box((-0.059, -0.070, 0.000), (0.042, 0.042, 0.132)), "z", WRIST_RADIUS_M),
             0.9),
    ArmJoint(5, (-0.027, 0.0, 0.10039), (HALF_PI, 0.0, 0.0), -1.53589, 2.40855, 6.98132,
             _EFFORT_WRIST_NM,
             _span(Box((-0.034, -0.066, -0.067), (0.068, 0.033, 0.027)), "y", WRIST_RADIUS_M),
             0.6),
    ArmJoint(6, (0.027, 0.029, 0.0), (-HALF_PI, 0.0, 0.0), -3.99680, 3.99680, 6.98132,
             _EFFORT_WRIST_NM, Cylinder((0.0, 0.0, 0.00075), "z", 0.0315, 0.0235), 0.2),
)
"""The seven arm joints in chain order (facts §1.2, §3.4); identical for both arms."""

# Flange: yumi_link_7 -> gripper base (= ABB tool0), (0, 0, 0.007), rpy (0, 0, pi) (§1.2, §2.1).
FLANGE_XYZ = (0.0, 0.0, 0.007)
FLANGE_RPY = (0.0, 0.0, math.pi)

# SmartGripper (facts §2): body box x +-0.0416, y +-0.0345, z 0..0.0931 in the gripper base frame.
GRIPPER_BODY = Box((-0.0416, -0.0345, 0.0), (0.0416, 0.0345, 0.0931))
GRIPPER_MASS_KG = 0.23  # ROS 0.2 kg placeholder rounded up with the servo (facts §3.1)
# Finger joints: prismatic along -x of their frames, origins (0, -+0.0065, 0.0837) (facts §2.2).
FINGER_JOINT_Z_M = 0.0837
FINGER_JOINT_Y_M = 0.0065
FINGER_TRAVEL_M = 0.025  # per finger: gap 0..50 mm (facts §2.2, ABB travel limit 25 mm)
FINGER_MAX_FORCE_N = 20.0  # ABB max grip force (facts §2.2 [TROBSG])
FINGER_MAX_SPEED_M_S = 0.025  # ABB max speed 25 mm/s (facts §2.2)
PAYLOAD_KG = 0.5  # per arm, ABB IRB 14000 data sheet as usually quoted (facts, table of §6: M)
# Finger shape in the finger-joint frame: the gripping face is x = 0, thickness 11 mm,
# y -0.0045..0.0167, length 52 mm (facts §2.3). 15 g per set (facts §2.3 [TROBSG]).
FINGER_BOX = Box((-0.011, -0.0045, 0.0), (0.0, 0.0167, 0.052))
FINGER_MASS_KG = 0.0075
# TCP between the fingertips, ABB's default finger tool frame (0, 0, 114.2 mm) from tool0 (§2.1).
TCP_Z_M = 0.1142

# Body (facts §3.3): WRS's collision boxes for the same body frame, (centre; half-sizes). They
# start at z = 0, the table top. The sheet's silhouette boxes have a shoulder block reaching
# x = +0.09 that the upper arms pass through in ABB's calibration pose, so the tighter WRS boxes
# are the ones that agree with how the real robot moves.
def _box(center: tuple[float, float, float], half: tuple[float, float, float]) -> Box:
    return Box(
        (center[0] - half[0], center[1] - half[1], center[2] - half[2]),
        (center[0] + half[0], center[1] + half[1], center[2] + half[2]),
    )


BODY_BOXES: tuple[Box, ...] = (
    _box((-0.20, 0.0, 0.04), (0.16, 0.20, 0.04)),  # base slab
    _box((-0.24, 0.0, 0.24), (0.12, 0.125, 0.24)),  # torso column
    _box((-0.07, 0.0, 0.40), (0.075, 0.125, 0.06)),  # shoulders, between the arm mounts
    _box((0.0, 0.145, 0.03), (0.135, 0.055, 0.03)),  # left foot
    _box((0.0, -0.145, 0.03), (0.135, 0.055, 0.03)),  # right foot
)
ROBOT_MASS_KG = 38.0  # ABB data sheet (facts §5, M)

# Home: ABB's calibration / sync pose, ABB order (j1, j2, j3, j4, j5, j6, j7) in degrees (§4, H).
HOME_ABB_ORDER_DEG = {
    "r": (0.0, -130.0, 30.0, 0.0, 40.0, 0.0, -135.0),
    "l": (0.0, -130.0, 30.0, 0.0, 40.0, 0.0, 135.0),
}


def arm_joint_name(abb_axis: int, side: str) -> str:
    """ROS-style joint name, numbered by ABB axis (facts §0): ``yumi_joint_7_r``."""
    return f"yumi_joint_{abb_axis}_{side}"


def arm_link_name(chain_index: int, side: str) -> str:
    """ROS-style link name, numbered in chain order (facts §0): ``yumi_link_3_r``."""
    return f"yumi_link_{chain_index}_{side}"


def body_mass_kg() -> float:
    """Mass left to the body once both arms and grippers are counted [kg]."""
    arm = sum(j.link_mass_kg for j in ARM_JOINTS) + GRIPPER_MASS_KG + 2 * FINGER_MASS_KG
    return ROBOT_MASS_KG - 2 * arm


# Acceleration and jerk limits: ABB publishes no per-joint values (facts §1.6: "No acceleration
# limits are given"). The data sheet's TCP figures are 1.5 m/s and 11 m/s^2 (facts §5, L-M). These
# stated limits keep the TCP well under 11 m/s^2 at the arm's 0.56 m reach (6 rad/s^2 x 0.56 m is
# about 3.4 m/s^2) and give smooth, quick moves of 1-2 s across the workspace.
MAX_ACCELERATION_RAD_S2 = {"proximal": 6.0, "wrist": 12.0}
MAX_JERK_RAD_S3 = {"proximal": 60.0, "wrist": 120.0}


def joint_class(abb_axis: int) -> str:
    """``"proximal"`` for axes 1, 2, 7, 3 (180 deg/s); ``"wrist"`` for 4, 5, 6 (400 deg/s)."""
    return "proximal" if abb_axis in (1, 2, 7, 3) else "wrist"
