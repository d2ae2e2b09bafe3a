"""What a run checks of a model: what it reads, before it starts; what it returned, each time.

A trial must never crash, nor act on garbage, because of a model: :func:`check_inputs` refuses
a model whose declared ``inputs`` the run cannot give (one clear line, before anything runs),
and :func:`check_prediction` turns whatever ``predict`` returned into the targets a pick acts on,
or an :class:`~perception.errors.InvalidPredictionError` that says what was wrong (the trial
records it as ``perception_failed``).
"""

from __future__ import annotations

from collections.abc import Set

import numpy as np

from perception.errors import InvalidInputError, InvalidPredictionError
from perception.interface import LabelKind, ModelInput, PerceptionModel, Prediction, Target
from perception.labels import nearest_rotation

MAX_POSITION_M = 100.0
"""The farthest a predicted target may lie from the world's origin (the robot base) [m]: a
workcell spans a few metres, and a position like 1e300 m overflows every error computed from it
(a record that reads Infinity, which strict JSON refuses)."""
MAX_OBJECT_TYPE_CHARS = 100
"""The longest ``object_type`` a prediction may state: type names are a word or two, and what a
model says is written into every trial record."""


def check_inputs(model: PerceptionModel, available: Set[ModelInput], where: str) -> None:
    """Raises unless ``model``'s declared inputs are all in ``available``, and it reads them.

    Args:
        model: The model a run is about to use.
        available: What the run gives each prediction (a trial: RGB, depth and the camera).
        where: What the run calls the model, for the message (e.g. its ``--model``).

    Raises:
        InvalidInputError: Names the model, what it declared and what the run gives.

    """
    inputs = getattr(model, "inputs", None)
    allowed = ", ".join(f"ModelInput.{i.name}" for i in ModelInput)
    if not isinstance(inputs, frozenset | set) or not inputs or not all(
            isinstance(i, ModelInput) for i in inputs):
        raise InvalidInputError(f"model {where}: inputs", inputs,
                                f"a non-empty frozenset of {allowed}")
    if missing := sorted(i.value for i in inputs if i not in available):
        given = ", ".join(sorted(i.value for i in available))
        raise InvalidInputError(f"model {where}: inputs", sorted(i.value for i in inputs),
                                f"what this run gives ({given}); it has no {', '.join(missing)}")
    cls = type(model)
    reads_frame = cls.predict_frame is not PerceptionModel.predict_frame
    if not reads_frame and cls.predict is PerceptionModel.predict:
        raise InvalidInputError(f"model {where}", cls.__name__, "a class that implements "
                                "predict(image, condition) or predict_frame(frame, condition)")
    if not reads_frame and inputs != {ModelInput.RGB}:
        raise InvalidInputError(f"model {where}: inputs", sorted(i.value for i in inputs),
                                "{ModelInput.RGB} for a model that implements only predict("
                                "image, condition); read depth or the camera in predict_frame")


def check_prediction(prediction: object, name: str, *, least: int, most: int,
                     label_kind: LabelKind) -> tuple[Target, ...]:
    """The targets of ``prediction``, checked; raises if a robot cannot act on them.

    Args:
        prediction: What the model's predict returned.
        name: The model's name, for the messages.
        least: The fewest targets the pick allows (the targets still on the table).
        most: The most (every target of the task).
        label_kind: What each target must be: a grasp pose needs a proper rotation.

    Raises:
        InvalidPredictionError: Not a Prediction, targets that are not Targets, the wrong
            number of them, non-finite numbers, or a rotation that is missing or not one.

    """
    if not isinstance(prediction, Prediction):
        raise InvalidPredictionError(f"{name} returned {type(prediction).__name__}, not a "
                                     "perception.interface.Prediction")
    targets = prediction.targets
    if not isinstance(targets, tuple | list) or not all(isinstance(t, Target) for t in targets):
        shown = type(targets).__name__ if not isinstance(targets, tuple | list) else \
            ", ".join(type(t).__name__ for t in targets)
        raise InvalidPredictionError(f"{name} predicted targets of {shown}; each must be a "
                                     "perception.interface.Target")
    if not least <= len(targets) <= most:
        wanted = f"{least}" if least == most else f"{least} to {most}"
        raise InvalidPredictionError(f"{name} predicted {len(targets)} targets; this pick "
                                     f"needs {wanted}")
    for number, target in enumerate(targets, 1):
        where = f"{name}'s target {number} of {len(targets)}"
        position = np.asarray(target.position_m, dtype=float)
        if position.shape != (3,) or not np.all(np.isfinite(position)):
            raise InvalidPredictionError(f"{where}: position_m = {position.tolist()} is not "
                                         "three finite numbers")
        if float(np.abs(position).max()) > MAX_POSITION_M:  # no square of 1e300 taken
            raise InvalidPredictionError(f"{where}: position_m = {position.tolist()} is more "
                                         f"than {MAX_POSITION_M:g} m from the robot base")
        kind = target.object_type
        if kind is not None and (not isinstance(kind, str) or len(kind) > MAX_OBJECT_TYPE_CHARS):
            shown = f"{len(kind)} characters" if isinstance(kind, str) else type(kind).__name__
            raise InvalidPredictionError(f"{where}: object_type of {shown} is not a type name "
                                         f"(a string of at most {MAX_OBJECT_TYPE_CHARS}) or None")
        if label_kind is LabelKind.GRASP_POSE:
            if target.rotation is None:
                raise InvalidPredictionError(f"{where}: no rotation; a pick needs a grasp pose "
                                             "(TCP position and rotation)")
            try:
                nearest_rotation("rotation", target.rotation)
            except InvalidInputError as error:
                raise InvalidPredictionError(f"{where}: {error}") from None
    return tuple(targets)
