"""A robot as data: the YuMi's description agrees with its fact sheet's names, and bad
descriptions are refused with the field, the value and what is allowed."""

from __future__ import annotations

import pickle
from dataclasses import replace

import pytest

from control.errors import InvalidInputError as ControlInputError
from perception.errors import InvalidInputError as PerceptionInputError
from robots import ROBOT_NAMES, get_robot, robot_identity, unnamed_robot, yumi
from robots.errors import InvalidInputError
from robots.yumi import specs


def test_the_yumi_description_is_the_yumi_modules_facts():
    robot = get_robot("yumi")
    assert robot is yumi.YUMI and robot.name in ROBOT_NAMES
    assert robot.arm_names == yumi.ARM_SIDES
    assert (robot.urdf_path, robot.srdf_path) == (yumi.URDF_PATH, yumi.SRDF_PATH)
    for side in yumi.ARM_SIDES:
        arm = robot.arm(side)
        assert arm.joints == yumi.ARM_JOINTS[side]
        assert (arm.tcp_frame, arm.flange_frame) == (yumi.TCP_FRAME[side], yumi.FLANGE_FRAME[side])
        assert arm.shoulder_frame == f"yumi_link_2_{side}"
        assert arm.gripper.finger_joints == yumi.GRIPPER_JOINTS[side]
        assert arm.gripper.max_opening_m == pytest.approx(0.050)  # facts §2.2: 2 x 25 mm
        assert arm.gripper.max_payload_kg == specs.PAYLOAD_KG
        assert dict(arm.max_acceleration_rad_s2) == {
            j: yumi.MAX_ACCELERATION_RAD_S2[j] for j in arm.joints}
        assert dict(arm.max_jerk_rad_s3) == {j: yumi.MAX_JERK_RAD_S3[j] for j in arm.joints}
    assert dict(robot.home) == dict(yumi.HOME)
    assert yumi.FINGERS.tip_beyond_tcp_m == pytest.approx(0.0215)


def test_a_bad_description_is_refused_by_name():
    robot = yumi.YUMI
    with pytest.raises(InvalidInputError, match=r"robot 'yumi' arms = \(\) is not allowed: at "
                                                r"least one arm"):
        replace(robot, arms=())
    with pytest.raises(InvalidInputError, match=r"robot 'yumi' home = .* a position for "
                                                r"every arm and finger joint \(missing "
                                                r"\['yumi_joint_1_r'"):
        replace(robot, home={k: v for k, v in robot.home.items() if k != "yumi_joint_1_r"})
    arm = robot.arm("r")
    with pytest.raises(InvalidInputError, match=r"robot 'yumi' arm names = \('r', 'r'\)"):
        replace(robot, arms=(arm, arm))
    with pytest.raises(InvalidInputError, match=r"arm 'r' max_jerk_rad_s3 = .*\(missing "
                                                r"\['yumi_joint_1_r', "):
        replace(arm, max_jerk_rad_s3={})
    with pytest.raises(InvalidInputError, match=r"gripper.max_opening_m = -0.05 is not allowed: "
                                                r"a finite number > 0"):
        replace(arm.gripper, max_opening_m=-0.05)
    with pytest.raises(InvalidInputError, match=r"gripper.neighbour_spacing_m = 0.0 is not "
                                                r"allowed: a finite number > 0"):
        replace(arm.gripper, neighbour_spacing_m=0.0)
    with pytest.raises(InvalidInputError, match=r"arm = 'x' is not allowed: one of r, l \(the "
                                                r"yumi's arms\)"):
        robot.arm("x")
    with pytest.raises(InvalidInputError, match=r"robot = 'ur5' is not allowed: one of yumi"):
        get_robot("ur5")


def test_an_identity_names_every_robot_but_the_yumi():
    """Folders and datasets from before other robots (all the YuMi's) keep their identity."""
    assert robot_identity("yumi") == {}
    assert robot_identity("panda") == {"robot": "panda"}
    assert robot_identity(unnamed_robot().name) == {}  # the robot an identity leaves unnamed


def test_every_packages_bad_input_error_is_one_error():
    """One ``except`` catches bad input from any package; each crosses processes intact."""
    for error in (InvalidInputError("f", 1, "2"), ControlInputError("f", 1, "2"),
                  PerceptionInputError("f", 1, "2")):
        assert isinstance(error, InvalidInputError) and isinstance(error, ValueError)
        again = pickle.loads(pickle.dumps(error))
        assert type(again) is type(error) and str(again) == "f = 1 is not allowed: 2"
