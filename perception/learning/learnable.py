"""Learnable perception models: a :class:`PerceptionModel` that also fits, saves and loads.

A learnable model is built from what a dataset says about its task (:class:`ModelSpec`: label
kind, number of targets, condition choices, image size) plus its own frozen hyper-parameter
dataclass. It predicts a whole batch at once (:meth:`LearnableModel.predict_batch`); ``predict``
checks one image and one condition and calls it.

Adding a model: subclass :class:`LearnableModel`, implement ``fit``, ``save``, ``load`` and
``predict_batch`` (:mod:`perception.learning.train` is the training loop,
:mod:`perception.learning.checkpoint` the file format), then register the class in
:mod:`perception.registry` or name it as ``"package.module:Class"``.
"""

from __future__ import annotations

import abc
import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self, cast

import numpy as np

from perception.camera import Calibrations, PinholeCamera, RgbdFrame
from perception.interface import (
    NO_CONDITION,
    Condition,
    ConditionKind,
    InvalidInputError,
    LabelKind,
    ModelInput,
    PerceptionModel,
    Prediction,
    check_image,
    condition_size,
)
from perception.labels import LABEL_DIMS
from perception.learning.data import Dataset, DatasetMetadata

if TYPE_CHECKING:
    from perception.learning.train import TrainConfig, TrainReport


