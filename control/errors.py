"""Exceptions of the control package, all under :class:`ControlError`."""

from __future__ import annotations

from robots import errors as robots_errors


class ControlError(Exception):
    """Base of every error raised by ``control``."""


class InvalidInputError(ControlError, robots_errors.InvalidInputError):
    """A caller passed a value the control stack cannot use.

    The message names the field, the value and what is allowed, e.g.
    ``frame = 'tcp' is not allowed: one of the model's frames: ...``.
    """
