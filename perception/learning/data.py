"""A dataset in memory: samples of one task in one scene, and the metadata a reader checks.

:class:`Dataset` holds images, conditions, labels and the scene record of each sample, checked
against its :class:`DatasetMetadata` when built. Its file, written and read strictly, is
:mod:`perception.learning.dataset_file`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from numbers import Integral
from typing import Any, cast

import numpy as np

from perception.camera import PinholeCamera
from perception.interface import (
    PICTURE_PX,
    Condition,
    ConditionKind,
    InvalidInputError,
    LabelKind,
    condition_size,
)
from perception.labels import LABEL_DIMS, check_rotations, split_label
from perception.learning.json_form import json_form

FORMAT_VERSION = 1
TENSORS = ("images", "conditions", "labels")  # a dataset's arrays, in its file's order
OPTIONAL_TENSORS = ("depths_m", "joint_positions")  # kept where the collector had them
JOINT_NAMES_KEY = "joint_names"
"""``metadata.extra`` key: the robot's joints in ``joint_positions`` column order."""
SAMPLE_CAMERA_KEY = "camera"
"""A scene record's key for the calibration its image was taken with, where it is not the
dataset's ``metadata.camera`` (a look moved the camera for that scene): what a model that reads
positions through the camera reads that sample through, as a trial reads its frame's."""


@dataclass(frozen=True)
class DatasetMetadata:
    """What a dataset holds and how it was made; a reader checks it before use.

    Args:
        scene: The scene family the images show (``"paper-sim"``, ``"yumi"``, ...).
        task: The task name (``"selected-type"``, ...).
        size: N, the number of samples.
        seed: The seed the scenes were drawn from (train and test seeds differ).
        image_height_px: H, image rows.
        image_width_px: W, image columns.
        label_kind: What each label holds; it fixes :attr:`label_dim`.
        targets: q, targets per sample.
        condition_kind: What the condition is (a one-hot choice, a sentence, a picture).
        condition_choices: What the conditions may name: the one-hot order for a one-hot kind;
            for a sentence or a picture, the targets they name (object types or sides, which
            the scene records hold per sample); () exactly when ``condition_kind`` is none.
        camera: JSON-able camera description (placement, field of view, ...).
        extra: Anything else JSON-able worth keeping (e.g. how many demonstrations were redrawn).
        format_version: The file format; this gva reads and writes :data:`FORMAT_VERSION` only.

    ``camera`` and ``extra`` are kept in their JSON form (tuples become lists), so what is loaded
    equals what was saved.

    """

    scene: str
    task: str
    size: int
    seed: int
    image_height_px: int
    image_width_px: int
    label_kind: LabelKind
    targets: int
    condition_kind: ConditionKind
    condition_choices: tuple[str, ...]
    camera: dict[str, Any]
    extra: dict[str, Any] = field(default_factory=dict)
    format_version: int = FORMAT_VERSION

    def __post_init__(self) -> None:
        for name in ("scene", "task"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name):
                raise InvalidInputError(name, getattr(self, name), "a non-empty string")
        for name, least in (("size", 0), ("seed", 0), ("image_height_px", 1),
                            ("image_width_px", 1), ("targets", 1), ("format_version", 0)):
            value = getattr(self, name)
            if not isinstance(value, Integral) or isinstance(value, bool) or value < least:
                raise InvalidInputError(name, value, f"an integer >= {least}")
            object.__setattr__(self, name, int(value))
        if self.format_version != FORMAT_VERSION:
            raise InvalidInputError("format_version", self.format_version,
                                    f"{FORMAT_VERSION}, the only version this gva writes")
        for name, kind in (("label_kind", LabelKind), ("condition_kind", ConditionKind)):
            if not isinstance(getattr(self, name), kind):
                allowed = ", ".join(f"{kind.__name__}.{member.name}" for member in kind)
                raise InvalidInputError(name, getattr(self, name), f"one of {allowed}")
        choices = self.condition_choices
        if isinstance(choices, str) or not isinstance(choices, Sequence) or not all(
                isinstance(choice, str) and choice for choice in choices):
            raise InvalidInputError("condition_choices", choices, "a tuple of non-empty strings")
        if len(set(choices)) != len(choices):
            raise InvalidInputError("condition_choices", choices, "distinct names")
        if (self.condition_kind is ConditionKind.NONE) != (len(choices) == 0):
            raise InvalidInputError("condition_choices", choices, "() exactly when condition_kind"
                                    f" is none (condition_kind is {self.condition_kind.value})")
        object.__setattr__(self, "condition_choices", tuple(choices))
        object.__setattr__(self, "camera", json_form("camera", self.camera))
        object.__setattr__(self, "extra", json_form("extra", self.extra))

    @property
    def label_dim(self) -> int:
        """D, the length of one target's label: 3 for a position, 12 for a grasp pose."""
        return LABEL_DIMS[self.label_kind]


