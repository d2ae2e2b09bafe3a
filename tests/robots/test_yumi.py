"""The generated YuMi URDF against the fact sheet (shared/robots/yumi-facts.md) and PyBullet."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pybullet
import pytest

from control.robot_model import RobotModel
from robots import yumi
from robots.yumi import generate

# Fact sheet §1.2: (ABB axis, lower, upper [rad], velocity [rad/s]) in chain order, both arms.
FACT_SHEET_LIMITS = (
    (1, -2.94088, 2.94088, 3.14159),
    (2, -2.50455, 0.75922, 3.14159),
    (7, -2.94088, 2.94088, 3.14159),
    (3, -2.15548, 1.39626, 3.14159),
    (4, -5.06145, 5.06145, 6.98132),
    (5, -1.53589, 2.40855, 6.98132),
    (6, -3.99680, 3.99680, 6.98132),
)
# Fact sheet §4: ABB calibration pose, ABB order (j1, j2, j3, j4, j5, j6, j7) in degrees.
FACT_SHEET_HOME_DEG = {"r": (0, -130, 30, 0, 40, 0, -135), "l": (0, -130, 30, 0, 40, 0, 135)}
# Fact sheet §6.1 and §6.2, the 0.0405 elbow: flange (gripper_*_base) positions in [m].
FLANGE_AT_ZERO_M = {"r": (0.5677, 0.0050, 0.4154), "l": (0.5678, -0.0041, 0.4144)}
FLANGE_AT_HOME_M = {"r": (-0.0097, -0.1824, 0.1984), "l": (-0.0102, 0.1830, 0.1989)}
FACT_SHEET_TOLERANCE_M = 5e-4


@pytest.fixture(scope="session")
def robot() -> RobotModel:
    return RobotModel.from_urdf(yumi.URDF_PATH, yumi.SRDF_PATH)


@pytest.fixture(scope="session")
def bullet() -> Iterator[int]:
    client = pybullet.connect(pybullet.DIRECT)
    yield client
    pybullet.disconnect(client)


def test_committed_files_are_what_the_generator_writes() -> None:
    urdf = generate.build_urdf()
    hint = "stale: run `python -m robots.yumi.generate`"
    assert yumi.URDF_PATH.read_text() == urdf, hint
    assert yumi.SRDF_PATH.read_text() == generate.build_srdf(urdf), hint


def test_arm_joints_in_chain_order(robot: RobotModel) -> None:
    for side in yumi.ARM_SIDES:
        chain_order = tuple(f"yumi_joint_{axis}_{side}" for axis in (1, 2, 7, 3, 4, 5, 6))
        assert yumi.ARM_JOINTS[side] == chain_order
        model = robot.model
        ids = [model.getJointId(name) for name in yumi.ARM_JOINTS[side]]
        assert [model.parents[i] for i in ids] == [0, *ids[:-1]]  # each the child of the one before
        flange_joint = model.frames[robot.frame_id(yumi.FLANGE_FRAME[side])].parentJoint
        assert flange_joint == ids[-1]


@pytest.mark.parametrize("side", yumi.ARM_SIDES)
@pytest.mark.parametrize(("abb_axis", "lower", "upper", "velocity"), FACT_SHEET_LIMITS)
def test_joint_limits_are_the_fact_sheets(
    robot: RobotModel, side: str, abb_axis: int, lower: float, upper: float, velocity: float
) -> None:
    index = robot.joint_index(f"yumi_joint_{abb_axis}_{side}")
    assert robot.lower_rad[index] == pytest.approx(lower, abs=1e-9)
    assert robot.upper_rad[index] == pytest.approx(upper, abs=1e-9)
    assert robot.max_velocity[index] == pytest.approx(velocity, abs=1e-9)


def test_home_is_the_calibration_pose_within_limits(robot: RobotModel) -> None:
    assert set(yumi.HOME) == set(robot.joint_names)
    for side, degrees in FACT_SHEET_HOME_DEG.items():
        for abb_axis, value_deg in zip((1, 2, 3, 4, 5, 6, 7), degrees, strict=True):
            value_rad = yumi.HOME[f"yumi_joint_{abb_axis}_{side}"]
            assert value_rad == pytest.approx(math.radians(value_deg))
    assert robot.within_limits(robot.q_from_dict(yumi.HOME), tolerance=0.0)
    np.testing.assert_allclose(robot.reference_configurations["home"], robot.q_from_dict(yumi.HOME))


@pytest.mark.parametrize("side", yumi.ARM_SIDES)
def test_flange_positions_match_the_fact_sheet(robot: RobotModel, side: str) -> None:
    flange = yumi.FLANGE_FRAME[side]
    at_zero = robot.frame_pose(np.zeros(robot.nq), flange).translation
    at_home = robot.frame_pose(robot.q_from_dict(yumi.HOME), flange).translation
    np.testing.assert_allclose(at_zero, FLANGE_AT_ZERO_M[side], atol=FACT_SHEET_TOLERANCE_M)
    np.testing.assert_allclose(at_home, FLANGE_AT_HOME_M[side], atol=FACT_SHEET_TOLERANCE_M)


def test_tcp_is_114_2_mm_along_the_flange_z_axis(robot: RobotModel) -> None:
    q = robot.q_from_dict(yumi.HOME)
    for side in yumi.ARM_SIDES:
        T_flange_tcp = robot.frame_pose(q, yumi.FLANGE_FRAME[side]).actInv(
            robot.frame_pose(q, yumi.TCP_FRAME[side])
        )
        np.testing.assert_allclose(T_flange_tcp.translation, [0.0, 0.0, 0.1142], atol=1e-12)
        np.testing.assert_allclose(T_flange_tcp.rotation, np.eye(3), atol=1e-12)


def test_pinocchio_and_pybullet_agree_on_both_tcps(robot: RobotModel, bullet: int) -> None:
    body = pybullet.loadURDF(str(yumi.URDF_PATH), useFixedBase=True, physicsClientId=bullet)
    joint_of: dict[str, int] = {}
    link_of: dict[str, int] = {}
    for index in range(pybullet.getNumJoints(body, physicsClientId=bullet)):
        info = pybullet.getJointInfo(body, index, physicsClientId=bullet)
        link_of[info[12].decode()] = index  # a link's index is that of the joint above it
        if info[2] != pybullet.JOINT_FIXED:
            joint_of[info[1].decode()] = index
    assert set(joint_of) == set(robot.joint_names)
    tcp_links = [link_of[yumi.TCP_FRAME[side]] for side in yumi.ARM_SIDES]
    rng = np.random.default_rng(0)
    worst_m = worst_rad = 0.0
    for _ in range(1000):
        q = robot.random_configuration(rng)
        for name, index in joint_of.items():
            value = q[robot.joint_index(name)]
            pybullet.resetJointState(body, index, value, physicsClientId=bullet)
        states = pybullet.getLinkStates(
            body, tcp_links, computeForwardKinematics=True, physicsClientId=bullet
        )
        for side, state in zip(yumi.ARM_SIDES, states, strict=True):
            T_pin = robot.frame_pose(q, yumi.TCP_FRAME[side])
            position = np.array(state[4])  # worldLinkFramePosition
            rotation = np.array(pybullet.getMatrixFromQuaternion(state[5])).reshape(3, 3)
            worst_m = max(worst_m, float(np.linalg.norm(position - T_pin.translation)))
            cos_angle = (np.trace(rotation.T @ T_pin.rotation) - 1.0) / 2.0
            worst_rad = max(worst_rad, math.acos(min(1.0, float(cos_angle))))
    assert worst_m <= 1e-6
    assert worst_rad <= 1e-6
