"""Exceptions of the sim package, all under :class:`SimError`."""

from __future__ import annotations

from control import errors as control_errors


class SimError(Exception):
    """Base of every error raised by ``sim``."""


class InvalidInputError(SimError, control_errors.InvalidInputError):
    """A caller passed a value the simulator cannot use.

    It is also a ``control`` :class:`~control.errors.InvalidInputError` (and a ``ValueError``),
    so one ``except`` catches bad input from either package. The message names the field, the
    value and what is allowed, e.g. ``side = 'x' is not allowed: one of 'r', 'l'``.
    """


class SimulationError(SimError):
    """PyBullet refused an operation (a shape, a body or a file could not be created)."""


class TargetNotFoundError(SimError):
    """The condition names an object that is not in the scene (the oracle cannot answer)."""


class RunFolderError(SimError):
    """A run folder that cannot be resumed: it holds another run, or a damaged file."""


__all__ = ["InvalidInputError", "RunFolderError", "SimError", "SimulationError",
           "TargetNotFoundError"]
