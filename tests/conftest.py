"""Shared fixtures: heavy models load once per test session."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from control.collision import CollisionChecker
from control.planner import PickPlanner
from control.robot_model import RobotModel
from control.trajectory import JointLimits
from robots import yumi
from robots.yumi import YUMI


@pytest.fixture(scope="session")
def yumi_model() -> RobotModel:
    return RobotModel.from_urdf(yumi.URDF_PATH, yumi.SRDF_PATH)


@pytest.fixture(scope="module", params=yumi.ARM_SIDES)
def limits(request: pytest.FixtureRequest, yumi_model: RobotModel) -> JointLimits:
    """Each arm's trajectory limits in turn (URDF positions and velocities, stated a and j)."""
    return JointLimits.from_robot(yumi_model, yumi.ARM_JOINTS[request.param],
                                  yumi.MAX_ACCELERATION_RAD_S2, yumi.MAX_JERK_RAD_S3)


@pytest.fixture(scope="session")
def right(yumi_model: RobotModel) -> JointLimits:
    """The right arm's trajectory limits."""
    return JointLimits.from_robot(yumi_model, yumi.ARM_JOINTS["r"],
                                  yumi.MAX_ACCELERATION_RAD_S2, yumi.MAX_JERK_RAD_S3)


@pytest.fixture(scope="session")
def yumi_home(yumi_model: RobotModel) -> np.ndarray:
    return yumi_model.q_from_dict(yumi.HOME)


@pytest.fixture(scope="session")
def yumi_checker(yumi_model: RobotModel) -> CollisionChecker:
    return CollisionChecker(yumi_model, yumi.URDF_PATH, yumi.SRDF_PATH)


@pytest.fixture(scope="session")
def yumi_planner() -> PickPlanner:
    from sim.trials.planner_setup import make_planner

    return make_planner(YUMI)


class DepthView:
    """What the head camera's depth image makes of a scene of boxes: the planner's obstacles.

    Each box (an :class:`~control.collision.Obstacle` of kind BOX) is put into a PyBullet world
    as a static body, the camera renders, and the points become height fields as in a trial.
    """

    def __init__(self) -> None:
        from sim.world.head_camera import HeadCamera, camera_config
        from sim.world.yumi_world import World

        self.world, self.camera = World(robot=YUMI), HeadCamera(camera_config(YUMI))
        self.world.reset_scene()

    def obstacles(self, boxes, grasp: pin.SE3 | None = None, opening_m: float = 0.05):
        """(obstacles, target obstacles) the depth image of ``boxes`` gives, table excluded."""
        import pybullet

        from control.depth_obstacles import GraspRegion, depth_obstacles
        from sim.trials.planner_setup import depth_config

        client, bodies = self.world.client, []
        for box in boxes:
            half = [s / 2 for s in box.size]
            shape = client.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half)
            look = client.createVisualShape(pybullet.GEOM_BOX, halfExtents=half)
            bodies.append(client.createMultiBody(0.0, shape, look, box.T_world_shape.translation
                                                 .tolist()))
        try:
            frame = self.camera.render_rgbd(client)
        finally:
            for body in bodies:
                client.removeBody(body)
        region = None if grasp is None else GraspRegion(grasp, opening_m)
        seen = depth_obstacles(frame.points_world(), np.asarray(frame.camera.position_m),
                               depth_config(YUMI), region)
        return seen.obstacles, seen.target_obstacles


@pytest.fixture(scope="session")
def depth_view():
    view = DepthView()
    yield view
    view.world.close()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """A test marked ``ray`` lives in a ``test_ray_*.py`` file: make test's Ray phase collects
    only those files (collecting the whole suite to select 14 tests cost it some 6 s).

    Then the scopes ``make test``'s workers take whole (a module, or a class where a module has
    classes: ``--dist loadscope``) are put in order, those holding a ``slow`` test first, each
    group in the order collected: the long scopes start while the other worker still has short
    ones to take, so no worker ends the run alone on one (``--no-loadscope-reorder`` keeps this
    order; xdist's own orders by the count of tests, which put a 15 s module of two tests last).
    """
    strays = [item.nodeid for item in items
              if item.get_closest_marker("ray") and not item.path.name.startswith("test_ray_")]
    if strays:
        raise pytest.UsageError(f"marked ray outside a test_ray_*.py file: {', '.join(strays)}")
    scopes: dict[str, list[pytest.Item]] = {}
    for item in items:
        scopes.setdefault(_scope(item.nodeid), []).append(item)
    slow = {scope for scope, held in scopes.items()
            if any(item.get_closest_marker("slow") for item in held)}
    order = sorted(scopes, key=lambda scope: scope not in slow)  # stable: collected order kept
    items[:] = [item for scope in order for item in scopes[scope]]


def _scope(nodeid: str) -> str:
    """The scope ``--dist loadscope`` gives a test: its module, or its module's class."""
    return nodeid.rsplit("::", 1)[0]


@pytest.fixture(scope="session")
def local_ray(request):
    """A local Ray of 2 CPUs, as CI's machine has, shared by every Ray test (started once).

    A pool that finds Ray running joins it and leaves it running, so each test pays no start.
    Only tests marked ``ray`` may take it: make test runs those alone, after the rest.
    """
    import ray

    for item in request.session.items:
        if "local_ray" in getattr(item, "fixturenames", ()) and not item.get_closest_marker("ray"):
            pytest.fail(f"{item.nodeid} uses local_ray: mark its module pytest.mark.ray")

    from harness.ray_jobs import start_local_ray

    start_local_ray(2)
    yield
    ray.shutdown()
