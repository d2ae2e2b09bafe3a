"""One file per dataset: images, conditions, labels and scene records, written and read strictly.

A dataset file is a single safetensors file::

    images      uint8   (N, H, W, 3)  RGB, row 0 at the top
    conditions  float32 (N, C)        one-hot rows in ``condition_choices`` order (C = 0 allowed)
    labels      float32 (N, q, D)     D = 3 (x, y, z [m]) or 12 (then the 3x3 TCP rotation,
                                      row-major); see :func:`label_vector`
    __metadata__ = {"gva.dataset": JSON {"metadata": {...}, "scenes": [...],
                                         "contents_sha256": "..."}}

One metadata entry, not three, because safetensors writes ``__metadata__`` from a hash map whose
order changes from call to call; inside it the JSON has sorted keys, so the same dataset always
gives the same bytes. The SHA-256 covers the metadata, the scene records and every tensor byte,
so a file changed after writing (a flipped pixel, an edited seed) is refused, which safetensors'
own header check would not catch. :func:`load_dataset` checks everything else it can before use:
truncation, format version, shapes and dtypes against the metadata, and what the caller expects.
"""

from __future__ import annotations

import enum
import hashlib
import json
from collections.abc import Mapping
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
from safetensors import SafetensorError, safe_open
from safetensors.numpy import save_file

from perception.files import FileError, atomic_write, read_safetensors_header
from perception.interface import ConditionKind, InvalidInputError, LabelKind
from perception.learning.data import (
    FORMAT_VERSION,
    OPTIONAL_TENSORS,
    TENSORS,
    Dataset,
    DatasetMetadata,
    expected_arrays,
)
from perception.learning.json_form import canonical_json

HEADER_KEY = "gva.dataset"  # the one safetensors metadata entry this module reads and writes
_NAMES = ", ".join(TENSORS)
_CODES = {np.dtype(np.uint8): "U8", np.dtype(np.float32): "F32"}  # safetensors' dtype names
_RECORD_KEYS = {"metadata", "scenes", "contents_sha256"}


class DatasetError(FileError):
    """A dataset file that cannot be used: missing, damaged, truncated, changed or not as asked."""

    kind = "dataset"


def save_dataset(dataset: Dataset, path: str | Path) -> Path:
    """Writes ``dataset`` to ``path`` (parents created) atomically; the same data, the same bytes.

    The file appears under its name only once complete: it is written to a temporary file in the
    same folder, flushed to disk, then renamed over ``path``.
    """
    if not isinstance(dataset, Dataset):
        raise InvalidInputError("dataset", type(dataset).__name__, "a Dataset")
    path = Path(path)
    tensors = {name: np.ascontiguousarray(array) for name, array in dataset.tensors().items()}
    record = _record(dataset)
    record["contents_sha256"] = _contents_sha256(record, tensors)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda temporary: save_file(
        tensors, str(temporary), metadata={HEADER_KEY: canonical_json(record)}))
    return path


def contents_sha256(dataset: Dataset) -> str:
    """The checksum a dataset file keeps of ``dataset`` (its metadata, records and arrays).

    Another container of the same data (a LeRobot folder) keeps it too, so a reader can tell
    it got back exactly what was written.
    """
    return _contents_sha256(_record(dataset), dataset.tensors())


def metadata_to_json(metadata: DatasetMetadata) -> dict[str, Any]:
    """``metadata`` in the JSON form a dataset file (or a LeRobot export) keeps it."""
    return {f.name: _plain(getattr(metadata, f.name)) for f in fields(DatasetMetadata)}


def metadata_from_json(data: Mapping[str, Any]) -> DatasetMetadata:
    """The metadata :func:`metadata_to_json` wrote, validated (an error names the field)."""
    values = dict(data)
    choices = data["condition_choices"]
    values["condition_choices"] = tuple(choices) if isinstance(choices, list) else choices
    for name, kind in (("label_kind", LabelKind), ("condition_kind", ConditionKind)):
        try:
            values[name] = kind(data[name])
        except (ValueError, TypeError):
            allowed = ", ".join(member.value for member in kind)
            raise InvalidInputError(name, data[name], f"one of {allowed}") from None
    return DatasetMetadata(**values)


def _record(dataset: Dataset) -> dict[str, Any]:
    """The file's record of ``dataset`` in JSON form, before its checksum."""
    return {"metadata": metadata_to_json(dataset.metadata), "scenes": list(dataset.scenes)}


def read_metadata(path: str | Path) -> DatasetMetadata:
    """The metadata of the dataset at ``path``, from its header alone (no image is read)."""
    path = Path(path)
    return _metadata_from_json(path, _read_record(path, _read_header(path))["metadata"])


