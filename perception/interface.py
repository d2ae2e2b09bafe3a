"""The one interface every perception model implements, and the types it speaks.

A plug-in model needs nothing but ``perception``. Before each pick the trial hands the model
an :class:`~perception.camera.RgbdFrame` (the head camera's RGB image, its depth image in metres
and its calibration: :class:`~perception.camera.PinholeCamera`, with ``K``, ``T_world_camera``
and rays through pixels) and a :class:`Condition` (what the top-down Query asks for), and gets
back a :class:`Prediction`: one :class:`Target` per predicted object (a position, or a grasp
pose for the gripper's tool centre point) plus the attention points the model looked at, in
pixels. :mod:`perception.objects.catalog` and :mod:`perception.objects.grasps` say which grasp
each object takes.

A model implements :meth:`PerceptionModel.predict` (colour image only) or
:meth:`PerceptionModel.predict_frame` (the whole frame) and declares what it reads in
``inputs``; a trial checks that before its first pick. Example (a model that always points at
the table centre)::

    class Centre(PerceptionModel):
        name = "centre"
        label_kind = LabelKind.POSITION

        def predict(self, image, condition):
            return Prediction(targets=(Target(position_m=np.array([0.4, 0.0, 0.0])),))
"""

from __future__ import annotations

import abc
import enum
import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np

from perception.camera import PinholeCamera, RgbdFrame
from perception.errors import InvalidInputError, InvalidPredictionError, PerceptionError
from perception.language.sentences import EMBEDDING_SIZE, embed

__all__ = ["NO_CONDITION", "PICTURE_PX", "Condition", "ConditionKind", "InvalidInputError",
           "InvalidPredictionError", "LabelKind", "ModelInput", "PerceptionError",
           "PerceptionModel", "PinholeCamera", "Prediction", "RgbdFrame", "Target",
           "check_image", "condition_size"]


class LabelKind(enum.Enum):
    """What a model predicts per target."""

    POSITION = "position"  # an object's position (x, y, z) in the world frame [m]
    GRASP_POSE = "grasp_pose"  # the gripper TCP pose that picks the object: position + rotation


class ConditionKind(enum.Enum):
    """What a top-down condition is: a one-hot choice (paper Table I), a sentence or a picture."""

    NONE = "none"  # baseline tasks: no condition, Base Queries only
    OBJECT_TYPE = "object_type"  # selected type: which object to attend to, one-hot
    SIDE = "side"  # selected position: the object on the left or on the right, one-hot
    TEXT = "text"  # a sentence that names the target ("grab the thing you spray with")
    IMAGE = "image"  # a small picture of the wanted object, taken in another scene

    @property
    def one_hot(self) -> bool:
        """Whether the condition is a choice among named values (its vector is one-hot)."""
        return self in (ConditionKind.OBJECT_TYPE, ConditionKind.SIDE)


PICTURE_PX = 32
"""An image condition is a (32, 32, 3) uint8 picture: big enough to tell the objects apart by
colour and shape, small enough to keep as a dataset row (3,072 numbers)."""
MAX_SENTENCE_CHARS = 500
"""A text condition is a sentence or two; the encoder reads at most 256 word pieces."""


def condition_size(kind: ConditionKind, choices: Sequence[str]) -> int:
    """C, the length of the vector a model reads for a condition of ``kind`` over ``choices``."""
    if kind.one_hot:
        return len(choices)
    if kind is ConditionKind.TEXT:
        return EMBEDDING_SIZE
    if kind is ConditionKind.IMAGE:
        return PICTURE_PX * PICTURE_PX * 3
    return 0


