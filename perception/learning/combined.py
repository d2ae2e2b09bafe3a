"""Several datasets trained on as one: demonstrations beside scenes labelled by the catalog.

The paper's budget is 20 demonstrations a task; scenes labelled by the catalog in randomised
looks (``gva collect --labels catalog --looks randomised``) cost no pick and are meant to be
trained on beside them (``gva train --data demonstrations.gva --data shape.gva``). A model is
built from one dataset's spec, so :func:`concatenate` first refuses files that disagree on what
a model reads and predicts (:func:`agreed_values`), then joins their samples into one
:class:`~perception.learning.data.Dataset`, each file's scenes kept apart: the held-out check
splits by scene (:func:`perception.learning.validation.split_scenes`) and must never take
half of one file's scene 3 and half of another's.

Each joined scene record keeps where it came from under :data:`PART_KEY` (the file's position,
its scene index there, what labelled it and in which looks), so the held-out check can hold
out demonstrations only (:func:`is_demonstration`): its score is meant to say how the model
does on the kind of scene the trials show, which a catalog-labelled scene in randomised looks
is not.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping, Sequence
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from perception.files import file_sha256
from perception.interface import InvalidInputError
from perception.learning.data import (
    JOINT_NAMES_KEY,
    OPTIONAL_TENSORS,
    TENSORS,
    Dataset,
    DatasetMetadata,
)
from perception.learning.learnable import ModelSpec

PART_KEY = "part"
"""A joined scene record's key: ``{"file", "index", "labels", "looks"}``, the file's position
in the list, the record's own ``"index"`` there (its ``"index"`` is moved past the earlier
files' scenes), what labelled it and in which looks."""
PARTS_KEY = "parts"
"""``metadata.extra`` key of a joined dataset: one entry per file, in order (its name, task,
seed, samples, scenes, labels and looks)."""
PICKED_LABELS, CATALOG_LABELS = "picked", "catalog"
"""``extra["labels"]`` values: ``harness.inputs.collector.LabelSource``'s (a demonstration records
none: picked)."""
TASK_LOOKS = "task"
"""The looks of a dataset that records no ``extra["looks"]``: its task's own."""
AGREEMENT = "datasets trained on together agree on what a model reads and predicts"


def task_family(task: str) -> str:
    """The task a dataset's task name is a form of: ``single`` for ``single+randomised``.

    A variant and the randomised looks name their task ``<task>+<what>``
    (``sim.tasks.variants``, ``sim.trials.scene_sets.randomised_looks``).
    """
    return task.split("+", 1)[0]


def labels_and_looks(metadata: DatasetMetadata) -> tuple[str, str]:
    """What labelled a dataset (picked, catalog) and in which looks (task, randomised)."""
    looks = metadata.extra.get("looks", TASK_LOOKS)
    return (str(metadata.extra.get("labels", PICKED_LABELS)),
            str(looks.get("kind") if isinstance(looks, Mapping) else looks))


def is_demonstration(record: Mapping[str, Any]) -> bool:
    """Whether a sample's scene is a demonstration (picked, verified) in its task's looks.

    What a run folder takes as demonstrations (``harness.run_files.dataset_present``), and
    what a held-out check holds out where a training mixes kinds of scene. A record outside a
    joined dataset says nothing of its file and counts as one: a single file is checked as
    it always was, whatever it holds.
    """
    part = record.get(PART_KEY)
    if not isinstance(part, Mapping):
        return True
    return part.get("labels") == PICKED_LABELS and part.get("looks") == TASK_LOOKS


def agreed_values(dataset: Dataset) -> dict[str, Any]:
    """What datasets trained on together must share, by name, as an error shows it.

    The model's spec (:meth:`ModelSpec.from_metadata`: scene, label kind, targets, condition
    kind and choices, image size, camera geometry, object types, sensor, heatmap focus) with
    the task compared by :func:`task_family` (the same task in other looks is the point), and
    the arrays beside the images (a model reading depth needs it of every sample; joint
    positions need one joint order).
    """
    spec = ModelSpec.from_metadata(dataset.metadata)
    values: dict[str, Any] = {}
    for f in fields(spec):
        value = getattr(spec, f.name)
        if f.name == "task":
            values["task family"] = task_family(value)
        elif f.name == "camera":
            values["camera"] = None if value is None else value.to_json()
        else:
            values[f.name] = value.value if isinstance(value, enum.Enum) else value
    values["arrays"] = tuple(n for n in OPTIONAL_TENSORS if getattr(dataset, n) is not None)
    if dataset.joint_positions is not None:
        values[JOINT_NAMES_KEY] = dataset.metadata.extra.get(JOINT_NAMES_KEY)
    return values


