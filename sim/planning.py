"""The YuMi's pick planner and the obstacles of a simulated scene, as the planner wants them."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import pinocchio as pin

from control.collision import CollisionChecker, Obstacle, ShapeKind
from control.ik import IkOptions
from control.pick import PickPlannerConfig, build_arm_specs
from control.planner import PickPlanner
from control.robot_model import RobotModel
from robots import yumi
from sim.objects import PrimitiveKind, obstacle_shapes
from sim.world import TABLE_HALF_SIZE_M, World

TABLE_THICKNESS_M = 0.05  # table/table.urdf's top slab

# The planner restarts IK itself with new seeds, so each solve gives up early.
PLANNER_IK_OPTIONS = IkOptions(max_restarts=3)


def make_yumi_planner(config: PickPlannerConfig | None = None) -> PickPlanner:
    """A pick planner for both YuMi arms, nearer arm first."""
    robot = RobotModel.from_urdf(yumi.URDF_PATH, yumi.SRDF_PATH)
    checker = CollisionChecker(robot, yumi.URDF_PATH, yumi.SRDF_PATH)
    arms = build_arm_specs(
        yumi.ARM_JOINTS, yumi.TCP_FRAME, yumi.GRIPPER_JOINTS, yumi.MAX_ACCELERATION_RAD_S2,
        yumi.MAX_JERK_RAD_S3, {side: f"yumi_link_2_{side}" for side in yumi.ARM_SIDES},
    )
    return PickPlanner(robot, checker, arms, config, PLANNER_IK_OPTIONS)


def table_obstacle(world: World) -> Obstacle:
    """The table top as a box whose upper face is z = 0."""
    cx, cy = world.config.table_center_xy_m
    hx, hy = TABLE_HALF_SIZE_M
    centre = np.array([cx, cy, -TABLE_THICKNESS_M / 2])
    return Obstacle("table", ShapeKind.BOX, (2 * hx, 2 * hy, TABLE_THICKNESS_M),
                    pin.SE3(np.eye(3), centre))


def object_obstacles(world: World, bodies: Iterable[int]) -> list[Obstacle]:
    """The primitives of the given objects, at their current poses."""
    obstacles = []
    for body in bodies:
        spec = world.object_spec(body)
        for number, shape in enumerate(obstacle_shapes(spec, world.object_pose(body))):
            if shape.kind is PrimitiveKind.BOX:
                kind, size = ShapeKind.BOX, tuple(float(s) for s in shape.size_m)
            else:
                kind, size = ShapeKind.CYLINDER, (shape.size_m[0] / 2, float(shape.size_m[2]))
            obstacles.append(Obstacle(f"{spec.name}#{body}/{number}", kind, size,
                                      shape.pose.as_se3()))
    return obstacles


def nearest_object(world: World, position_m: np.ndarray) -> int | None:
    """The object whose centre lies nearest a point (in the table plane), or None if none."""
    bodies = list(world.objects)
    if not bodies:
        return None
    distances = [np.linalg.norm(world.object_pose(b).position[:2] - position_m[:2]) for b in bodies]
    return bodies[int(np.argmin(distances))]
