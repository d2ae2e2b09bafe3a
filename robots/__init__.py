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
_UNNAMED_ROBOT = "yumi"
"""The robot identities leave unnamed: every run folder and dataset made before another robot
existed is the YuMi's. Not :data:`DEFAULT_ROBOT`, though the same today: were the default to
change, those folders would still be the YuMi's."""


def get_robot(name: str) -> RobotDescription:
    """The description of the robot called ``name`` (one of :data:`ROBOT_NAMES`)."""
    if name == "yumi":
        from robots.yumi import YUMI

        return YUMI
    if name == "panda":  # example-robot-data, and so Pinocchio, loads only here
        from robots.panda import panda

        return panda()
    raise InvalidInputError("robot", name, f"one of {', '.join(ROBOT_NAMES)}")


def unnamed_robot() -> RobotDescription:
    """The robot an identity means where it names none (:data:`_UNNAMED_ROBOT`, the YuMi).

    What a record holds of a robot without naming it is this robot's: a trial run's obstacle
    identity keeps its depth settings whatever robot picks, as identities always have.
    """
    return get_robot(_UNNAMED_ROBOT)


def robot_identity(name: str) -> dict[str, str]:
    """The robot's part of an identity or record: ``{"robot": name}``, or nothing for the YuMi.

    The one rule every run, dataset and folder identity follows (``run.json``, a dataset's
    ``extra``, ``gva reproduce real``'s folders), so those made before other robots existed
    keep their identity.
    """
    return {} if name == _UNNAMED_ROBOT else {"robot": name}


__all__ = ["DEFAULT_ROBOT", "ROBOT_NAMES", "get_robot", "robot_identity", "unnamed_robot"]
