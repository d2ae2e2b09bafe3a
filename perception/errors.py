"""Exceptions of the perception package, all under :class:`PerceptionError`."""

from __future__ import annotations


class PerceptionError(Exception):
    """Base of every error raised by ``perception``."""


class InvalidInputError(PerceptionError, ValueError):
    """A value a model cannot use; the message names the field, the value and what is allowed."""

    def __init__(self, field: str, value: object, allowed: str) -> None:
        self.field, self.value, self.allowed = field, value, allowed
        super().__init__(f"{field} = {value!r} is not allowed: {allowed}")

    def __reduce__(self) -> tuple[type, tuple[str, object, str]]:
        """Pickled by its three fields: it crosses to and from worker processes (and Ray)."""
        return type(self), (self.field, self.value, self.allowed)


class InvalidPredictionError(PerceptionError):
    """A model's prediction a robot cannot act on; the message says what was wrong with it."""


__all__ = ["InvalidInputError", "InvalidPredictionError", "PerceptionError"]
