"""The head camera's self filter: a frame taken with the arm in view gives no depth on the arm."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import top_down

from control.pick import PickRequest
from robots import yumi
from sim.world.head_camera import HeadCamera
from sim.world.sensor import SensorConfig, SensorKind, SensorSeed
from sim.world.yumi_world import World


@pytest.mark.parametrize("kind", [SensorKind.IDEAL, SensorKind.D435])
def test_the_arm_in_view_leaves_no_depth_on_itself(yumi_planner, yumi_home, kind):
    plan = yumi_planner.plan(PickRequest(top_down(0.45, -0.08, 0.035), yumi_home)).plan
    q_pre = plan.segment("approach").trajectory.positions[-1]  # the hand over the table
    camera, seed = HeadCamera(sensor=SensorConfig(kind)), SensorSeed(0)
    with World() as world:
        world.reset_scene(dict(zip(yumi.ARM_JOINTS[plan.arm], q_pre, strict=True)))
        plain = camera.render_rgbd(world.client, seed=seed)
        filtered = camera.render_rgbd(world.client, seed=seed, self_body=world.robot.body_id)
        np.testing.assert_array_equal(filtered.rgb, plain.rgb)  # the model still sees the arm
        removed = (filtered.depth_m == 0.0) & (plain.depth_m != 0.0)
        assert removed.sum() > 100  # the hand and forearm over the table
        kept = filtered.depth_m != 0.0
        np.testing.assert_array_equal(filtered.depth_m[kept], plain.depth_m[kept])
        tcp = world.robot.link_pose(yumi.TCP_FRAME[plan.arm]).position
        points = filtered.points_world().reshape(-1, 3)
        points = points[np.isfinite(points).all(axis=1)]
        assert np.linalg.norm(points - tcp, axis=1).min() > 0.02  # nothing left near the hand
        near = np.linalg.norm(plain.points_world().reshape(-1, 3) - tcp, axis=1)
        assert np.nanmin(near) < 0.02  # where the unfiltered frame had the hand
