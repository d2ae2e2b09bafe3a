"""Checkpoints: a folder with ``weights.safetensors`` and ``config.json``; never pickle.

::

    checkpoint/
        weights.safetensors   every tensor of the network (safetensors: no code runs on load)
        config.json           {"format_version", "model", "weights_sha256", "config_sha256",
                               "spec", ...}

``config.json`` names the model, holds what it needs to rebuild its network (hyper-parameters,
the dataset spec with its camera record, the label scaler, ...), the SHA-256 of the weights
file and the SHA-256 of its own values (``config_sha256``, over the canonical JSON of every
other key): a changed value changes predictions as surely as a changed weight, and is refused
the same way. Loading checks, in this order, and refuses with a message naming the file and the
problem: both files exist, the format version, the config's checksum, the model name, the
weights file is whole (not truncated), its checksum, then (in :func:`check_shapes`) every
tensor against the network the config describes. A version-1 checkpoint (written before the
config had a checksum) still loads; :func:`config_verified` says its values are unverified.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from safetensors import SafetensorError
from safetensors.torch import load_file, save_file

from perception.files import FileError, atomic_write, file_sha256, read_safetensors_header
from perception.interface import InvalidInputError

FORMAT_VERSION = 2
READABLE_VERSIONS = (1, 2)
"""Version 1: no ``config_sha256`` (its values cannot be verified); version 2: with it."""
WEIGHTS_FILE = "weights.safetensors"
CONFIG_FILE = "config.json"


class CheckpointError(FileError):
    """A checkpoint that cannot be used; the message names the file and what is wrong."""

    kind = "checkpoint"


@dataclass(frozen=True)
class Checkpoint:
    """What a checkpoint folder holds, checked against its checksum."""

    folder: Path
    config: dict[str, Any]  # the whole config.json
    tensors: dict[str, torch.Tensor]


def save_checkpoint(folder: str | Path, model: str, config: Mapping[str, Any],
                    tensors: Mapping[str, torch.Tensor]) -> Path:
    """Writes ``tensors`` and ``config`` (JSON-able, plus model name, version, checksum).

    Each file is written under a temporary name and renamed into place, the weights first: a
    save that stops half-way leaves a config whose checksum refuses the weights.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    reserved = {"format_version", "model", "weights_sha256", "config_sha256"} & set(config)
    if reserved:
        raise InvalidInputError("config keys", sorted(reserved), "keys other than those "
                                "save_checkpoint writes itself")
    weights = {name: tensor.detach().cpu().contiguous() for name, tensor in tensors.items()}
    atomic_write(folder / WEIGHTS_FILE, lambda path: save_file(weights, str(path)))
    record = {"format_version": FORMAT_VERSION, "model": model,
              "weights_sha256": file_sha256(folder / WEIGHTS_FILE), **config}
    record["config_sha256"] = config_sha256(record)
    text = json.dumps(record, indent=2, sort_keys=True, allow_nan=False) + "\n"
    atomic_write(folder / CONFIG_FILE, lambda path: path.write_text(text, encoding="utf-8"))
    return folder


def read_config(folder: str | Path) -> dict[str, Any]:
    """The checked ``config.json`` of a checkpoint folder (weights not read)."""
    path = Path(folder) / CONFIG_FILE
    if not Path(folder).is_dir():
        raise CheckpointError(Path(folder), "no such folder" if not Path(folder).exists()
                              else "not a folder")
    if not path.is_file():
        raise CheckpointError(path, f"missing: a checkpoint folder holds {CONFIG_FILE} and "
                              f"{WEIGHTS_FILE}")
    try:
        config = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, ValueError) as error:
        raise CheckpointError(path, f"not valid JSON ({error})") from error
    if not isinstance(config, dict):
        raise CheckpointError(path, "not a JSON object")
    version = config.get("format_version")
    if version not in READABLE_VERSIONS:
        raise CheckpointError(path, f"format version {version!r}; this gva reads versions "
                              f"{', '.join(map(str, READABLE_VERSIONS))}")
    needed = ("model", "weights_sha256", "config_sha256")[:2 if version == 1 else 3]
    for key in needed:
        if not isinstance(config.get(key), str):
            raise CheckpointError(path, f"lacks {key!r}")
    if version != 1 and config_sha256(config) != config["config_sha256"]:
        raise CheckpointError(path, "its values do not match its config_sha256: they were "
                              "changed after saving (a hyper-parameter, the label scaler, the "
                              "camera record, ...), which changes what the model predicts")
    return config


def config_sha256(config: Mapping[str, Any]) -> str:
    """The SHA-256 of a config's canonical JSON (sorted keys, no spaces), but its own."""
    values = {key: value for key, value in config.items() if key != "config_sha256"}
    text = json.dumps(values, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def config_verified(config: Mapping[str, Any]) -> bool:
    """Whether ``config`` (as :func:`read_config` gave it) carries a checksum it matched."""
    return config.get("format_version") != 1


def load_checkpoint(folder: str | Path, model: str | None = None) -> Checkpoint:
    """The config and tensors of a checkpoint folder, for ``model`` (any model when None)."""
    folder = Path(folder)
    config = read_config(folder)
    if model is not None and config["model"] != model:
        raise CheckpointError(folder / CONFIG_FILE, f"a checkpoint of model "
                              f"{config['model']!r}, not {model!r}")
    path = folder / WEIGHTS_FILE
    if not path.is_file():
        raise CheckpointError(path, f"missing: a checkpoint folder holds {CONFIG_FILE} and "
                              f"{WEIGHTS_FILE}")
    read_safetensors_header(path, CheckpointError)
    if file_sha256(path) != config["weights_sha256"]:
        raise CheckpointError(path, f"its SHA-256 does not match {CONFIG_FILE}: the weights "
                              "were changed or damaged after saving")
    try:
        tensors = load_file(str(path))
    except (SafetensorError, OSError) as error:
        raise CheckpointError(path, f"safetensors cannot read it ({error})") from error
    return Checkpoint(folder, config, tensors)


def check_shapes(checkpoint: Checkpoint, expected: Mapping[str, torch.Tensor]) -> None:
    """An error unless the checkpoint has exactly ``expected``'s tensors, each of its shape."""
    path, found = checkpoint.folder / WEIGHTS_FILE, checkpoint.tensors
    if missing := sorted(set(expected) - set(found)):
        raise CheckpointError(path, f"lacks tensors {', '.join(missing)} that the network "
                              f"{CONFIG_FILE} describes needs")
    if extra := sorted(set(found) - set(expected)):
        raise CheckpointError(path, f"has tensors {', '.join(extra)} that the network "
                              f"{CONFIG_FILE} describes does not have")
    for name, tensor in expected.items():
        if found[name].shape != tensor.shape or found[name].dtype != tensor.dtype:
            raise CheckpointError(path, f"tensor {name} is {found[name].dtype} "
                                  f"{tuple(found[name].shape)}; the network {CONFIG_FILE} "
                                  f"describes needs {tensor.dtype} {tuple(tensor.shape)}")