@dataclass(frozen=True, eq=False)
class Dataset:
    """Samples of one task in one scene, as a dataset file keeps them.

    Args:
        metadata: What the samples are; every shape below follows from it.
        images: (N, H, W, 3) uint8 RGB, row 0 at the top.
        conditions: (N, C) float32 rows: what a model reads of each sample's condition
            (:meth:`perception.interface.Condition.vector`): one-hot in
            ``metadata.condition_choices`` order, a sentence's embedding, or a picture's pixels.
        labels: (N, q, D) float32 in the :func:`label_vector` layout.
        scenes: One JSON-able record per sample (object types and poses, targets, condition),
            kept in JSON form like ``metadata.camera``.
        depths_m: (N, H, W) float32 depth along the optical axis [m] of each image, as the
            RGB-D camera gave it (inf where none); None where the collector had no depth (the
            paper-sim scene, datasets made before depth was kept). Models read the colour; the
            depth is there for exports (LeRobot) and for models that want it.
        joint_positions: (N, J) float32 robot joint positions [rad, m] when each image was
            taken, columns in ``metadata.extra["joint_names"]`` order; None where unknown.

    """

    metadata: DatasetMetadata
    images: np.ndarray  # (N, H, W, 3) uint8
    conditions: np.ndarray  # (N, C) float32
    labels: np.ndarray  # (N, q, D) float32
    scenes: tuple[dict[str, Any], ...]
    depths_m: np.ndarray | None = None  # (N, H, W) float32
    joint_positions: np.ndarray | None = None  # (N, J) float32

    def __post_init__(self) -> None:
        if not isinstance(self.metadata, DatasetMetadata):
            raise InvalidInputError("metadata", type(self.metadata).__name__, "a DatasetMetadata")
        present = tuple(n for n in OPTIONAL_TENSORS if getattr(self, n) is not None)
        for name, (dtype, shape, layout) in expected_arrays(self.metadata, present).items():
            array = getattr(self, name)
            found = f"{getattr(array, 'dtype', type(array).__name__)} {np.shape(array)}"
            if not isinstance(array, np.ndarray) or array.dtype != dtype or array.shape != shape:
                raise InvalidInputError(name, found, f"{dtype} {layout} = {shape} from metadata")
        _check_conditions(self.metadata.condition_kind, self.conditions)
        if not np.all(np.isfinite(self.labels)):
            raise InvalidInputError("labels", "non-finite values", "finite values")
        rotation = split_label(self.labels).rotation
        if rotation is not None:
            check_rotations("labels", rotation)
        if isinstance(self.scenes, str | Mapping) or not isinstance(self.scenes, Sequence):
            raise InvalidInputError("scenes", type(self.scenes).__name__, "a tuple of dicts")
        if len(self.scenes) != self.metadata.size:
            raise InvalidInputError("scenes", f"{len(self.scenes)} records",
                                    f"one per sample ({self.metadata.size})")
        records = tuple(json_form(f"scenes[{i}]", s) for i, s in enumerate(self.scenes))
        for i, record in enumerate(records):
            if SAMPLE_CAMERA_KEY in record:
                try:
                    PinholeCamera.from_json(record[SAMPLE_CAMERA_KEY])
                except InvalidInputError as error:
                    raise InvalidInputError(f"scenes[{i}].{SAMPLE_CAMERA_KEY}.{error.field}",
                                            error.value, error.allowed) from None
        object.__setattr__(self, "scenes", records)

    def __len__(self) -> int:
        return self.metadata.size

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Dataset):
            return NotImplemented
        def same(name: str) -> bool:
            a, b = getattr(self, name), getattr(other, name)
            return (a is None) == (b is None) and (a is None or np.array_equal(a, b))

        return (self.metadata == other.metadata and self.scenes == other.scenes
                and all(same(n) for n in TENSORS + OPTIONAL_TENSORS))

    def tensors(self) -> dict[str, np.ndarray]:
        """Every array the dataset holds, by name: :data:`TENSORS`, then the optional present."""
        return {n: a for n in TENSORS + OPTIONAL_TENSORS if (a := getattr(self, n)) is not None}

    def subset(self, indices: Sequence[int] | np.ndarray) -> Dataset:
        """The samples at ``indices``, in that order (e.g. the first 4 of 100); size follows."""
        index = np.asarray(indices)
        if index.ndim != 1 or (index.size and not np.issubdtype(index.dtype, np.integer)):
            raise InvalidInputError("indices", index.tolist(), "a 1-D sequence of integers")
        index = index.astype(np.intp)
        wrong = index[(index < 0) | (index >= len(self))]
        if wrong.size:
            raise InvalidInputError("indices", wrong.tolist(), f"integers in [0, {len(self)})")
        if np.unique(index).size != index.size:
            raise InvalidInputError("indices", index.tolist(), "distinct sample indices")
        return Dataset(replace(self.metadata, size=int(index.size)),
                       scenes=tuple(self.scenes[i] for i in index),
                       **{name: array[index] for name, array in self.tensors().items()})

    def scene_keys(self) -> list[int]:
        """Each sample's scene: its record's ``"index"`` (a record without one is its own)."""
        return [int(record.get("index", -1 - n)) for n, record in enumerate(self.scenes)]

    def first_scenes(self, count: int) -> Dataset:
        """The samples of the dataset's first ``count`` scenes, with ``extra["scenes"]`` set.

        A scene may give several samples (an image before each pick of a demonstration; one
        per condition value, :mod:`harness.inputs.collector`): they share :meth:`scene_keys`.
        """
        if not isinstance(count, int) or count < 0:
            raise InvalidInputError("count", count, "an integer >= 0")
        keys = self.scene_keys()
        kept = list(dict.fromkeys(keys))[:count]
        if len(kept) < count:
            raise InvalidInputError("count", count, f"at most the dataset's {len(kept)} scenes")
        wanted = set(kept)
        part = self.subset([n for n, key in enumerate(keys) if key in wanted])
        meta = replace(part.metadata, extra=part.metadata.extra | {"scenes": count})
        return replace(part, metadata=meta)

    def condition_names(self) -> tuple[str | None, ...]:
        """(N,) what each sample's condition names, one of ``condition_choices``; None: none.

        A one-hot row names its choice; a sentence or a picture names the value its scene
        record keeps under ``"condition"`` (what the collector drew it for).
        """
        meta = self.metadata
        if meta.condition_kind is ConditionKind.NONE:
            return (None,) * len(self)
        if meta.condition_kind.one_hot:
            return tuple(meta.condition_choices[int(i)] for i in self.conditions.argmax(axis=1))
        names = tuple(record.get("condition", {}).get("value") for record in self.scenes)
        wrong = [n for n, name in enumerate(names) if name not in meta.condition_choices]
        if wrong:
            raise InvalidInputError(f"scenes[{wrong[0]}].condition.value", names[wrong[0]],
                                    f"one of {', '.join(meta.condition_choices)}")
        return names

    def condition(self, index: int) -> Condition:
        """Sample ``index``'s condition as a model is given it (its vector is the row)."""
        meta = self.metadata
        kind = meta.condition_kind
        if kind is ConditionKind.NONE:
            return Condition()
        if kind.one_hot:
            value = meta.condition_choices[int(np.argmax(self.conditions[index]))]
            return Condition(kind, value, meta.condition_choices)
        if kind is ConditionKind.IMAGE:
            picture = np.rint(self.conditions[index] * 255.0).astype(np.uint8)
            return Condition(kind, picture=picture.reshape(PICTURE_PX, PICTURE_PX, 3))
        query = self.scenes[index].get("query", {})
        return Condition(kind, query.get("value"))

    def camera(self, index: int) -> PinholeCamera | None:
        """The calibration sample ``index`` was taken with (None: the dataset records none).

        Its own where its record keeps one (:data:`SAMPLE_CAMERA_KEY`: a look moved the camera
        for that scene), else the dataset's ``metadata.camera``.
        """
        own = self.scenes[index].get(SAMPLE_CAMERA_KEY)
        return PinholeCamera.from_record(self.metadata.camera) if own is None \
            else PinholeCamera.from_json(own)

    def cameras(self) -> list[PinholeCamera] | None:
        """:meth:`camera` of every sample, in order, the dataset's camera read once.

        None where the dataset records no camera geometry (a synthetic dataset).
        """
        recorded = PinholeCamera.from_record(self.metadata.camera)
        cameras = [recorded if (own := r.get(SAMPLE_CAMERA_KEY)) is None
                   else PinholeCamera.from_json(own) for r in self.scenes]
        return None if None in cameras else cast(list[PinholeCamera], cameras)

    def condition_prototypes(self) -> np.ndarray:
        """(k, C) float32: per ``condition_choices`` entry, the mean of its distinct conditions.

        Each distinct sentence (or picture) counts once, however many samples ask it, so a
        model that reads a new condition by its likeness to these (kqv's sentence prototypes)
        weighs every training wording alike. A choice no sample names gets zeros.
        """
        names = np.array(self.condition_names(), dtype=object)
        prototypes = np.zeros((len(self.metadata.condition_choices), self.conditions.shape[1]),
                              dtype=np.float32)
        for k, choice in enumerate(self.metadata.condition_choices):
            rows = self.conditions[names == choice]
            if len(rows):
                prototypes[k] = np.unique(rows, axis=0).mean(axis=0)
        return prototypes

    def target_types(self) -> tuple[tuple[str | None, ...], ...]:
        """(N, q) each target's object type as its scene record names it; None where it does not.

        A record names target ``k``'s type as ``record["objects"][record["targets"][k]]["type"]``
        (what the simulator's collector writes).
        """
        return tuple(tuple(_target_type(record, k) for k in range(self.metadata.targets))
                     for record in self.scenes)

    def target_present(self) -> np.ndarray:
        """(N, q) bool: whether each target is in its sample's image.

        A demonstration with several picks keeps the image taken before each pick; its record
        lists under ``"taken"`` the targets already picked and set aside by then. Their labels
        are kept (finite, where they were) but say nothing of that image: losses and scores skip
        them. A record without ``"taken"`` has every target present.
        """
        present = np.ones((len(self), self.metadata.targets), dtype=bool)  # (N, q)
        for n, record in enumerate(self.scenes):
            for k in record.get("taken", ()):
                if isinstance(k, int) and 0 <= k < self.metadata.targets:
                    present[n, k] = False
        return present

    def target_type_indices(self) -> np.ndarray:
        """(N, q) int64: each target's type as its index in ``metadata.extra["object_types"]``.

        -1 where the record names no type, the vocabulary lacks it, the dataset has no
        vocabulary (one collected before gva recorded it), or the target is not in the image
        (:meth:`target_present`): the labels of a model that states the type it attends to.
        """
        vocabulary = self.metadata.extra.get("object_types") or []
        index = {name: i for i, name in enumerate(vocabulary) if isinstance(name, str)}
        indices = np.array([[index.get(name, -1) if name is not None else -1 for name in row]
                            for row in self.target_types()],
                           dtype=np.int64).reshape(len(self), self.metadata.targets)  # (N, q)
        return np.where(self.target_present(), indices, -1)