@dataclass(frozen=True)
class ModelSpec:
    """What a model is built for, as a dataset's metadata states it.

    Args:
        scene: The scene family (``"paper-sim"``, ``"yumi"``).
        task: The task name.
        label_kind: What the model predicts per target.
        targets: q, targets (attention heads) per image.
        condition_kind: What the condition is (a one-hot choice, a sentence, a picture).
        condition_choices: What the condition may name: the one-hot order of a one-hot kind,
            the targets a sentence or a picture names; () for none.
        image_height_px: H of the images the model reads.
        image_width_px: W of the images the model reads.
        camera: The geometry of the camera the images come from, where the dataset records it
            (None: it does not, or a checkpoint from before gva kept it); a model may read
            positions off it.
        object_types: The scene's object types in a fixed order, the vocabulary a model may
            state a target's type in (from ``metadata.extra["object_types"]``); (): unknown (a
            dataset or checkpoint from before gva recorded it).
        sensor: The sensor that rendered the training images, as the dataset's camera record
            names it (``{"sensor": "d435", ...}``); None: the ideal camera (every checkpoint
            from before sensors were recorded). Trials under another sensor are refused.
        focus_window_px: The heatmap focus derived for that camera, as its record states it
            (``KqvConfig.focus_window_px`` reads it; 0: none derived, the whole heatmap); None:
            the record does not state one (a dataset from before cameras recorded it, or a
            scene without one).
        focus_box_px: The focus's densest square [px], beside it; None likewise.

    """

    scene: str
    task: str
    label_kind: LabelKind
    targets: int
    condition_kind: ConditionKind
    condition_choices: tuple[str, ...]
    image_height_px: int
    image_width_px: int
    camera: PinholeCamera | None = None
    object_types: tuple[str, ...] = ()
    sensor: dict[str, Any] | None = None
    focus_window_px: int | None = None
    focus_box_px: int | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.label_kind, LabelKind):
            raise InvalidInputError("label_kind", self.label_kind, "a LabelKind")
        if not isinstance(self.condition_kind, ConditionKind):
            raise InvalidInputError("condition_kind", self.condition_kind, "a ConditionKind")
        for name in ("targets", "image_height_px", "image_width_px"):
            if not isinstance(getattr(self, name), int) or getattr(self, name) < 1:
                raise InvalidInputError(name, getattr(self, name), "an integer >= 1")
        object.__setattr__(self, "condition_choices", tuple(self.condition_choices))
        if self.camera is not None and not isinstance(self.camera, PinholeCamera):
            raise InvalidInputError("camera", self.camera, "a PinholeCamera or None")
        types = self.object_types
        if isinstance(types, str) or not isinstance(types, Sequence) or not all(
                isinstance(name, str) and name for name in types) or len(set(types)) != \
                len(types):
            raise InvalidInputError("object_types", types, "distinct non-empty strings")
        object.__setattr__(self, "object_types", tuple(types))
        for name in ("focus_window_px", "focus_box_px"):
            value = getattr(self, name)
            if value is not None and (not isinstance(value, int) or isinstance(value, bool) or
                                      value < 0):
                raise InvalidInputError(name, value, "None or an integer >= 0 [px]")

    @property
    def label_dim(self) -> int:
        """D, one target's label length (3 or 12)."""
        return LABEL_DIMS[self.label_kind]

    @property
    def condition_size(self) -> int:
        """C, the length of the condition vector a model reads (0 without one)."""
        return condition_size(self.condition_kind, self.condition_choices)

    @classmethod
    def from_metadata(cls, metadata: DatasetMetadata) -> ModelSpec:
        """The spec of a model trained on a dataset with ``metadata``."""
        values = {f.name: getattr(metadata, f.name) for f in fields(cls)
                  if f.name not in _RECORDED}
        record = metadata.camera
        sensor = record.get("sensor")
        return cls(**values, camera=PinholeCamera.from_record(record),
                   object_types=tuple(metadata.extra.get("object_types", ())),
                   sensor=None if sensor in (None, IDEAL_SENSOR) else sensor,
                   focus_window_px=record.get("focus_window_px"),
                   focus_box_px=record.get("focus_box_px"))

    def check_dataset(self, dataset: Dataset) -> None:
        """An error naming every field in which ``dataset`` differs from this spec.

        Scene and task names may differ. Object types and the focus are compared only where
        both sides state them: () and None mean unknown, not none (a dataset or checkpoint from
        before gva kept them).
        """
        other = ModelSpec.from_metadata(dataset.metadata)
        skipped = {"scene", "task"} | ({"object_types"} if not (
            self.object_types and other.object_types) else set()) | {
            name for name in _FOCUS if getattr(self, name) is None or
            getattr(other, name) is None}
        wrong = [f"{f.name} is {_shown(getattr(other, f.name))!r}, the model's is "
                 f"{_shown(getattr(self, f.name))!r}" for f in fields(self)
                 if f.name not in skipped and getattr(other, f.name) != getattr(self, f.name)]
        if wrong:
            raise InvalidInputError("dataset", "; ".join(wrong), "a dataset of the model's spec")

    def to_json(self) -> dict[str, Any]:
        """The spec as JSON-able data (enums by value)."""
        data = {f.name: getattr(self, f.name) for f in fields(self)}
        data |= {"camera": None if self.camera is None else self.camera.to_json(),
                 "label_kind": self.label_kind.value, "condition_kind": self.condition_kind.value,
                 "condition_choices": list(self.condition_choices), "label_dim": self.label_dim,
                 "object_types": list(self.object_types)}
        if self.sensor is None:  # the ideal camera: a checkpoint as before sensors were kept
            del data["sensor"]
        for name in _FOCUS:  # unstated: a checkpoint as before cameras recorded their focus
            if data[name] is None:
                del data[name]
        return data

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ModelSpec:
        """The spec :meth:`to_json` wrote."""
        values = {f.name: data[f.name] for f in fields(cls) if f.name not in _RECORDED}
        values["sensor"] = data.get("sensor")  # absent: the ideal camera
        values |= {name: data.get(name) for name in _FOCUS}  # absent: unstated
        camera = data.get("camera")  # absent from checkpoints older than the field
        values["camera"] = None if camera is None else PinholeCamera.from_json(camera)
        values["object_types"] = tuple(data.get("object_types", ()))  # absent: older, too
        values["label_kind"] = LabelKind(values["label_kind"])
        values["condition_kind"] = ConditionKind(values["condition_kind"])
        values["condition_choices"] = tuple(values["condition_choices"])
        return cls(**values)


_FOCUS = ("focus_window_px", "focus_box_px")
_RECORDED = ("camera", "object_types", "sensor", *_FOCUS)  # read from records, not fields
IDEAL_SENSOR = {"sensor": "ideal"}
"""A dataset camera record's ``sensor`` for the ideal camera; a spec keeps it as None."""


