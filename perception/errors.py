"""Exceptions of the perception package, all under :class:`PerceptionError`."""

from __future__ import annotations

from robots import errors as robots_errors


class PerceptionError(Exception):
    """Base of every error raised by ``perception``."""


class NoAnswerError(PerceptionError):
    """The model gave no answer at all (a server silent past its limit, or gone).

    A pick cannot wait on it: in a closed loop too it costs the pick, where an answer the
    robot cannot act on only leaves the plan followed standing.
    """


class InvalidInputError(PerceptionError, robots_errors.InvalidInputError):
    """A value a model cannot use; the message names the field, the value and what is allowed."""


class InvalidPredictionError(PerceptionError):
    """A model's prediction a robot cannot act on; the message says what was wrong with it."""


__all__ = ["InvalidInputError", "InvalidPredictionError", "NoAnswerError", "PerceptionError"]
