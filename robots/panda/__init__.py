"""The Franka Emika Panda with its hand, from example-robot-data (issue 39).

:data:`PANDA` describes it as the pick stack reads a robot: one arm, ``panda_joint1..7``, the
Franka Hand. Its URDF is example-robot-data's ``panda.urdf`` with one frame added,
``panda_grasp_tcp``: ``panda_hand_tcp`` turned a quarter turn about its z axis, so that the
fingers close along the frame's x axis as every grasp here is stated (the hand's own TCP
closes them along y). The patched file is written once per installed version into a cache
folder, its mesh paths made absolute, so PyBullet and Pinocchio read the same file from
anywhere. example-robot-data is imported only when :func:`panda` is first called:
``perception`` reads ``robots`` and must not load Pinocchio.
"""

from __future__ import annotations

import functools
import hashlib
import math
import os
import re
from pathlib import Path

from robots.description import (
    ArmDescription,
    CameraMount,
    FingerGeometry,
    GripperDescription,
    RobotDescription,
)

ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
FINGER_JOINTS = ("panda_finger_joint1", "panda_finger_joint2")
GRASP_FRAME = "panda_grasp_tcp"
"""The tool frame grasps are given for: z along the approach, x the fingers' closing axis."""

MAX_ACCELERATION_RAD_S2 = dict(zip(ARM_JOINTS, (3.75, 1.875, 2.5, 3.125, 3.75, 5.0, 5.0),
                                   strict=True))
"""Planning limits of MoveIt's Panda configuration (moveit_resources, panda_moveit_config/
config/joint_limits.yaml): a quarter of Franka's rate limits (libfranka ``kMaxJointAcceleration``
15, 7.5, 10, 12.5, 15, 20, 20 rad/s^2)."""
MAX_JERK_RAD_S3 = dict.fromkeys(ARM_JOINTS, 300.0)
"""The jerk limit the same MoveIt configuration states for Ruckig (300 rad/s^3 on each joint;
libfranka allows 3750-10000)."""
HOME_RAD = dict(zip(ARM_JOINTS, (0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2,
                                 math.pi / 4), strict=True))
"""The SRDF's ``default`` pose (Franka's "ready" pose), the hand closed."""
FINGER_TRAVEL_M = 0.04
"""Each finger's stroke in the URDF (0..0.04 m): the hand opens 80 mm."""
FINGER_MAX_FORCE_N = 100.0
"""The URDF's finger effort limit [N]."""
FINGER_MAX_SPEED_M_S = 0.2
"""The URDF's finger velocity limit [m/s]."""
PAYLOAD_KG = 3.0
"""Franka's stated payload, as usually quoted."""
FINGERS = FingerGeometry(tip_beyond_tcp_m=0.0095, length_m=0.0545, half_width_m=0.011,
                         thickness_m=0.015)
"""The fingers in the grasp frame (the URDF's finger collision boxes: the pads end about
9.5 mm past ``panda_hand_tcp``)."""
NEIGHBOUR_SPACING_M = 0.16
"""Object centres a scene keeps apart for the Panda's hand [m]: its collision hull reaches
0.104 m from the TCP along the closing axis (``panda_hand``'s y), 77 mm above the TCP, so at a
sponge's grasp it passes a spray bottle (170 mm tall, 4.7 cm from its centre to its farthest
corner) nearer than 0.151 m; rounded up to the centimetre. The YuMi's hand fits the tasks'
own 0.12 m (docs/decisions/robots.md)."""
STAND_CAMERA = CameraMount(position_m=(0.95, 0.0, 0.55), target_m=(0.475, 0.0, 0.0))
"""A camera on a stand across the workspace, looking back at it and the robot (a Panda's hand
at home is where the YuMi's head camera sits). No heatmap focus is derived for it, so models
read the whole heatmap: the head camera's sizes, rescaled, would cut the spray bottle more, and
seen from this side the part cut lies along its side grasp's approach (docs/decisions/robots.md,
"The focus is each camera's")."""
FOOTPRINT_M = ((-0.16, 0.08), (-0.10, 0.10))
"""x and y ranges of ``panda_link0`` on the table [m] (its collision mesh's box)."""


def _cache_folder() -> Path:
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(root) / "gva" / "robots"


@functools.cache
def files() -> tuple[Path, Path]:
    """The patched URDF (written on the first call) and example-robot-data's SRDF."""
    from example_robot_data.robots_loader import PandaLoader, getModelPath

    folder = Path(getModelPath(PandaLoader.path)) / PandaLoader.path
    source = folder / PandaLoader.urdf_subpath / PandaLoader.urdf_filename
    srdf = folder / PandaLoader.srdf_subpath / PandaLoader.srdf_filename
    text = source.read_text(encoding="utf-8")
    models = Path(getModelPath(PandaLoader.path)).resolve()
    # package://example-robot-data/robots/<x> -> the installed file, so no search path is needed
    text = re.sub(r"package://example-robot-data/robots/", models.as_posix() + "/", text)
    frame = (f'  <joint name="{GRASP_FRAME}_joint" type="fixed">\n'
             f'    <parent link="panda_hand_tcp"/>\n    <child link="{GRASP_FRAME}"/>\n'
             f'    <origin xyz="0 0 0" rpy="0 0 {math.pi / 2!r}"/>\n  </joint>\n'
             f'  <link name="{GRASP_FRAME}">\n    <inertial>\n      <mass value="0"/>\n'
             f'      <origin rpy="0 0 0" xyz="0 0 0"/>\n      <inertia ixx="0" ixy="0" '
             f'ixz="0" iyy="0" iyz="0" izz="0"/>\n    </inertial>\n  </link>\n')  # massless
    patched = text.replace("</robot>", frame + "</robot>")
    digest = hashlib.sha256(patched.encode()).hexdigest()[:12]
    target = _cache_folder() / f"panda-{digest}.urdf"
    if not target.is_file():
        target.parent.mkdir(parents=True, exist_ok=True)
        temporary = target.with_suffix(f".{os.getpid()}.tmp")
        temporary.write_text(patched, encoding="utf-8")
        temporary.replace(target)  # atomic: a concurrent reader sees all of it or nothing
    return target, srdf


@functools.cache
def panda() -> RobotDescription:
    """The Panda, standing at the world origin like the YuMi."""
    urdf, srdf = files()
    gripper = GripperDescription(
        finger_joints=FINGER_JOINTS, max_opening_m=2 * FINGER_TRAVEL_M,
        max_force_n=FINGER_MAX_FORCE_N, max_speed_m_s=FINGER_MAX_SPEED_M_S,
        max_payload_kg=PAYLOAD_KG, fingers=FINGERS, neighbour_spacing_m=NEIGHBOUR_SPACING_M)
    arm = ArmDescription(
        name="panda", joints=ARM_JOINTS, tcp_frame=GRASP_FRAME, flange_frame="panda_link8",
        shoulder_frame="panda_link2", gripper=gripper,
        max_acceleration_rad_s2=MAX_ACCELERATION_RAD_S2, max_jerk_rad_s3=MAX_JERK_RAD_S3)
    return RobotDescription(
        name="panda", urdf_path=urdf, srdf_path=srdf, base_link="panda_link0",
        footprint_m=FOOTPRINT_M, camera=STAND_CAMERA, arms=(arm,),
        home=HOME_RAD | dict.fromkeys(FINGER_JOINTS, 0.0))


__all__ = ["ARM_JOINTS", "FINGER_JOINTS", "GRASP_FRAME", "files", "panda"]
