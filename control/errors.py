"""Exceptions of the control package, all under :class:`ControlError`."""

from __future__ import annotations

from typing import Any


class ControlError(Exception):
    """Base of every error raised by ``control``."""


class InvalidInputError(ControlError, ValueError):
    """A caller passed a value the control stack cannot use.

    The message names the field, the value and what is allowed, e.g.
    ``frame = 'tcp' is not allowed: expected one of gripper_l_tcp, gripper_r_tcp``.
    """

    def __init__(self, field: str, value: Any, allowed: str) -> None:
        self.field = field
        self.value = value
        self.allowed = allowed
        super().__init__(f"{field} = {value!r} is not allowed: {allowed}")

    def __reduce__(self) -> tuple[type, tuple[str, object, str]]:
        """Pickled by its three fields: it crosses to and from worker processes (and Ray)."""
        return type(self), (self.field, self.value, self.allowed)