@dataclass(frozen=True)
class Condition:
    """A top-down condition: what the Query is asked for, and the vector a learned Query reads.

    Args:
        kind: What the condition is.
        value: The named choice (``"mug"``, ``"left"``) for a one-hot kind; the sentence for
            :attr:`ConditionKind.TEXT`; for :attr:`ConditionKind.IMAGE`, set to
            ``"picture <sha256[:12]>"`` of the picture (so equal pictures compare equal);
            None for :attr:`ConditionKind.NONE`.
        choices: Every value a one-hot kind allows, in one-hot order; () for the other kinds (a
            sentence or a picture is open: it is not a choice among names).
        picture: The (:data:`PICTURE_PX`, :data:`PICTURE_PX`, 3) uint8 RGB picture of an image
            condition; None otherwise.

    """

    kind: ConditionKind = ConditionKind.NONE
    value: str | None = None
    choices: tuple[str, ...] = ()
    picture: np.ndarray | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.kind, ConditionKind):
            allowed = ", ".join(repr(kind.value) for kind in ConditionKind)
            raise InvalidInputError("condition.kind", self.kind, f"a ConditionKind: {allowed}")
        if not self.kind.one_hot and self.choices:
            raise InvalidInputError("condition.choices", self.choices,
                                    f"() when kind is {self.kind.value!r}")
        if self.kind is not ConditionKind.IMAGE and self.picture is not None:
            raise InvalidInputError("condition.picture", "a picture",
                                    "None unless kind is 'image'")
        if self.kind is ConditionKind.NONE:
            if self.value is not None:
                raise InvalidInputError("condition.value", self.value, "None when kind is 'none'")
        elif self.kind is ConditionKind.TEXT:
            if not isinstance(self.value, str) or not self.value.strip() or \
                    len(self.value) > MAX_SENTENCE_CHARS:
                raise InvalidInputError("condition.value", self.value,
                                        f"a sentence of 1-{MAX_SENTENCE_CHARS} characters")
        elif self.kind is ConditionKind.IMAGE:
            picture = self.picture
            shape = (PICTURE_PX, PICTURE_PX, 3)
            if not isinstance(picture, np.ndarray) or picture.dtype != np.uint8 or \
                    picture.shape != shape:
                found = f"{getattr(picture, 'dtype', type(picture).__name__)} " \
                    f"{getattr(picture, 'shape', '')}"
                raise InvalidInputError("condition.picture", found, f"uint8 of shape {shape}")
            picture = picture.copy()
            picture.flags.writeable = False
            object.__setattr__(self, "picture", picture)
            object.__setattr__(self, "value",
                               f"picture {hashlib.sha256(picture.tobytes()).hexdigest()[:12]}")
        elif self.value not in self.choices:
            raise InvalidInputError(
                "condition.value", self.value, f"one of {', '.join(self.choices) or '(no choices)'}"
            )

    def vector(self) -> np.ndarray:
        """The float32 vector a learned Query reads (:func:`condition_size` long).

        One-hot kinds: a one-hot vector in ``choices`` order; text: the sentence's embedding
        (:mod:`perception.language.sentences`, loaded at the first sentence); image: the picture's
        pixels in [0, 1], row by row; none: an empty vector.
        """
        if self.kind is ConditionKind.TEXT:
            assert self.value is not None  # checked when built
            return embed(self.value).copy()  # the cached one is shared and read-only
        if self.kind is ConditionKind.IMAGE:
            assert self.picture is not None
            return (self.picture.reshape(-1) / np.float32(255.0)).astype(np.float32)
        vector = np.zeros(len(self.choices), dtype=np.float32)
        if self.value is not None:
            vector[self.choices.index(self.value)] = 1.0
        return vector


NO_CONDITION = Condition()


@dataclass(frozen=True)
class Target:
    """One predicted target in the world frame.

    Args:
        position_m: (3,) position [m]: the object's, or the TCP's for a grasp.
        rotation: (3, 3) TCP orientation for a grasp (columns: the TCP x, y, z axes in the world;
            z is the approach direction); None for position-only predictions.
        object_type: The object type the model believes it attends to, where it knows. A pick
            takes the catalog grasp's opening, pre-grasp distance and symmetric alternatives
            from it; None: the trial's default grip (the gripper fully open).
        opening_m: The finger gap to approach with [m], where the model says; it overrides
            the type's.

    """

    position_m: np.ndarray
    rotation: np.ndarray | None = None
    object_type: str | None = None
    opening_m: float | None = None

    def __post_init__(self) -> None:
        if np.shape(self.position_m) != (3,):
            raise InvalidInputError("position_m", np.shape(self.position_m), "shape (3,)")
        if not np.all(np.isfinite(np.asarray(self.position_m, dtype=float))):
            raise InvalidInputError("position_m", np.asarray(self.position_m).tolist(),
                                    "finite numbers")
        if self.rotation is not None and np.shape(self.rotation) != (3, 3):
            raise InvalidInputError("rotation", np.shape(self.rotation), "shape (3, 3) or None")
        if self.rotation is not None and not np.all(np.isfinite(np.asarray(self.rotation,
                                                                           dtype=float))):
            raise InvalidInputError("rotation", np.asarray(self.rotation).tolist(),
                                    "finite numbers")
        if self.opening_m is not None and not self.opening_m > 0.0:
            raise InvalidInputError("opening_m", self.opening_m, "a gap > 0 m, or None")