def check_agreement(datasets: Sequence[Dataset], names: Sequence[str]) -> None:
    """An error naming the first field in which a dataset differs from the first one.

    The message names the field, both values (a camera's differing entries only) and both
    files: ``image_height_px of b.gva = 64 is not allowed: a.gva's 128 (...)``.
    """
    first = agreed_values(datasets[0])
    for name, dataset in zip(names[1:], datasets[1:], strict=True):
        for key, value in agreed_values(dataset).items():
            if value != first[key]:
                ours, theirs = _differing(value, first[key])
                raise InvalidInputError(f"{key} of {name}", ours,
                                        f"{names[0]}'s {theirs!r} ({AGREEMENT})")


def concatenate(datasets: Sequence[Dataset], names: Sequence[str] | None = None) -> Dataset:
    """One dataset of every sample of ``datasets``, in order, each file's scenes kept apart.

    Args:
        datasets: Datasets that agree (:func:`check_agreement`); one is returned as it is.
        names: What messages and the record name each (its file); default ``dataset 1``, ...

    The metadata is the first dataset's with the size summed, the task name kept where every
    file has the same, else their :func:`task_family`; ``extra`` keeps the entries every file
    holds alike (a flag such as ``mirror_symmetric`` only where all agree), with ``scenes`` the
    scenes joined and :data:`PARTS_KEY` what each file gave. Each record's ``"index"`` is moved
    past the earlier files' scenes (the first file's stay) and its own kept under
    :data:`PART_KEY`, so :meth:`Dataset.scene_keys` never joins scenes of two files.

    """
    if isinstance(datasets, Dataset) or not datasets:
        raise InvalidInputError("datasets", datasets, "a non-empty sequence of datasets")
    names = [f"dataset {k + 1}" for k in range(len(datasets))] if names is None else list(names)
    if len(names) != len(datasets):
        raise InvalidInputError("names", names, f"one per dataset ({len(datasets)})")
    if len(datasets) == 1:
        return datasets[0]
    check_agreement(datasets, names)
    records: list[dict[str, Any]] = []
    parts: list[dict[str, Any]] = []
    offset = 0
    for k, (name, dataset) in enumerate(zip(names, datasets, strict=True)):
        keys = dataset.scene_keys()
        if keys and min(keys) < 0:  # a record without an index is its own scene: number them
            order = {key: i for i, key in enumerate(dict.fromkeys(keys))}
            keys = [order[key] for key in keys]
        labels, looks = labels_and_looks(dataset.metadata)
        records += [record | {"index": offset + key, PART_KEY: {
            "file": k, "index": record.get("index"), "labels": labels, "looks": looks}}
                    for record, key in zip(dataset.scenes, keys, strict=True)]
        offset += max(keys, default=-1) + 1
        meta = dataset.metadata
        parts.append({"name": name, "task": meta.task, "seed": meta.seed, "samples": meta.size,
                      "scenes": len(set(keys)), "labels": labels, "looks": looks})
    first = datasets[0].metadata
    extras = [d.metadata.extra for d in datasets]
    shared = {key: value for key, value in extras[0].items()
              if all(key in extra and extra[key] == value for extra in extras[1:])}
    tasks = {d.metadata.task for d in datasets}
    metadata = replace(first, task=first.task if len(tasks) == 1 else task_family(first.task),
                       size=len(records), extra=shared | {
                           "scenes": sum(part["scenes"] for part in parts), PARTS_KEY: parts})
    present = [n for n in TENSORS + OPTIONAL_TENSORS if getattr(datasets[0], n) is not None]
    return Dataset(metadata, scenes=tuple(records), **{
        n: np.concatenate([getattr(d, n) for d in datasets]) for n in present})


def _differing(ours: Any, theirs: Any) -> tuple[Any, Any]:
    """Two values as a message shows them: of two dicts, the entries that differ only."""
    if isinstance(ours, Mapping) and isinstance(theirs, Mapping):
        keys = [k for k in dict.fromkeys([*ours, *theirs]) if ours.get(k) != theirs.get(k)]
        return ({k: ours[k] for k in keys if k in ours}, {k: theirs[k] for k in keys
                                                          if k in theirs})
    return ours, theirs


def training_files(dataset: Dataset, paths: Sequence[Path]) -> list[dict[str, Any]]:
    """What a checkpoint trained on several files records of each: its part, path and SHA-256.

    ``dataset`` is their :func:`concatenate`; its ``extra["parts"]`` says what each file gave
    (task, scenes, samples, labels, looks), so a checkpoint says it was trained on
    demonstrations plus a randomised set, and which files (``gva train --data A --data B``,
    ``gva reproduce real --randomised-scenes``).
    """
    return [part | {"path": str(path.resolve()), "sha256": file_sha256(path)}
            for part, path in zip(dataset.metadata.extra[PARTS_KEY], paths, strict=True)]