class LearnableModel(PerceptionModel):
    """A perception model with weights: ``fit`` on a dataset, ``save`` and ``load`` a checkpoint.

    Subclasses set ``name``, keep their :class:`ModelSpec` in ``self.spec`` and implement
    :meth:`predict_batch`, :meth:`fit`, :meth:`save` and :meth:`load`.
    """

    spec: ModelSpec

    @abc.abstractmethod
    def predict_batch(self, images: np.ndarray, conditions: np.ndarray,
                      depths_m: np.ndarray | None = None) -> list[Prediction]:
        """Predictions for uint8 images (B, H, W, 3) and condition vectors (B, C), in order.

        ``depths_m`` (B, H, W) [m]: each image's depth, for a model whose ``inputs`` name
        :attr:`ModelInput.DEPTH` (others ignore it). A model whose ``inputs`` name
        :attr:`ModelInput.CAMERA` also takes ``cameras`` (keyword): each image's calibration
        (:data:`~perception.camera.Calibrations`); only such a model is given it.
        """

    def predict_frame(self, frame: RgbdFrame, condition: Condition = NO_CONDITION
                      ) -> Prediction:
        """Predicts from a trial's frame: its colour image, its depth and calibration if read.

        Depth and calibration go to a model whose ``inputs`` name them: a camera moved and
        re-calibrated is read through its new pose.
        """
        if not self.inputs & {ModelInput.DEPTH, ModelInput.CAMERA}:
            return self.predict(frame.rgb, condition)
        return self._predict_one(frame.rgb, condition,
                                 frame.depth_m[None] if ModelInput.DEPTH in self.inputs else None,
                                 (frame.camera,) if ModelInput.CAMERA in self.inputs else None)

    @abc.abstractmethod
    def fit(self, dataset: Dataset, config: TrainConfig, progress: bool = True) -> TrainReport:
        """Trains on ``dataset`` (of this model's spec) and says how it went."""

    @abc.abstractmethod
    def save(self, path: str | Path) -> Path:
        """Writes a checkpoint folder (weights + JSON config) at ``path``; returns it."""

    @classmethod
    @abc.abstractmethod
    def load(cls, path: str | Path) -> Self:
        """The model a checkpoint folder at ``path`` holds, checked before use."""

    def predict(self, image: np.ndarray, condition: Condition = NO_CONDITION) -> Prediction:
        """Predicts the targets in one uint8 (H, W, 3) image under ``condition``."""
        return self._predict_one(image, condition, None)

    def _predict_one(self, image: np.ndarray, condition: Condition,
                     depths_m: np.ndarray | None, cameras: Calibrations = None) -> Prediction:
        """:meth:`predict`'s checks and batch of one.

        With the image's depth (1, H, W) or None, and its calibration (one) or None.
        """
        spec = self.spec
        check_image(image, (spec.image_height_px, spec.image_width_px, 3))
        wanted = spec.condition_choices if spec.condition_kind.one_hot else ()
        if condition.kind is not spec.condition_kind or condition.choices != wanted:
            over = f" over ({', '.join(wanted)})" if wanted else ""
            raise InvalidInputError("condition", f"{condition.kind.value} {condition.choices}",
                                    f"a {spec.condition_kind.value} condition{over}")
        rows = self.condition_rows([condition], condition.vector()[None])
        return self.predict_images(image[None], rows, depths_m, cameras)[0]

    def predict_images(self, images: np.ndarray, conditions: np.ndarray,
                       depths_m: np.ndarray | None = None, cameras: Calibrations = None
                       ) -> list[Prediction]:
        """:meth:`predict_batch`, given ``cameras`` only where there are any.

        A model that reads no calibration keeps its three-argument ``predict_batch``.
        """
        if cameras is None:
            return self.predict_batch(images, conditions, depths_m)
        predict = cast(Any, self.predict_batch)  # a CAMERA-reading model's takes ``cameras``
        return cast(list[Prediction], predict(images, conditions, depths_m, cameras=cameras))

    def predict_samples(self, dataset: Dataset, rows: Sequence[int],
                        conditions: np.ndarray | None = None) -> list[Prediction]:
        """Predictions for ``dataset``'s samples ``rows``, each read as a trial reads its frame.

        With its depth and its own calibration where this model reads them (the one reading of
        a sample that ``gva evaluate``, ``gva show`` and the figures share). ``conditions`` (one
        row per sample): what the model is given; None: each sample's own condition, as
        :meth:`condition_rows` reads it.
        """
        index = list(rows)
        if conditions is None:
            conditions = self.condition_rows([dataset.condition(i) for i in index],
                                             dataset.conditions[index])
        depths = dataset.depths_m[index] if dataset.depths_m is not None and \
            ModelInput.DEPTH in self.inputs else None
        cameras = dataset.cameras() if ModelInput.CAMERA in self.inputs else None
        return self.predict_images(dataset.images[index], conditions, depths,
                                   None if cameras is None else [cameras[i] for i in index])

    def condition_rows(self, conditions: Sequence[Condition], rows: np.ndarray) -> np.ndarray:
        """The condition vectors (B, C) :meth:`predict_batch` is given for ``conditions``.

        ``rows`` are their :meth:`Condition.vector` rows (a dataset's ``conditions``), returned
        as they are here; a model that reads a condition otherwise (kqv's sentence reading from
        the words, ``KqvConfig.sentence_reading``) gives the rows its network reads instead.
        """
        return rows

    def check_batch(self, images: np.ndarray, conditions: np.ndarray) -> None:
        """An error unless ``images`` (B, H, W, 3) uint8 and ``conditions`` (B, C) fit the spec."""
        spec = self.spec
        shape = (spec.image_height_px, spec.image_width_px, 3)
        if not isinstance(images, np.ndarray) or images.dtype != np.uint8 or \
                images.shape[1:] != shape or images.ndim != 4:
            found = f"{getattr(images, 'dtype', type(images).__name__)} {np.shape(images)}"
            raise InvalidInputError("images", found,
                                    f"uint8 of shape (B, {shape[0]}, {shape[1]}, 3)")
        if np.shape(conditions) != (len(images), spec.condition_size):
            raise InvalidInputError("conditions", f"shape {np.shape(conditions)}",
                                    f"shape ({len(images)}, {spec.condition_size})")


