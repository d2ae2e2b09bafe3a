"""Properties of control.ik on both YuMi arms and on example-robot-data's Panda."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import example_robot_data
import numpy as np
import pinocchio as pin
import pytest

from control.errors import InvalidInputError
from control.ik import ArmIk, IkOptions, IkStatus
from control.robot_model import RobotModel
from robots import yumi

POSES_PER_ARM = 200
SUCCESS_RATE = 0.99
POSITION_OK_M = 5e-4
ROTATION_OK_RAD = 0.01
PANDA_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))


@dataclass(frozen=True)
class Arm:
    robot: RobotModel
    joints: tuple[str, ...]
    frame: str
    q_start: np.ndarray  # (nq,)
    ik: ArmIk

    @property
    def index(self) -> np.ndarray:
        return self.robot.joint_indices(self.joints)

    def random_reachable(self, rng: np.random.Generator) -> tuple[np.ndarray, pin.SE3]:
        """A random in-limit configuration of the arm and the frame pose it gives."""
        q = self.q_start.copy()
        lower, upper = self.robot.lower_rad[self.index], self.robot.upper_rad[self.index]
        q[self.index] = rng.uniform(lower, upper)
        return q, self.robot.frame_pose(q, self.frame)


@pytest.fixture(scope="session")
def yumi_robot() -> RobotModel:
    return RobotModel.from_urdf(yumi.URDF_PATH, yumi.SRDF_PATH)


@pytest.fixture(scope="session")
def panda() -> tuple[RobotModel, np.ndarray]:
    wrapper = example_robot_data.load("panda")
    return RobotModel(wrapper.model), np.array(wrapper.q0, dtype=float)


@pytest.fixture(scope="session", params=["yumi_r", "yumi_l", "panda"])
def arm(request: pytest.FixtureRequest, yumi_robot: RobotModel, panda: tuple) -> Arm:
    if request.param == "panda":
        robot, q_start = panda
        joints, frame = PANDA_JOINTS, "panda_hand_tcp"
    else:
        side = request.param[-1]
        robot, q_start = yumi_robot, yumi_robot.q_from_dict(yumi.HOME)
        joints, frame = yumi.ARM_JOINTS[side], yumi.TCP_FRAME[side]
    return Arm(robot, tuple(joints), frame, q_start, ArmIk(robot, joints, frame))


def pose_errors(T_a: pin.SE3, T_b: pin.SE3) -> tuple[float, float]:
    """Distance in [m] and rotation angle in [rad] between two poses, computed independently."""
    position_m = float(np.linalg.norm(T_a.translation - T_b.translation))
    cos_angle = (np.trace(T_a.rotation.T @ T_b.rotation) - 1.0) / 2.0
    return position_m, math.acos(float(np.clip(cos_angle, -1.0, 1.0)))


def test_reaches_random_reachable_poses_within_limits(arm: Arm) -> None:
    rng = np.random.default_rng(1234)  # the benchmark uses seed 0: different poses
    others = np.setdiff1d(np.arange(arm.robot.nq), arm.index)
    reached = 0
    for _ in range(POSES_PER_ARM):
        _, T_target = arm.random_reachable(rng)
        result = arm.ik.solve(T_target, arm.q_start)
        assert arm.robot.within_limits(result.q, tolerance=0.0)
        np.testing.assert_array_equal(result.q[others], arm.q_start[others])
        position_m, rotation_rad = pose_errors(arm.robot.frame_pose(result.q, arm.frame), T_target)
        assert position_m == pytest.approx(result.position_error_m, abs=1e-9)
        assert rotation_rad == pytest.approx(result.rotation_error_rad, abs=1e-6)
        if result.solved:
            assert position_m <= arm.ik.options.position_tolerance_m
            assert rotation_rad <= arm.ik.options.rotation_tolerance_rad
        reached += position_m <= POSITION_OK_M and rotation_rad <= ROTATION_OK_RAD
    assert reached / POSES_PER_ARM >= SUCCESS_RATE


def test_start_near_a_solution_stays_near_it(arm: Arm) -> None:
    rng = np.random.default_rng(5)
    jumps_rad = []
    for _ in range(50):
        q_solution, T_target = arm.random_reachable(rng)
        q_init = q_solution.copy()
        q_init[arm.index] += rng.normal(0.0, 0.02, len(arm.joints))
        result = arm.ik.solve(T_target, q_init)
        assert result.solved and result.restarts == 0
        jumps_rad.append(np.max(np.abs(result.q - q_solution)))
    assert np.median(jumps_rad) < 0.05 and np.max(jumps_rad) < 1.0


def test_start_at_a_solution_returns_it_unchanged(arm: Arm) -> None:
    q_solution, T_target = arm.random_reachable(np.random.default_rng(6))
    result = arm.ik.solve(T_target, q_solution)
    assert (result.status, result.iterations, result.restarts) == (IkStatus.SOLVED, 0, 0)
    np.testing.assert_array_equal(result.q, q_solution)


def test_same_call_and_same_seed_give_the_same_answer(arm: Arm) -> None:
    # Three iterations per attempt cannot converge, so every restart draws from the generator.
    ik = ArmIk(arm.robot, arm.joints, arm.frame, IkOptions(max_iterations=3, max_restarts=4))
    _, T_target = arm.random_reachable(np.random.default_rng(7))
    first, again = ik.solve(T_target, arm.q_start), ik.solve(T_target, arm.q_start)
    assert first.restarts == 4
    np.testing.assert_array_equal(first.q, again.q)
    seeded = [ik.solve(T_target, arm.q_start, rng=np.random.default_rng(1)) for _ in range(2)]
    np.testing.assert_array_equal(seeded[0].q, seeded[1].q)


def test_unreachable_target_is_reported_not_raised(arm: Arm) -> None:
    T_start = arm.robot.frame_pose(arm.q_start, arm.frame)
    T_far = pin.SE3(T_start.rotation, T_start.translation + np.array([2.0, 0.0, 0.0]))
    ik = ArmIk(arm.robot, arm.joints, arm.frame, IkOptions(max_restarts=3))
    result = ik.solve(T_far, arm.q_start)
    assert result.status is IkStatus.NOT_CONVERGED and not result.solved
    assert result.restarts == 3 and result.iterations > 0
    assert 1.0 < result.position_error_m < 3.0 and math.isfinite(result.rotation_error_rad)
    assert arm.robot.within_limits(result.q, tolerance=0.0)


def test_start_outside_the_limits_gives_an_in_limit_answer(arm: Arm) -> None:
    _, T_target = arm.random_reachable(np.random.default_rng(8))
    q_init = arm.q_start.copy()
    q_init[arm.index] = arm.robot.upper_rad[arm.index] + 1.0
    result = arm.ik.solve(T_target, q_init)
    assert result.solved and arm.robot.within_limits(result.q, tolerance=0.0)


def test_held_chain_joint_keeps_the_callers_value(panda: tuple) -> None:
    # Joint 1 is upstream of the hand but not moved: the reduced model must lock it at q_init's
    # value, not at the value seen when the solver was built.
    robot, q0 = panda
    ik = ArmIk(robot, PANDA_JOINTS[1:], "panda_hand_tcp")
    rng = np.random.default_rng(9)
    for joint_1_rad in (0.7, -1.2):
        q_target = q0.copy()
        index = robot.joint_indices(PANDA_JOINTS[1:])
        q_target[index] = rng.uniform(robot.lower_rad[index], robot.upper_rad[index])
        q_target[robot.joint_index("panda_joint1")] = joint_1_rad
        q_init = q0.copy()
        q_init[robot.joint_index("panda_joint1")] = joint_1_rad
        T_target = robot.frame_pose(q_target, "panda_hand_tcp")
        result = ik.solve(T_target, q_init)
        assert result.solved
        assert result.q[robot.joint_index("panda_joint1")] == joint_1_rad
        position_m, _ = pose_errors(robot.frame_pose(result.q, "panda_hand_tcp"), T_target)
        assert position_m <= 1e-4


# ---- bad input: the message names the field, the value and what is allowed ----

def test_unknown_joint(yumi_robot: RobotModel) -> None:
    pattern = r"^joint = 'yumi_joint_9_r' is not allowed: one of the model's joints: "
    with pytest.raises(InvalidInputError, match=pattern):
        ArmIk(yumi_robot, ["yumi_joint_9_r"], "gripper_r_tcp")


def test_joint_that_does_not_move_the_frame(yumi_robot: RobotModel) -> None:
    expected = ("joints = 'yumi_joint_1_l' is not allowed: a joint that moves gripper_r_tcp: "
                + ", ".join(yumi.ARM_JOINTS["r"]))
    with pytest.raises(InvalidInputError, match=f"^{re.escape(expected)}$"):
        ArmIk(yumi_robot, [*yumi.ARM_JOINTS["r"][:6], "yumi_joint_1_l"], "gripper_r_tcp")


@pytest.mark.parametrize("joints", [[], ["yumi_joint_1_r", "yumi_joint_1_r"]])
def test_empty_or_repeated_joints(yumi_robot: RobotModel, joints: list[str]) -> None:
    expected = f"joints = {joints!r} is not allowed: a non-empty list of distinct names"
    with pytest.raises(InvalidInputError, match=f"^{re.escape(expected)}$"):
        ArmIk(yumi_robot, joints, "gripper_r_tcp")


def test_unknown_frame(yumi_robot: RobotModel) -> None:
    pattern = r"^frame = 'tcp' is not allowed: one of the model's frames: .*gripper_r_tcp"
    with pytest.raises(InvalidInputError, match=pattern):
        ArmIk(yumi_robot, yumi.ARM_JOINTS["r"], "tcp")


@pytest.fixture(scope="module")
def right_ik(yumi_robot: RobotModel) -> ArmIk:
    return ArmIk(yumi_robot, yumi.ARM_JOINTS["r"], yumi.TCP_FRAME["r"])


def test_wrong_q_shape(right_ik: ArmIk, yumi_robot: RobotModel) -> None:
    expected = "q_init = 'array of shape (7,)' is not allowed: shape (18,)"
    with pytest.raises(InvalidInputError, match=f"^{re.escape(expected)}$"):
        right_ik.solve(pin.SE3.Identity(), np.zeros(7))


def test_nan_in_q(right_ik: ArmIk, yumi_robot: RobotModel) -> None:
    q = yumi_robot.q_from_dict(yumi.HOME)
    q[3] = np.nan
    pattern = r"^q_init = \[.*nan.*\] is not allowed: finite joint values$"
    with pytest.raises(InvalidInputError, match=pattern):
        right_ik.solve(pin.SE3.Identity(), q)


def test_target_not_se3(right_ik: ArmIk, yumi_robot: RobotModel) -> None:
    expected = "T_world_target = 'ndarray' is not allowed: a pinocchio.SE3"
    with pytest.raises(InvalidInputError, match=f"^{re.escape(expected)}$"):
        right_ik.solve(np.eye(4), yumi_robot.q_from_dict(yumi.HOME))


@pytest.mark.parametrize("rotation", [np.diag([1.0, 1.0, 2.0]), np.diag([1.0, 1.0, -1.0])])
def test_target_not_a_rigid_transform(
    right_ik: ArmIk, yumi_robot: RobotModel, rotation: np.ndarray
) -> None:
    pattern = r"^T_world_target = \[\[.*\]\] is not allowed: a finite rigid transform"
    with pytest.raises(InvalidInputError, match=pattern):
        right_ik.solve(pin.SE3(rotation, np.zeros(3)), yumi_robot.q_from_dict(yumi.HOME))


def test_rng_not_a_generator(right_ik: ArmIk, yumi_robot: RobotModel) -> None:
    expected = "rng = 0 is not allowed: a numpy.random.Generator or None"
    with pytest.raises(InvalidInputError, match=f"^{re.escape(expected)}$"):
        right_ik.solve(pin.SE3.Identity(), yumi_robot.q_from_dict(yumi.HOME), rng=0)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("field", "value", "allowed"),
    [
        ("position_tolerance_m", 0.0, "a finite number > 0"),
        ("rotation_tolerance_rad", float("nan"), "a finite number > 0"),
        ("damping", -1.0, "a finite number > 0"),
        ("rotation_weight_m", "0.1", "a finite number > 0"),
        ("limit_gain", 1.5, "a number in (0, 1]"),
        ("max_iterations", 0, "an integer >= 1"),
        ("max_restarts", 2.0, "an integer >= 0"),
        ("stall_iterations", True, "an integer >= 1"),
    ],
)
def test_bad_options(field: str, value: object, allowed: str) -> None:
    expected = f"{field} = {value!r} is not allowed: {allowed}"
    with pytest.raises(InvalidInputError, match=f"^{re.escape(expected)}$"):
        IkOptions(**{field: value})  # type: ignore[arg-type]
