"""The head camera's self filter: a frame taken with the arm in view shows neither the planner
nor the model the arm: no depth on it, and the table's colour over it."""

from __future__ import annotations

import numpy as np
import pytest
from tcp_poses import top_down

from control.pick import PickRequest
from robots import yumi
from robots.yumi import YUMI
from sim.world.head_camera import HeadCamera, camera_config
from sim.world.sensor import SensorConfig, SensorKind, SensorSeed
from sim.world.yumi_world import World


@pytest.mark.parametrize("kind", [SensorKind.IDEAL, SensorKind.D435])
def test_the_arm_in_view_leaves_no_depth_and_no_colour_of_itself(yumi_planner, yumi_home, kind):
    plan = yumi_planner.plan(PickRequest(top_down(0.45, -0.08, 0.035), yumi_home)).plan
    q_pre = plan.segment("approach").trajectory.positions[-1]  # the hand over the table
    camera, seed = HeadCamera(camera_config(YUMI), sensor=SensorConfig(kind)), SensorSeed(0)
    with World(robot=YUMI) as world:
        world.reset_scene(dict(zip(yumi.ARM_JOINTS[plan.arm], q_pre, strict=True)))
        plain = camera.render_rgbd(world.client, seed=seed)
        filtered = camera.render_rgbd(world.client, seed=seed, self_body=world.robot.body_id)
        removed = (filtered.depth_m == 0.0) & (plain.depth_m != 0.0)
        assert plain.robot_mask is None and filtered.robot_mask is not None
        np.testing.assert_array_equal(removed, filtered.robot_mask & (plain.depth_m != 0.0))
        assert removed.sum() > 100  # the hand and forearm over the table
        kept = filtered.depth_m != 0.0
        np.testing.assert_array_equal(filtered.depth_m[kept], plain.depth_m[kept])
        np.testing.assert_array_equal(filtered.rgb[kept], plain.rgb[kept])  # the rest as seen
        fill = filtered.rgb[removed][0]  # one colour over the arm: the rest's, the table's
        one = np.broadcast_to(fill, (removed.sum(), 3))
        np.testing.assert_array_equal(filtered.rgb[removed], one)
        assert np.abs(fill - np.median(plain.rgb[kept], axis=0)).max() <= 2
        assert (plain.rgb[removed] != fill).any(axis=1).mean() > 0.5  # the arm was another
        u, v = np.round(camera.project(tcp_of(world, plan.arm))).astype(int).reshape(2)
        assert (filtered.rgb[v, u] == fill).all()  # the hand's pixel shows the table
        tcp = tcp_of(world, plan.arm)
        points = filtered.points_world().reshape(-1, 3)
        points = points[np.isfinite(points).all(axis=1)]
        assert np.linalg.norm(points - tcp, axis=1).min() > 0.02  # nothing left near the hand
        near = np.linalg.norm(plain.points_world().reshape(-1, 3) - tcp, axis=1)
        assert np.nanmin(near) < 0.02  # where the unfiltered frame had the hand


def tcp_of(world: World, arm: str) -> np.ndarray:
    """Where the hand's TCP is now (world frame) [m]."""
    return world.robot.link_pose(yumi.TCP_FRAME[arm]).position
