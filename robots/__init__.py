"""Robot descriptions: URDF files and the small facts a planner needs about them.

Each robot is a :class:`~robots.description.RobotDescription`; :func:`get_robot` finds one by
name (``gva`` records name the robot a run used).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robots.errors import InvalidInputError

if TYPE_CHECKING:
    from robots.description import RobotDescription

ROBOT_NAMES = ("yumi", "panda")
"""The robots gva describes."""
DEFAULT_ROBOT = "yumi"
"""The robot a run uses when its user names none: the paper's. The one default of a robot;
below the settings a user fills, every function takes its robot resolved (docs/design.md)."""


def get_robot(name: str) -> RobotDescription:
    """The description of the robot called ``name`` (one of :data:`ROBOT_NAMES`)."""
    if name == "yumi":
        from robots.yumi import YUMI

        return YUMI
    if name == "panda":  # example-robot-data, and so Pinocchio, loads only here
        from robots.panda import panda

        return panda()
    raise InvalidInputError("robot", name, f"one of {', '.join(ROBOT_NAMES)}")


__all__ = ["DEFAULT_ROBOT", "ROBOT_NAMES", "get_robot"]