def _check_conditions(kind: ConditionKind, conditions: np.ndarray) -> None:
    """An error naming the first row that is not a condition vector of ``kind``."""
    if kind.one_hot:
        good = (conditions.sum(axis=1) == 1) & np.isin(conditions, (0, 1)).all(axis=1)
        allowed = "a one-hot row: one 1.0, the rest 0.0"
    elif kind is ConditionKind.TEXT:
        good = np.abs(np.linalg.norm(conditions, axis=1) - 1.0) < 1e-3
        allowed = "a sentence embedding of unit length"
    elif kind is ConditionKind.IMAGE:
        good = ((conditions >= 0) & (conditions <= 1)).all(axis=1)
        allowed = "a picture's pixels in [0, 1]"
    else:
        return
    if not good.all():
        row = int(np.flatnonzero(~good)[0])
        shown = conditions[row].tolist()
        raise InvalidInputError(f"conditions[{row}]", shown if len(shown) <= 6 else
                                f"{shown[:6]}...", allowed)


def _target_type(record: Mapping[str, Any], k: int) -> str | None:
    """The type of target ``k`` in a scene record; None if the record does not say."""
    try:
        name = record["objects"][record["targets"][k]]["type"]
    except (KeyError, IndexError, TypeError):
        return None
    return name if isinstance(name, str) else None