def load_dataset(path: str | Path, expect: Mapping[str, Any] | None = None) -> Dataset:
    """The dataset at ``path``, checked in full; ``expect`` maps metadata fields to required values.

    Raises:
        InvalidInputError: ``expect`` names a field :class:`DatasetMetadata` does not have.
        DatasetError: The file cannot be used; the message says what is wrong and what was expected.

    """
    path, expect = Path(path), dict(expect or {})
    names = [f.name for f in fields(DatasetMetadata)]
    if unknown := sorted(set(expect) - set(names)):
        raise InvalidInputError("expect", unknown, f"metadata fields: {', '.join(names)}")
    header = _read_header(path)
    record = _read_record(path, header)
    metadata = _metadata_from_json(path, record["metadata"])
    mismatches = [f"{name} is {record['metadata'][name]!r} in the file, expected {_plain(value)!r}"
                  for name, value in expect.items() if record["metadata"][name] != _plain(value)]
    if mismatches:
        raise DatasetError(path, "not the dataset asked for: " + "; ".join(mismatches))
    entries = {name: entry for name, entry in header.items() if name != "__metadata__"}
    if missing := sorted(set(TENSORS) - set(entries)):
        raise DatasetError(path, f"lacks tensors {', '.join(missing)}; it needs {_NAMES}")
    if extra := sorted(set(entries) - set(TENSORS) - set(OPTIONAL_TENSORS)):
        raise DatasetError(path, f"has unexpected tensors {', '.join(extra)}; it holds {_NAMES}"
                           f", and may hold {', '.join(OPTIONAL_TENSORS)}")
    present = tuple(name for name in OPTIONAL_TENSORS if name in entries)
    for name, (dtype, shape, layout) in expected_arrays(metadata, present).items():
        found = (entries[name].get("dtype"), tuple(entries[name].get("shape", ())))
        if found != (_CODES[dtype], shape):
            raise DatasetError(path, f"tensor {name} is {found[0]} of shape {found[1]}; the "
                               f"metadata says {_CODES[dtype]} {layout} = {shape}")
    try:
        with safe_open(str(path), framework="numpy") as file:
            tensors = {name: file.get_tensor(name) for name in TENSORS + present}
    except (SafetensorError, OSError) as error:
        raise DatasetError(path, f"safetensors cannot read it: {error}") from error
    if _contents_sha256(record, tensors) != record["contents_sha256"]:
        raise DatasetError(path, "contents do not match their checksum: the file was changed or "
                           "damaged after it was written")
    try:
        return Dataset(metadata, scenes=tuple(record["scenes"]), **tensors)
    except InvalidInputError as error:
        raise DatasetError(path, f"holds data a dataset cannot have: {error}") from error


def _read_header(path: Path) -> dict[str, Any]:
    """The safetensors header JSON of ``path``, after checking the file is whole."""
    return read_safetensors_header(path, DatasetError)


def _read_record(path: Path, header: Mapping[str, Any]) -> dict[str, Any]:
    """The gva record in ``header``, its format version checked first."""
    entries = header.get("__metadata__")
    text = entries.get(HEADER_KEY) if isinstance(entries, dict) else None
    if not isinstance(text, str):
        raise DatasetError(path, f"not a gva dataset: no {HEADER_KEY!r} entry in its metadata")
    try:
        record = json.loads(text)
    except ValueError as error:
        raise DatasetError(path, f"the {HEADER_KEY!r} JSON is damaged ({error})") from error
    metadata = record.get("metadata") if isinstance(record, dict) else None
    if not isinstance(metadata, dict):
        raise DatasetError(path, f"the {HEADER_KEY!r} entry lacks its metadata object")
    version = metadata.get("format_version")
    if version != FORMAT_VERSION:
        raise DatasetError(path, f"written by format version {version}; this gva reads version "
                           f"{FORMAT_VERSION}")
    if missing := sorted(_RECORD_KEYS - set(record)):
        raise DatasetError(path, f"the {HEADER_KEY!r} entry lacks {', '.join(missing)}")
    names = {f.name for f in fields(DatasetMetadata)}
    if missing := sorted(names - set(metadata)):
        raise DatasetError(path, f"metadata lacks keys {', '.join(missing)}; "
                           f"version {FORMAT_VERSION} has {', '.join(sorted(names))}")
    if unknown := sorted(set(metadata) - names):
        raise DatasetError(path, f"metadata has unknown keys {', '.join(unknown)}; "
                           f"version {FORMAT_VERSION} has {', '.join(sorted(names))}")
    return dict(record)


def _metadata_from_json(path: Path, data: Mapping[str, Any]) -> DatasetMetadata:
    """The metadata in its JSON form ``data`` (keys already checked), validated."""
    try:
        return metadata_from_json(data)
    except InvalidInputError as error:
        raise DatasetError(path, f"metadata is not valid: {error}") from error


def _plain(value: Any) -> Any:
    """``value`` as it reads back from JSON (enums by value, tuples as lists)."""
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, tuple | list):
        return [_plain(item) for item in value]
    return value


def _contents_sha256(record: Mapping[str, Any], tensors: Mapping[str, np.ndarray]) -> str:
    """SHA-256 over the metadata, the scene records and each tensor's dtype, shape and bytes."""
    digest = hashlib.sha256(canonical_json([record["metadata"], record["scenes"]]).encode())
    for name in [n for n in TENSORS + OPTIONAL_TENSORS if n in tensors]:  # old files: TENSORS
        array = np.ascontiguousarray(tensors[name])
        digest.update(f"\n{name} {array.dtype.str} {array.shape}\n".encode())
        digest.update(array.reshape(-1).view(np.uint8).data)
    return digest.hexdigest()
