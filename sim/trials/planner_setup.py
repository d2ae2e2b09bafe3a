"""A robot's pick planner and the obstacles of a scene, as the planner wants them.

Every function takes the robot that picks (a :class:`~robots.description.RobotDescription`,
resolved once where a run starts). A pick is planned against the table (a fixed, known fixture)
and what the head camera's depth image shows (:func:`depth_config`,
:mod:`control.depth_obstacles`): the default, and the
only source of the paper's tables. :attr:`ObstacleSource.TRUTH` gives the planner the
simulator's true object shapes instead; it exists to debug the planner (does a failure come
from what the camera saw?) and reads what no real robot knows.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable

import numpy as np
import pinocchio as pin

from control.collision import CollisionChecker, Obstacle, ShapeKind
from control.depth_obstacles import DepthObstacleConfig, FingerBox, GraspRegion, depth_obstacles
from control.ik import IkOptions
from control.pick import PickPlannerConfig, build_arm_specs
from control.planner import PickPlanner
from control.robot_model import RobotModel
from perception.camera import RgbdFrame
from perception.objects.catalog import PrimitiveKind, obstacle_shapes
from robots.description import RobotDescription
from sim.trials.pick_results import PickObstacles
from sim.world.world_config import TABLE_HALF_SIZE_M, WorldConfig
from sim.world.yumi_world import World

TABLE_THICKNESS_M = 0.05  # table/table.urdf's top slab

class ObstacleSource(enum.Enum):
    """What a pick is planned around, besides the table."""

    DEPTH = "depth"  # the head camera's depth image: what a real robot has
    TRUTH = "truth"  # the simulator's true shapes: for debugging the planner only

# The planner restarts IK itself with new seeds, so each solve gives up early.
PLANNER_IK_OPTIONS = IkOptions(max_restarts=3)


def make_planner(robot: RobotDescription, config: PickPlannerConfig | None = None
                 ) -> PickPlanner:
    """A pick planner for every arm of ``robot`` (the YuMi's two), nearer arm first."""
    model = RobotModel.from_urdf(robot.urdf_path, robot.srdf_path)
    checker = CollisionChecker(model, robot.urdf_path, robot.srdf_path)
    return PickPlanner(model, checker, build_arm_specs(robot), config, PLANNER_IK_OPTIONS)


DEPTH_PADDING_M = 0.005
"""How much the obstacles seen in depth are grown [m]: one 5 mm cell. An object's true edge lies
between the last pixel on it and the first beyond, up to a pixel's footprint (4-6 mm on the
workspace at 128 x 128 px) outside its outline, and the camera's hand-eye error (0.25 deg RMS,
docs/decisions/d435-sensor.md) shifts what it sees by 2.6 mm at the table; with the checker's 2 mm,
7 mm in all. Without it a re-targeted approach passed 0.6 mm from a spray bottle's head that
the depth image placed 2 mm away, and touched it (issue 36)."""


def depth_config(robot: RobotDescription, config: WorldConfig | None = None
                 ) -> DepthObstacleConfig:
    """Depth obstacles over the table top in front of ``robot``'s base.

    The robot's own body stands behind the front of its footprint and is left out; the camera
    sees no arm link at the start of a pick (the arms rest at home, out of its view). The open
    fingers that mark the target's columns are its first arm's gripper's.
    """
    config = config or WorldConfig()
    (cx, cy), (hx, hy) = config.table_center_xy_m, TABLE_HALF_SIZE_M
    f = robot.arms[0].gripper.fingers
    fingers = FingerBox(f.tip_beyond_tcp_m, f.length_m, f.half_width_m, f.thickness_m)
    return DepthObstacleConfig(fingers, x_range_m=(robot.footprint_m[0][1], cx + hx),
                               y_range_m=(cy - hy, cy + hy), padding_m=DEPTH_PADDING_M)


def table_obstacle(world: World) -> Obstacle:
    """The table top as a box whose upper face is z = 0."""
    cx, cy = world.config.table_center_xy_m
    hx, hy = TABLE_HALF_SIZE_M
    centre = np.array([cx, cy, -TABLE_THICKNESS_M / 2])
    return Obstacle("table", ShapeKind.BOX, (2 * hx, 2 * hy, TABLE_THICKNESS_M),
                    pin.SE3(np.eye(3), centre))


def object_obstacles(world: World, bodies: Iterable[int]) -> list[Obstacle]:
    """The true primitives of the given objects, at their current poses.

    What :attr:`ObstacleSource.TRUTH` plans around: for tests and debugging, never a trial's
    default.
    """
    obstacles = []
    for body in bodies:
        spec = world.object_spec(body)
        for number, shape in enumerate(obstacle_shapes(spec, world.object_pose(body))):
            if shape.kind is PrimitiveKind.BOX:
                kind, size = ShapeKind.BOX, tuple(float(s) for s in shape.size_m)
            else:
                kind, size = ShapeKind.CYLINDER, (shape.size_m[0] / 2, float(shape.size_m[2]))
            obstacles.append(Obstacle(f"{spec.name}#{body}/{number}", kind, size,
                                      pin.SE3(shape.pose.matrix)))
    return obstacles


def nearest_object(world: World, position_m: np.ndarray) -> int | None:
    """The object whose centre lies nearest a point (in the table plane), or None if none.

    :attr:`ObstacleSource.TRUTH`'s guess at the target; a trial's default finds it in the
    depth image instead.
    """
    bodies = list(world.objects)
    if not bodies:
        return None
    distances = [np.linalg.norm(world.object_pose(b).position[:2] - position_m[:2]) for b in bodies]
    return bodies[int(np.argmin(distances))]


def pick_obstacles(world: World, source: ObstacleSource, depth: DepthObstacleConfig,
                   frame: RgbdFrame, grasp: GraspRegion, remembered: np.ndarray | None = None,
                   ) -> PickObstacles:
    """A pick's obstacles and the target's own, from ``source``, and what the record keeps.

    From depth: the frame's (:func:`~control.depth_obstacles.depth_obstacles`, ``remembered``
    points among them); from the truth, the true shapes, the object nearest the grasp the
    target's.
    """
    if source is ObstacleSource.DEPTH:
        seen = depth_obstacles(frame.points_world(), np.asarray(frame.camera.position_m), depth,
                               grasp, frame.unknown_rays(), remembered)
        return PickObstacles(seen.obstacles, seen.target_obstacles,
                             {"source": "depth"} | seen.to_record(), seen.obstacle_image)
    aimed = nearest_object(world, grasp.T_world_tcp.translation)
    others = object_obstacles(world, [b for b in world.objects if b != aimed])
    own = object_obstacles(world, [aimed]) if aimed is not None else []
    return PickObstacles(tuple(others), tuple(own),
                         {"source": "truth", "shapes": len(others) + len(own)})