def expected_arrays(metadata: DatasetMetadata, optional: Sequence[str] = ()
                    ) -> dict[str, tuple[np.dtype, tuple, str]]:
    """Per tensor: the dtype, the shape and its symbolic layout the metadata implies.

    The :data:`TENSORS`, then those of ``optional`` (names in :data:`OPTIONAL_TENSORS`).
    """
    n, h, w, q = metadata.size, metadata.image_height_px, metadata.image_width_px, metadata.targets
    arrays: dict[str, tuple[np.dtype, tuple, str]] = {
        "images": (np.dtype(np.uint8), (n, h, w, 3), "(N, H, W, 3)"),
        "conditions": (np.dtype(np.float32), (n, condition_size(
            metadata.condition_kind, metadata.condition_choices)), "(N, C)"),
        "labels": (np.dtype(np.float32), (n, q, metadata.label_dim), "(N, q, D)"),
    }
    if "depths_m" in optional:
        arrays["depths_m"] = (np.dtype(np.float32), (n, h, w), "(N, H, W)")
    if "joint_positions" in optional:
        joints = len(metadata.extra.get(JOINT_NAMES_KEY, ()))
        arrays["joint_positions"] = (np.dtype(np.float32), (n, joints),
                                     f"(N, J) with J = len(extra[{JOINT_NAMES_KEY!r}])")
    return arrays

