"""The one bad-input error every package raises, each under its own base class.

``robots`` sits below ``control`` and ``perception``, so the message format and the pickling
(errors cross to worker processes and Ray) live here once; :class:`control.errors.InvalidInputError`
and :class:`perception.errors.InvalidInputError` add their package's base.
"""

from __future__ import annotations


class InvalidInputError(ValueError):
    """A value that cannot be used: the message names the field, the value and what is allowed.

    E.g. ``arms = () is not allowed: at least one arm``.
    """

    def __init__(self, field: str, value: object, allowed: str) -> None:
        self.field, self.value, self.allowed = field, value, allowed
        super().__init__(f"{field} = {value!r} is not allowed: {allowed}")

    def __reduce__(self) -> tuple[type, tuple[str, object, str]]:
        """Pickled by its three fields: it crosses to and from worker processes (and Ray)."""
        return type(self), (self.field, self.value, self.allowed)


__all__ = ["InvalidInputError"]