@dataclass(frozen=True)
class Prediction:
    """What a model saw and predicted for one image.

    A model has p attention heads, each giving a point and, where it has them, a heatmap. p
    need not be the number of targets: a key-point model's 16 points look at whatever helps
    its MLP (:attr:`PerceptionModel.attention_per_target` says whether head k looks for
    target k, as kqv's Queries do).

    Args:
        targets: One entry per target, in the task's target order.
        attention_px: (p, 2) attention points (u right, v down) in image pixels; (0, 2) for a
            model without attention.
        heatmaps: (p', h, w) attention heatmaps, each summing to 1, where the model has them.

    """

    targets: tuple[Target, ...]
    attention_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    heatmaps: np.ndarray | None = None

    def __post_init__(self) -> None:
        if np.ndim(self.attention_px) != 2 or np.shape(self.attention_px)[1] != 2:
            raise InvalidInputError("attention_px", np.shape(self.attention_px),
                                    "shape (p, 2): a (u, v) point per attention head")
        if self.heatmaps is not None and np.ndim(self.heatmaps) != 3:
            raise InvalidInputError("heatmaps", np.shape(self.heatmaps),
                                    "shape (p, h, w): a map per attention head, or None")

    def without_types(self) -> Prediction:
        """The same prediction with no target's ``object_type`` stated.

        Every pick then takes the default grip: what a stated type is worth is measured
        against this.
        """
        return replace(self, targets=tuple(replace(t, object_type=None) for t in self.targets))


class ModelInput(enum.Enum):
    """What a model may read of a camera frame (declared in ``PerceptionModel.inputs``)."""

    RGB = "rgb"  # the colour image
    DEPTH = "depth"  # the depth image [m]
    CAMERA = "camera"  # the calibration: intrinsics and pose in the world


class PerceptionModel(abc.ABC):
    """A model that turns a camera frame and a condition into target predictions.

    Subclasses set ``name`` and ``label_kind``, and implement :meth:`predict` (the colour image
    is all they read) or :meth:`predict_frame` (they read depth or calibration too, and say so
    in ``inputs``).
    """

    name: ClassVar[str]
    label_kind: LabelKind  # per instance where one class serves both kinds (kqv)
    inputs: frozenset[ModelInput] = frozenset({ModelInput.RGB})
    """What the model reads; a run checks it can give them before the first prediction. A class
    attribute, or an instance's where its settings decide (a kqv model with ``depth_input``)."""
    attention_per_target: ClassVar[bool] = True
    """Whether attention head k looks for target k (kqv's Queries; a detector's points), where
    a prediction has as many heads as targets. False for heads tied to no target (a key-point
    model's points): evaluation then reads its heatmaps as a whole, never as one target's."""

    def predict(self, image: np.ndarray, condition: Condition = NO_CONDITION) -> Prediction:
        """Predicts the targets in ``image`` (uint8 (H, W, 3) RGB, row 0 at the top)."""
        raise NotImplementedError(f"{type(self).__name__} implements neither predict(image, "
                                  "condition) nor predict_frame(frame, condition)")

    def predict_frame(self, frame: RgbdFrame, condition: Condition = NO_CONDITION
                      ) -> Prediction:
        """Predicts the targets seen in ``frame`` (RGB, depth and calibration).

        What a trial calls. The default reads the colour image alone: :meth:`predict`.
        """
        return self.predict(frame.rgb, condition)


def check_image(image: np.ndarray, shape: Sequence[int] | None = None) -> None:
    """Raises a clear error unless ``image`` is uint8 (H, W, 3), of ``shape`` when given."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim != 3:
        description = f"{type(image).__name__} {getattr(image, 'dtype', '')} {np.shape(image)}"
        raise InvalidInputError("image", description.strip(), "a uint8 array of shape (H, W, 3)")
    if image.shape[2] != 3 or (shape is not None and tuple(image.shape) != tuple(shape)):
        expected = f"shape {tuple(shape)}" if shape is not None else "3 channels (RGB)"
        raise InvalidInputError("image", f"shape {image.shape}", expected)
