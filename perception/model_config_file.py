"""Model config files: a model's hyper-parameters set from TOML, checked like a task file.

A model config file sets fields of a model's config dataclass (``KqvConfig`` for ``kqv``, ...)
as top-level keys; a key left out keeps the preset's value, else the default::

    # kqv as the paper computes its attention, from one start
    similarity = "dot"
    starts = 1
    channels = [32, 32]          # an array is read as a tuple

``gva train --model-config FILE`` and ``gva reproduce sim|real --model-config MODEL=FILE`` read
it with :func:`read_model_config`. Every mistake (an unknown key, a table, ``seed``, a value
the config refuses, a file that is missing or not TOML) is an
:class:`~perception.interface.InvalidInputError` naming the file, in one line.
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import re
import tomllib
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from perception.interface import InvalidInputError
from perception.learning.learnable import LearnableModel
from perception.models.torch_model import TorchModel
from perception.registry import resolve_model_config, trainable

MAX_MODEL_CONFIG_BYTES = 64 * 1024
"""A model config file is a few lines; a bigger file is refused unread (a dataset, a model)."""
_SHOWN_CHARS = 80
_KINDS = {bool: "true or false", int: "an integer", float: "a number", str: "a string",
          tuple: "an array"}


@dataclass(frozen=True)
class ModelConfigFile:
    """A model config file as read: the model it was read for, its path and its settings.

    Frozen and hashable, so run settings can hold it; ``settings`` are (field, value) pairs in
    the file's order, arrays as tuples.
    """

    model: str
    path: str  # as given on the command line, so a printed command runs again
    settings: tuple[tuple[str, Any], ...]

    @classmethod
    def read(cls, path: str | Path, model: str) -> ModelConfigFile:
        """The file at ``path``, read and checked for ``model`` (:func:`read_model_config`)."""
        return cls(model, str(path), tuple(read_model_config(path, model).items()))

    def hyperparameters(self) -> dict[str, Any]:
        """The settings as keyword arguments of ``new_model``."""
        return dict(self.settings)

    def to_json(self) -> dict[str, Any]:
        """``{"path": ..., "settings": {...}}``, arrays as lists: what a record keeps of it."""
        return json.loads(json.dumps({"path": self.path, "settings": self.hyperparameters()}))

    def record(self, model: LearnableModel) -> None:
        """Notes this file in ``model``'s training record (its checkpoint's ``config.json``).

        The hyper-parameters are saved whole either way; this says which of them a file set,
        and which file. Only a :class:`TorchModel` (all ``new_model`` builds) keeps a record.
        """
        if isinstance(model, TorchModel):
            model.provenance["model_config_file"] = self.to_json()


def read_model_config(path: str | Path, model: str) -> dict[str, Any]:
    """The settings a model config file gives ``model``: config field -> value.

    A key left out keeps the preset's value, else the config's default; so a field that may be
    None cannot be set to None here (TOML has no null): leave it out for its default.

    Args:
        path: A TOML file of top-level keys, each a field of the model's config dataclass
            but ``seed`` (seeds come from ``--seed``).
        model: A registered name, a preset (its settings are the base the file changes) or
            ``"package.module:Class"`` of a :class:`~perception.models.torch_model.TorchModel`.

    Raises:
        InvalidInputError: An unknown model; a file that is missing, too big, not UTF-8 or not
            TOML; an unknown key, a table, ``seed``, or a value of the wrong type, beyond 64
            bits or one the config refuses (every number of gva's configs has an upper bound,
            each with its reason in the config's module: ``key_dim`` at most 4096, ...). The
            message names the file, the key, the value and what is allowed.

    """
    cls = trainable(model).cls
    source = str(path)
    data = _read_toml(Path(path), source)
    config_class = cls.config_class
    allowed = [f.name for f in dataclasses.fields(config_class) if f.name != "seed"]
    keys = f"fields of {config_class.__name__}: {', '.join(allowed)}"
    try:
        hints = typing.get_type_hints(config_class)
    except (NameError, TypeError):  # a plug-in's unresolvable annotation: its config checks
        hints = {}
    settings: dict[str, Any] = {}
    for key, value in data.items():
        field = f"model config {source}: {_key(key)}"
        if key == "seed":
            raise InvalidInputError(field, _brief(value), f"set by --seed, not by the file; "
                                    f"its keys are {keys}")
        if isinstance(value, datetime.date | datetime.time):
            raise InvalidInputError(field, _brief(value), "a string, number, boolean or array; "
                                    "no config field is a date or a time")
        if _holds_table(value):
            raise InvalidInputError(field, _brief(value), "a value, not a [table]: the file "
                                    f"holds top-level keys only, {keys}")
        if key not in allowed:
            raise InvalidInputError(field, _brief(value), f"a known key, one of the {keys}")
        value = _tuples(value)
        kinds = _kinds(hints.get(key))
        if kinds is not None and not _fits(value, kinds):
            raise InvalidInputError(field, _brief(value), " or ".join(_KINDS[k] for k in kinds))
        settings[key] = value
    try:
        resolve_model_config(model, None, settings)
    except InvalidInputError as error:  # the config's own check, told where the value came from
        raise InvalidInputError(f"model config {source}: {error.field}", error.value,
                                error.allowed) from None
    except (TypeError, ValueError) as error:
        raise InvalidInputError(f"model config {source}", _brief(settings),
                                f"values {config_class.__name__} accepts ({error})") from None
    for key, value in settings.items():  # tomllib reads integers of any size; TOML's are 64-bit
        if _beyond_int64(value):  # and a plug-in's config may bound none of its own
            raise InvalidInputError(f"model config {source}: {_key(key)}", _brief(value),
                                    f"integers of TOML's 64 bits, {-2 ** 63} to {2 ** 63 - 1}")
    return settings


def _read_toml(path: Path, source: str) -> dict[str, Any]:
    """The parsed file; a missing, oversized, non-UTF-8 or non-TOML file names itself."""
    field = f"model config {source}"
    try:
        with path.open("rb") as file:
            data = file.read(MAX_MODEL_CONFIG_BYTES + 1)  # enough to tell a file too big
    except OSError as error:
        raise InvalidInputError(field, (error.strerror or "unreadable").lower(),
                                "an existing, readable TOML file") from None
    if len(data) > MAX_MODEL_CONFIG_BYTES:
        raise InvalidInputError(field, f"{len(data)} bytes or more",
                                f"a model config file of at most {MAX_MODEL_CONFIG_BYTES} bytes")
    try:
        return tomllib.loads(data.decode("utf-8-sig"))
    except UnicodeDecodeError as error:
        raise InvalidInputError(field, "not UTF-8 text", f"a TOML text file in UTF-8 (byte "
                                f"{error.start} is {data[error.start]:#04x})") from None
    except tomllib.TOMLDecodeError as error:
        raise InvalidInputError(field, "not valid TOML", f"TOML ({error})") from None
    except RecursionError:  # tomllib recurses per level: ~300 nested arrays exhaust the stack
        raise InvalidInputError(field, "arrays nested too deeply", "TOML of top-level keys "
                                "and flat arrays") from None


def _holds_table(value: Any) -> bool:
    """Whether ``value`` is a table, or an array with one inside."""
    if isinstance(value, dict):
        return True
    return isinstance(value, list) and any(_holds_table(item) for item in value)


def _tuples(value: Any) -> Any:
    """``value`` with every array a tuple: configs are frozen and compared by value."""
    return tuple(_tuples(item) for item in value) if isinstance(value, list) else value


def _beyond_int64(value: Any) -> bool:
    """Whether ``value`` is, or holds, an integer the TOML spec's 64 bits cannot hold."""
    if isinstance(value, tuple):
        return any(_beyond_int64(item) for item in value)
    return isinstance(value, int) and not -2 ** 63 <= value < 2 ** 63


def _kinds(hint: Any) -> tuple[type, ...] | None:
    """The TOML kinds a field's type annotation takes (None dropped); None: not checked here."""
    members = typing.get_args(hint) if typing.get_origin(hint) in (
        typing.Union, types.UnionType) else (hint,)
    kinds = tuple(typing.get_origin(m) or m for m in members if m is not type(None))
    return kinds if kinds and all(k in _KINDS for k in kinds) else None


def _fits(value: Any, kinds: tuple[type, ...]) -> bool:
    """Whether a TOML value has one of ``kinds``: a bool is no number, an integer a float."""
    if isinstance(value, bool):
        return bool in kinds
    if isinstance(value, int):
        return int in kinds or float in kinds
    return any(isinstance(value, k) for k in kinds if k is not int)


def _key(key: str) -> str:
    """A TOML key as written: bare if it can be, else quoted (no newline reaches a message)."""
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)


def _brief(value: Any) -> Any:
    """``value``, or the start of its repr when it would not fit a one-line message."""
    text = repr(value)
    return value if len(text) <= _SHOWN_CHARS else _Shown(f"{text[:_SHOWN_CHARS]}...")


class _Shown:
    """A shortened value: its repr is the given text (no quotes added)."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text


def settings_text(settings: Mapping[str, Any]) -> str:
    """``similarity = 'dot', starts = 1``: settings in one line, for messages and summaries."""
    return ", ".join(f"{key} = {value!r}" for key, value in settings.items())
