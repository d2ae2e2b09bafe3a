"""Plan and run one pick from what the head camera sees: a sponge beside a mug.

    python examples/04_plan_and_run_one_pick.py

The grasp pose here comes straight from the object catalog (what the oracle would predict);
everything else is what the robot senses. The head camera's depth image becomes the planner's
obstacles (the sponge, which the fingers close on, apart from the mug it must not touch); the
planner picks the nearer arm and checks every sample of every segment; the simulator tracks the
plan at the physics rate and judges the pick by physics.
"""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin

from control.depth_obstacles import GraspRegion, depth_obstacles
from control.pick import PickRequest
from perception.objects.catalog import get_object_spec
from perception.objects.grasps import grasp_pose
from robots import yumi
from robots.yumi import YUMI
from sim.trials.execution import ExecutionSettings, execute_pick
from sim.trials.planner_setup import depth_config, make_planner, table_obstacle
from sim.world.head_camera import HeadCamera, camera_config
from sim.world.yumi_world import World


def main() -> None:
    planner = make_planner(YUMI)
    with World(robot=YUMI) as world:
        world.reset_scene(yumi.HOME)
        sponge = get_object_spec("sponge")
        body = world.add_object(sponge, position_xy_m=(0.42, -0.08), yaw_rad=0.6)
        world.add_object(get_object_spec("mug"), position_xy_m=(0.46, 0.06), yaw_rad=2.0)
        world.step(60)  # let them settle

        T_world_grasp = pin.SE3(grasp_pose(sponge, world.object_pose(body)).matrix)
        print("grasp TCP position [m]:", T_world_grasp.translation.round(4))

        frame = HeadCamera(camera_config(YUMI)).render_rgbd(world.client)  # RGB-D, calibration
        started = time.perf_counter()
        seen = depth_obstacles(frame.points_world(), np.asarray(frame.camera.position_m),
                               depth_config(YUMI), GraspRegion(T_world_grasp,
                                                                sponge.grasp.opening_m))
        print(f"depth obstacles: {seen.to_record()} in "
              f"{1000 * (time.perf_counter() - started):.1f} ms")

        started = time.perf_counter()
        result = planner.plan(PickRequest(
            T_world_grasp=T_world_grasp,
            q_start=planner.robot.q_from_dict(world.robot.joint_positions()),
            obstacles=(table_obstacle(world), *seen.obstacles),
            target_obstacles=seen.target_obstacles,
            finger_opening_m=sponge.grasp.opening_m / 2,
            pregrasp_distance_m=sponge.grasp.pregrasp_distance_m,
        ))
        print(f"plan: {result.status.value} ({result.reason}) "
              f"in {1000 * (time.perf_counter() - started):.0f} ms")
        if result.plan is None:
            return
        for segment in result.plan.segments:
            print(f"  {segment.name:<9} {segment.trajectory.duration_s:5.2f} s "
                  f"({len(segment.trajectory.times_s)} samples), gripper before: "
                  f"{segment.gripper_before.value}")

        outcome = execute_pick(world, result.plan, body, sponge.grasp.opening_m,
                               ExecutionSettings())
        print(f"outcome: {outcome.outcome.value}: {outcome.reason}; "
              f"simulated {world.time_s:.2f} s")


if __name__ == "__main__":
    main()
