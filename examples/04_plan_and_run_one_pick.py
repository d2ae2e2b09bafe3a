"""Plan and run one pick: a sponge on the table, its grasp, the planner, the simulator.

    python examples/04_plan_and_run_one_pick.py

The grasp pose here comes straight from the object catalog (what the oracle would predict);
the planner picks the nearer arm, checks every sample of every segment for collisions, and the
simulator tracks the plan at the physics rate and judges the pick by physics.
"""

from __future__ import annotations

import time

from control.pick import PickRequest
from robots import yumi
from sim.execution import ExecutionSettings, execute_pick
from sim.grasps import grasp_pose
from sim.objects import get_object_spec
from sim.planning import make_yumi_planner, table_obstacle
from sim.world import World


def main() -> None:
    planner = make_yumi_planner()
    with World() as world:
        world.reset_scene(yumi.HOME)
        sponge = get_object_spec("sponge")
        body = world.add_object(sponge, position_xy_m=(0.42, -0.08), yaw_rad=0.6)
        world.step(60)  # let it settle

        T_world_grasp = grasp_pose(sponge, world.object_pose(body)).as_se3()
        print("grasp TCP position [m]:", T_world_grasp.translation.round(4))

        started = time.perf_counter()
        result = planner.plan(PickRequest(
            T_world_grasp=T_world_grasp,
            q_start=planner.robot.q_from_dict(world.robot.joint_positions()),
            obstacles=(table_obstacle(world),),
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
