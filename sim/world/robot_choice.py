"""Which robot a run uses: a name a user gives, resolved once, or refused with the names allowed.

Every settings class that holds a robot's name (``TrialSettings``, ``CollectSettings``,
``gva reproduce real``'s settings) and the Gymnasium env resolve it here, so one rule checks a
name and one message refuses it. Below them the description travels (docs/design.md).
"""

from __future__ import annotations

from robots import get_robot
from robots.description import RobotDescription
from robots.errors import InvalidInputError as RobotInputError
from sim.errors import InvalidInputError


def resolve_robot(name: str) -> RobotDescription:
    """The description of the robot called ``name`` (one of :data:`robots.ROBOT_NAMES`).

    Raises:
        InvalidInputError: ``name`` is no robot gva describes (``robot = 'ur5' is not
            allowed: one of yumi, panda``), as :func:`robots.get_robot` says it, under
            ``sim``'s error.

    """
    try:
        return get_robot(name)
    except RobotInputError as error:
        raise InvalidInputError(error.field, error.value, error.allowed) from None


__all__ = ["resolve_robot"]
