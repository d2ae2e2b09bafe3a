"""The Panda (example-robot-data) as a second robot: its description, and the planner's stack
on it unchanged: Pinocchio and PyBullet agree on its frames, its home is free of collisions, the
collision checker reads its meshes (as convex hulls, which a depth height field collides with),
and IK reaches the YuMi's workspace from home."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pybullet
import pytest
from pybullet_utils import bullet_client

from control.collision import CollisionChecker, HeightField
from control.ik import ArmIk, IkOptions
from control.robot_model import RobotModel
from robots import get_robot, yumi
from robots.description import RobotDescription


@pytest.fixture(scope="module", params=["yumi", "panda"])
def robot(request: pytest.FixtureRequest) -> RobotDescription:
    return get_robot(request.param)


@pytest.fixture(scope="module")
def model(robot: RobotDescription) -> RobotModel:
    return RobotModel.from_urdf(robot.urdf_path, robot.srdf_path)


def test_the_panda_is_one_arm_whose_grasp_frame_closes_along_x():
    panda = get_robot("panda")
    assert panda.arm_names == ("panda",)
    arm = panda.arm("panda")
    assert arm.joints == tuple(f"panda_joint{i}" for i in range(1, 8))
    assert arm.gripper.max_opening_m == pytest.approx(0.08)
    model = RobotModel.from_urdf(panda.urdf_path, panda.srdf_path)
    q = model.q_from_dict(panda.home)
    hand_tcp = model.frame_pose(q, "panda_hand_tcp")
    grasp = model.frame_pose(q, arm.tcp_frame)
    np.testing.assert_allclose(grasp.translation, hand_tcp.translation, atol=1e-12)
    # the grasp frame's x is the hand's y (the fingers' axis), z the same approach
    np.testing.assert_allclose(grasp.rotation[:, 0], hand_tcp.rotation[:, 1], atol=1e-12)
    np.testing.assert_allclose(grasp.rotation[:, 2], hand_tcp.rotation[:, 2], atol=1e-12)
    assert panda.urdf_path == get_robot("panda").urdf_path  # written once, then reused


def test_pinocchio_and_pybullet_agree_on_every_arms_tool_frame(robot, model):
    client = bullet_client.BulletClient(connection_mode=pybullet.DIRECT)
    try:
        body = client.loadURDF(str(robot.urdf_path), useFixedBase=True)
        index = {client.getJointInfo(body, j)[1].decode(): j for j in range(
            client.getNumJoints(body))}
        links = {client.getJointInfo(body, j)[12].decode(): j for j in range(
            client.getNumJoints(body))}
        rng = np.random.default_rng(39)
        for _ in range(20):
            q = model.q_from_dict(robot.home)
            for arm in robot.arms:
                where = model.joint_indices(arm.joints)
                q[where] = rng.uniform(model.lower_rad[where], model.upper_rad[where])
            for name in model.joint_names:
                client.resetJointState(body, index[name], float(q[model.joint_index(name)]))
            for arm in robot.arms:
                state = client.getLinkState(body, links[arm.tcp_frame],
                                            computeForwardKinematics=True)
                rotation = np.array(client.getMatrixFromQuaternion(state[5])).reshape(3, 3)
                pose = model.frame_pose(q, arm.tcp_frame)
                np.testing.assert_allclose(state[4], pose.translation, atol=1e-6)
                np.testing.assert_allclose(rotation, pose.rotation, atol=1e-6)
    finally:
        client.disconnect()


def test_home_is_free_and_the_depth_field_collides_with_the_hand(robot, model):
    checker = CollisionChecker(model, robot.urdf_path, robot.srdf_path)
    home = model.q_from_dict(robot.home)
    assert not checker.check(home).in_collision
    arm = robot.arms[0]
    tcp = model.frame_pose(home, arm.tcp_frame).translation
    heights = np.zeros((21, 21))
    heights[10, 10] = tcp[2] + 0.02  # a post up through the tool frame
    field = HeightField("depth", (tcp[0] - 0.05, tcp[1] - 0.05), 0.005, heights, 0.0)
    checker.set_obstacles([field])
    report = checker.check(home, stop_at_first=False)
    assert report.in_collision and all(b == "depth" for _, b in report.pairs)


def test_ik_reaches_the_workspace_top_down_from_home(robot, model):
    """Every grasp position of the YuMi's workspace, from above, at both ends of its height."""
    home = model.q_from_dict(robot.home)
    arms = {arm.name: ArmIk(model, arm.joints, arm.tcp_frame, IkOptions()) for arm in robot.arms}
    down = pin.utils.rotate("x", np.pi)
    for x in (0.40, 0.55):
        for y in (-0.2, 0.0, 0.2):
            for z in (0.03, 0.13):
                goal = pin.SE3(down, np.array([x, y, z]))
                assert any(ik.solve(goal, home).solved for ik in arms.values()), (x, y, z)


def test_the_yumi_keeps_its_two_arms():
    assert get_robot("yumi").arm_names == yumi.ARM_SIDES
