"""The settings of the PyBullet world, checked: physics, the table's placement, the longest wait.

:class:`WorldConfig` is what :class:`~sim.world.yumi_world.World` is built with (time step,
gravity, solver, where the table stands, object sleeping, the robot's controller), and refuses
a table that does not stand under a robot's base; :func:`check_wait_s` refuses a wait longer
than the physics runs in one go (:data:`MAX_WAIT_S`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from robots.description import RobotDescription
from sim.errors import InvalidInputError
from sim.world.sim_robot import RobotConfig

TABLE_HALF_SIZE_M = (0.75, 0.5)
"""Half the table top along x and y [m]: 1.5 m x 1.0 m."""
MAX_WAIT_S = 10.0
"""Longest the physics runs in one go: a settle, the gripper's close, the hold [s] (2,400 steps
at 240 Hz). ``World.step`` refuses more, so every loop that steps the simulator ends: each is
bounded by such a wait or by a planned trajectory's length (one step per sample)."""


def check_wait_s(name: str, value: float) -> None:
    """Raises unless ``value`` is a wait the physics can run: finite, in [0, MAX_WAIT_S] s."""
    if not (math.isfinite(value) and 0.0 <= value <= MAX_WAIT_S):
        raise InvalidInputError(name, value, f"a time in [0, {MAX_WAIT_S}] s")


@dataclass(frozen=True)
class WorldConfig:
    """Physics settings and the table's placement.

    Attributes:
        time_step_s: Physics step [s]; trajectories are sampled at this rate.
        gravity_m_s2: Gravity's magnitude [m/s^2], pointing down -z.
        solver_iterations: Constraint solver iterations per step: twice PyBullet's default, for
            contact-rich steps (an object pinched between two fingers while it still touches
            the table); a step of the robot with three objects stays near 0.5 ms.
        table_center_xy_m: Centre of the table top in the world [m]. The default puts the table's
            back edge behind the robot (x = -0.4) and its front edge 1.1 m ahead.
        object_sleeping: Whether objects at rest may sleep (Bullet's deactivation): a sleeping
            object costs the solver nothing until something touches it, which wakes it. Three
            resting objects make a step about 1.1 ms awake and 0.1 ms asleep
            (``benchmarks/bench_trials.py``); a grasp wakes its object before it squeezes it.
        robot: Joint controller and finger settings.

    """

    time_step_s: float = 1.0 / 240.0
    gravity_m_s2: float = 9.81
    solver_iterations: int = 100
    table_center_xy_m: tuple[float, float] = (0.35, 0.0)
    object_sleeping: bool = True
    robot: RobotConfig = field(default_factory=RobotConfig)

    def __post_init__(self) -> None:
        if not 0.0 < self.time_step_s <= 0.01:
            raise InvalidInputError("time_step_s", self.time_step_s, "in (0, 0.01] s")
        if self.gravity_m_s2 < 0.0:
            raise InvalidInputError("gravity_m_s2", self.gravity_m_s2, ">= 0 m/s^2")
        if self.solver_iterations < 1:
            raise InvalidInputError("solver_iterations", self.solver_iterations, ">= 1")
        if not isinstance(self.object_sleeping, bool):
            raise InvalidInputError("object_sleeping", self.object_sleeping, "True or False")

    def check_robot(self, robot: RobotDescription) -> None:
        """Raises unless the table stands under all of ``robot``'s base."""
        (x_lo, x_hi), (y_lo, y_hi) = robot.footprint_m
        cx, cy = self.table_center_xy_m
        hx, hy = TABLE_HALF_SIZE_M
        if not (cx - hx <= x_lo and x_hi <= cx + hx and cy - hy <= y_lo and y_hi <= cy + hy):
            raise InvalidInputError("table_center_xy_m", self.table_center_xy_m,
                                    f"a table ({2 * hx} x {2 * hy} m) under the {robot.name}'s "
                                    f"base, x {x_lo}..{x_hi} m, y {y_lo}..{y_hi} m")
