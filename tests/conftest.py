"""Shared fixtures: heavy models load once per test session."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from control.collision import CollisionChecker
from control.planner import PickPlanner
from control.robot_model import RobotModel
from robots import yumi


@pytest.fixture(scope="session")
def yumi_model() -> RobotModel:
    return RobotModel.from_urdf(yumi.URDF_PATH, yumi.SRDF_PATH)


@pytest.fixture(scope="session")
def yumi_home(yumi_model: RobotModel) -> np.ndarray:
    return yumi_model.q_from_dict(yumi.HOME)


@pytest.fixture(scope="session")
def yumi_checker(yumi_model: RobotModel) -> CollisionChecker:
    return CollisionChecker(yumi_model, yumi.URDF_PATH, yumi.SRDF_PATH)


@pytest.fixture(scope="session")
def yumi_planner() -> PickPlanner:
    from sim.planning import make_yumi_planner

    return make_yumi_planner()


def top_down(x: float, y: float, z: float, yaw: float = np.pi / 2) -> pin.SE3:
    """A TCP pose pointing straight down, fingers closing along the yawed x axis."""
    down = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    return pin.SE3(pin.utils.rotate("z", yaw) @ down, np.array([x, y, z]))