def _shown(value: object) -> object:
    """An enum by its value (``'grasp_pose'``, not ``<LabelKind.GRASP_POSE: ...>``) for messages."""
    return value.value if isinstance(value, enum.Enum) else value


def check_choices(name: str, value: object, allowed: Sequence[object]) -> None:
    """An error unless ``value`` is one of ``allowed`` (for config ``__post_init__`` checks)."""
    if value not in allowed:
        raise InvalidInputError(name, value, f"one of {', '.join(map(repr, allowed))}")


def check_integer(name: str, value: object, least: int, most: int, *,
                  optional: bool = False) -> None:
    """An error unless ``value`` is an integer in [``least``, ``most``] (or None, if optional).

    Every count of a model config has an upper bound as well (a width, a number of steps): a
    value past it is a typo or a unit mistake, which would otherwise end in an allocation error
    or a training that never ends.
    """
    if optional and value is None:
        return
    if isinstance(value, bool) or not isinstance(value, int) or not least <= value <= most:
        raise InvalidInputError(name, value, f"{'None or ' if optional else ''}an integer >= "
                                f"{least} and <= {most}")


def check_number(name: str, value: object, least: float, most: float, *,
                 open_below: bool = False) -> None:
    """An error unless ``value`` is a finite number in [``least``, ``most``].

    ``open_below``: in (``least``, ``most``]. A config's weights and temperatures, bounded as
    its counts are (:func:`check_integer`).
    """
    number = value if isinstance(value, int | float) and not isinstance(value, bool) else None
    if number is None or not math.isfinite(number) or not (
            number > least if open_below else number >= least) or number > most:
        raise InvalidInputError(name, value, f"a finite value {'>' if open_below else '>='} "
                                f"{least:g} and <= {most:g}")
