"""Task files: TOML read into a :class:`~sim.tasks.task_spec.TaskSpec`, and written back.

A task file is user input: it is read safely (size, UTF-8, TOML, depth), and every mistake is
an :class:`~sim.errors.InvalidInputError` naming the file, the field, the value and what is
allowed, in one line. The built-in tasks are ``sim/tasks/task_files/*.toml``.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import math
import re
import tomllib
from pathlib import Path
from typing import Any

from perception.interface import ConditionKind
from sim.errors import InvalidInputError
from sim.tasks.appearance_toml import (
    LIGHT_RANGES,
    MOUNT_KEYS,
    appearance_from_toml,
    appearance_to_toml,
)
from sim.tasks.disturbance import Disturbance, DisturbanceWhen, disturbance_from_table
from sim.tasks.phrasings import Phrasings, read_phrase_file
from sim.tasks.task_spec import (
    MAX_OBJECTS,
    ConditionForm,
    ObjectChoice,
    TargetSelection,
    TaskSpec,
    brief,
    finite_number,
)
from sim.world.d435 import D435Config
from sim.world.sensor import SensorConfig, sensor_from_table

MAX_TASK_FILE_BYTES = 64 * 1024
"""A task file is a few hundred bytes; a bigger file is refused unread (an image, a dataset)."""

TASK_FILES = Path(__file__).resolve().parent / "task_files"


def _key(key: str) -> str:
    """A TOML key as written: bare if it can be, else quoted (no newline reaches a message)."""
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)


_SECTIONS: dict[str, set[str]] = {
    "": {"name", "description", "objects", "targets", "condition", "placement", "lighting",
         "distractors", "camera", "disturbance", "table", "appearance"},
    "objects": {"choose", "count", "balance_types", "palette", "textures"},
    "targets": {"select"},
    "condition": {"kind", "given_as", "phrases"},
    "placement": {"sides", "yaw_deg", "min_spacing_m", "x_m", "y_m"},
    "lighting": {"brightness", *LIGHT_RANGES, "shadows"},
    "distractors": {"types", "per_scene"},
    "camera": {"sensor", *MOUNT_KEYS, *(f.name for f in dataclasses.fields(D435Config))},
    "table": {"looks"},
    "appearance": {"held_out"},
    "disturbance": {f.name for f in dataclasses.fields(Disturbance)},
}


class _Reader:
    """Typed access to a parsed TOML table, with errors that name the file and the field."""

    def __init__(self, data: dict[str, Any], source: str) -> None:
        self.data, self.source = data, source

    def error(self, field: str, value: Any, allowed: str) -> InvalidInputError:
        return InvalidInputError(f"task file {self.source}: {field}", brief(value), allowed)

    def check_keys(self) -> None:
        for section, allowed in _SECTIONS.items():
            table = self.data if not section else self.data.get(section, {})
            if not isinstance(table, dict):
                raise self.error(section, table, "a [table]")
            for key in table:
                if key not in allowed:
                    prefix = f"{section}." if section else ""
                    names = ", ".join(sorted(allowed))
                    raise self.error(f"{prefix}{_key(key)}", table[key], f"a known key: {names}")

    def get(self, section: str, key: str, kind: type | tuple[type, ...], default: Any,
            allowed: str | None = None) -> Any:
        """``section.key`` if it has type ``kind`` (a bool is no number), ``default`` if absent.

        ``allowed`` says what the field takes in the error; by default, the type's name.
        """
        table = self.data if not section else self.data.get(section, {})
        value = table.get(key, default)
        field = f"{section}.{key}" if section else key
        wrong_type = not isinstance(value, kind) or (isinstance(value, bool) and kind is not bool)
        if value is not default and wrong_type:
            kinds = (kind,) if isinstance(kind, type) else kind
            raise self.error(field, value,
                             allowed or f"a {' or '.join(k.__name__ for k in kinds)}")
        return value

    def choice(self, section: str, key: str, enum_type: type[enum.Enum], default: enum.Enum) -> Any:
        value = self.get(section, key, str, default.value)
        try:
            return enum_type(value)
        except ValueError:
            allowed = ", ".join(repr(e.value) for e in enum_type)
            raise self.error(f"{section}.{key}", value, f"one of {allowed}") from None

    def number(self, section: str, key: str, default: float) -> float:
        """``section.key`` as a float; NaN and inf pass (the task's range check names them)."""
        value = self.get(section, key, (int, float), default, "a finite number")
        try:
            return float(value)
        except OverflowError:  # TOML integers are unbounded in tomllib: 1e400 as digits
            raise self.error(f"{section}.{key}", value, "a finite number") from None

    def pair(self, section: str, key: str) -> tuple[float, float] | None:
        """``section.key`` as ``(low, high)``, two finite numbers; None if absent."""
        value = self.get(section, key, list, None, "a list of two finite numbers [low, high]")
        if value is None:
            return None
        if len(value) != 2 or not all(finite_number(v) for v in value):
            raise self.error(f"{section}.{key}", value, "a list of two finite numbers [low, high]")
        return float(value[0]), float(value[1])

    def span(self, section: str, key: str) -> tuple[float, float] | None:
        """``section.key``, a number or ``[low, high]``, as ``(low, high)``; None if absent."""
        allowed = "a finite number or a list of two [low, high]"
        value = self.get(section, key, (int, float, list), None, allowed)
        if value is None:
            return None
        values = value if isinstance(value, list) else [value, value]
        if len(values) != 2 or not all(finite_number(v) for v in values):
            raise self.error(f"{section}.{key}", value, allowed)
        return float(values[0]), float(values[1])

    def names(self, section: str, key: str, default: tuple[str, ...]) -> tuple[str, ...]:
        """``section.key`` as a list of names; ``default`` if absent."""
        value = self.get(section, key, list, None, "a list of names")
        if value is None:
            return default
        if not all(isinstance(v, str) for v in value):
            raise self.error(f"{section}.{key}", value, "a list of names")
        return tuple(value)


def task_from_toml(text: str, source: str = "<string>", folder: Path | None = None) -> TaskSpec:
    """Reads a task from TOML text; every mistake is an error naming the file and the field.

    ``folder``: where the file lies; a palette file it names is read relative to it.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise InvalidInputError(f"task file {source}", "not valid TOML",
                                f"TOML ({error})") from None
    except RecursionError:  # tomllib recurses per level: ~300 nested arrays exhaust the stack
        raise InvalidInputError(f"task file {source}", "arrays or tables nested too deeply",
                                "TOML nested as a task is (tables of keys, lists of values)"
                                ) from None
    return task_from_data(data, source, folder)


def task_from_data(data: dict[str, Any], source: str, folder: Path | None = None) -> TaskSpec:
    """Reads a task from a parsed task file (``tomllib``'s tables), as :func:`task_from_toml`."""
    reader = _Reader(data, source)
    reader.check_keys()
    name = reader.get("", "name", str, None)
    if not name:
        raise reader.error("name", name, "a non-empty string")
    yaw = reader.pair("placement", "yaw_deg") or (-180.0, 180.0)
    distractors = reader.get("distractors", "types", list, [])
    if not all(isinstance(t, str) for t in distractors):
        raise reader.error("distractors.types", distractors, "a list of object type names")
    per_scene = reader.get("distractors", "per_scene", list, None,
                           "a list of two integers [low, high]")
    if per_scene is not None and not (len(per_scene) == 2 and all(
            isinstance(v, int) and not isinstance(v, bool) for v in per_scene)):
        raise reader.error("distractors.per_scene", per_scene, "a list of two integers [low, high]")
    return TaskSpec(
        name=name,
        description=reader.get("", "description", str, ""),
        objects=reader.choice("objects", "choose", ObjectChoice, ObjectChoice.RANDOM),
        count=reader.get("objects", "count", int, 1, f"an integer in [1, {MAX_OBJECTS}]"),
        balance_types=reader.get("objects", "balance_types", bool, False, "true or false"),
        targets=reader.choice("targets", "select", TargetSelection, TargetSelection.ALL),
        condition=reader.choice("condition", "kind", ConditionKind, ConditionKind.NONE),
        given_as=reader.choice("condition", "given_as", ConditionForm, ConditionForm.ONE_HOT),
        phrasings=_phrasings(reader, source),
        sides=reader.get("placement", "sides", bool, False, "true or false"),
        yaw_range_rad=(math.radians(yaw[0]), math.radians(yaw[1])),
        min_spacing_m=reader.number("placement", "min_spacing_m", 0.12),
        workspace_x_m=reader.pair("placement", "x_m"),
        workspace_y_m=reader.pair("placement", "y_m"),
        brightness=reader.number("lighting", "brightness", 1.0),
        distractors=tuple(distractors),
        distractors_per_scene=None if per_scene is None else (per_scene[0], per_scene[1]),
        camera=_camera(reader, source),
        disturbance=_disturbance(reader, source),
        appearance=appearance_from_toml(reader, folder),
        source=source,
    )


def _disturbance(reader: _Reader, source: str) -> Disturbance | None:
    """``[disturbance]``: how the target moves during a pick; None where the table is absent."""
    if "disturbance" not in reader.data:
        return None
    table: dict[str, Any] = {
        "move_m": reader.pair("disturbance", "move_m") or (0.0, 0.0),
        "turn_deg": reader.pair("disturbance", "turn_deg") or (0.0, 0.0),
        "velocity_m_s": reader.number("disturbance", "velocity_m_s", 0.0),
        "when": reader.choice("disturbance", "when", DisturbanceWhen, DisturbanceWhen.APPROACH)}
    return disturbance_from_table(table, f"task file {source}")


def _camera(reader: _Reader, source: str) -> SensorConfig | None:
    """``[camera]``: ``sensor = "ideal"`` or ``"d435"``, and D435 fields by name.

    None where the file names no sensor: the command's sensor renders the task (``--sensor``,
    else the D435; :mod:`sim.tasks.task_sensor`). D435 fields need ``sensor = "d435"`` beside
    them: under ``--sensor ideal`` they would be recorded yet never used.
    """
    table = reader.get("", "camera", dict, None, 'a table such as { sensor = "d435" }')
    if table is None:
        return None
    table = {k: v for k, v in table.items() if k not in MOUNT_KEYS}  # the mount: not the sensor
    if "sensor" not in table:
        if table:
            key = sorted(table)[0]
            raise reader.error(f"camera.{_key(key)}", table[key], "absent unless sensor = "
                               "'d435' is named beside it (without one the command's sensor "
                               "renders, and --sensor ideal has no D435 parameters)")
        return None
    try:
        return sensor_from_table(table, f"task file {source}: camera")
    except InvalidInputError as error:  # a long value shortened: the message stays one line
        raise InvalidInputError(error.field, brief(error.value), error.allowed) from None


def _phrasings(reader: _Reader, source: str) -> Phrasings | None:
    """``[condition.phrases]``: tables ``train`` and ``test`` of target = [phrasings]."""
    table = reader.get("condition", "phrases", dict, None, "a table with tables train and test")
    if table is None:
        return None
    if set(table) != {"train", "test"}:
        raise reader.error("condition.phrases", sorted(table), "exactly the tables train and "
                           "test")
    for split in ("train", "test"):
        if not isinstance(table[split], dict):
            raise reader.error(f"condition.phrases.{split}", table[split],
                               "a table of target = [phrasings]")
    return Phrasings(tuple(table["train"].items()), tuple(table["test"].items()),
                     f"task file {source}")


def with_test_phrases(task: TaskSpec, path: str | Path, targets: tuple[str, ...],
                      known: tuple[str, ...]) -> TaskSpec:
    """``task`` tested with the phrase file ``path`` (``gva trials --phrases``).

    ``targets`` are the values the task names in its scene, ``known`` every value a condition
    names there (its types and the sides): a file's lines for known values the task does not
    name (another task's sides, say) are left out, so one file serves several tasks; an
    unknown one is refused as a typo.

    Raises:
        InvalidInputError: The task is not given as text, the file is malformed, or it leaves
            a target without a phrasing.

    """
    if task.phrasings is None:
        raise InvalidInputError("phrases", str(path), f"a task given as text (task {task.name!r}"
                                f" is given as {task.given_as.value})")
    table = read_phrase_file(path, known)
    kept = tuple((target, phrases) for target, phrases in table if target in targets)
    missing = [t for t in targets if t not in dict(kept)]
    if missing:
        raise InvalidInputError(f"phrases {Path(path).name}", f"no line for {missing}",
                                f"at least one phrase for every target of task {task.name!r} "
                                f"({', '.join(targets)})")
    return dataclasses.replace(task, phrasings=task.phrasings.with_test(kept, Path(path).name))


def task_from_bytes(data: bytes, source: str = "<bytes>", folder: Path | None = None) -> TaskSpec:
    """Reads a task from a file's bytes: UTF-8 text (a leading BOM is skipped), then TOML.

    ``folder``: where the file lies (palette files are read relative to it).
    """
    if len(data) > MAX_TASK_FILE_BYTES:
        raise InvalidInputError(f"task file {source}", f"{len(data)} bytes or more",
                                f"a task file of at most {MAX_TASK_FILE_BYTES} bytes")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise InvalidInputError(f"task file {source}", "not UTF-8 text", "a TOML text file in "
                                f"UTF-8 (byte {error.start} is {data[error.start]:#04x})"
                                ) from None
    return task_from_toml(text, source, folder)


def task_to_toml(task: TaskSpec) -> str:
    """``task`` as the text of a task file, every key written; ``task_from_toml`` reads it back.

    Used to write variants of a task, e.g. the same task under dimmer light::

        text = task_to_toml(dataclasses.replace(load_task("single"), name="single-dark",
                                                brightness=0.5))
    """

    def value(item: Any) -> str:
        if isinstance(item, bool):
            return "true" if item else "false"
        if isinstance(item, str):
            return json.dumps(item)  # a JSON string is a TOML basic string
        if isinstance(item, tuple | list):
            return "[" + ", ".join(value(v) for v in item) + "]"
        return repr(float(item)) if isinstance(item, float) else str(item)

    placement: dict[str, Any] = {
        "sides": task.sides,
        "yaw_deg": [math.degrees(a) for a in task.yaw_range_rad],
        "min_spacing_m": task.min_spacing_m}
    if task.workspace_x_m is not None:
        placement["x_m"] = list(task.workspace_x_m)
    if task.workspace_y_m is not None:
        placement["y_m"] = list(task.workspace_y_m)
    tables: dict[str, dict[str, Any]] = {
        "objects": {"choose": task.objects.value, "count": task.count,
                    "balance_types": task.balance_types},
        "targets": {"select": task.targets.value},
        "condition": {"kind": task.condition.value, "given_as": task.given_as.value},
        "placement": placement,
        "lighting": {"brightness": task.brightness},
        "distractors": {"types": list(task.distractors)} | (
            {} if task.distractors_per_scene is None
            else {"per_scene": list(task.distractors_per_scene)}),
    }
    if task.camera is not None:  # none named: the command's sensor (sim.tasks.task_sensor)
        tables["camera"] = task.camera.to_json()
    appearance_to_toml(task.appearance, tables)
    if task.disturbance is not None:
        tables["disturbance"] = task.disturbance.to_json()
    if task.phrasings is not None:
        for split, phrases in task.phrasings.to_json().items():
            tables[f"condition.phrases.{split}"] = {_key(t): p for t, p in phrases.items()}
    lines = [f"name = {value(task.name)}", f"description = {value(task.description)}"]
    for table, keys in tables.items():
        lines += ["", f"[{table}]", *(f"{key} = {value(v)}" for key, v in keys.items())]
    return "\n".join(lines) + "\n"


def builtin_tasks() -> tuple[str, ...]:
    """Names of the tasks that ship with gva (``sim/tasks/task_files/*.toml``)."""
    return tuple(sorted(p.stem for p in TASK_FILES.glob("*.toml")))


def load_task(name_or_path: str | Path) -> TaskSpec:
    """A built-in task by name, or a task file by path."""
    text = str(name_or_path)
    path = Path(text)
    if text.endswith(".toml") or path.is_file():
        if not path.is_file():
            raise InvalidInputError("task file", text, "an existing TOML file")
        source = path.name if path.name.isprintable() else repr(path.name)
        try:
            with path.open("rb") as file:
                data = file.read(MAX_TASK_FILE_BYTES + 1)  # enough to tell a file too big
        except OSError as error:
            raise InvalidInputError("task file", text, f"a readable file ({error.strerror})"
                                    ) from None
        return task_from_bytes(data, source, path.resolve().parent)
    if text not in builtin_tasks():
        raise InvalidInputError(
            "task", text, f"one of {', '.join(builtin_tasks())}, or the path of a .toml file"
        )
    return task_from_toml((TASK_FILES / f"{text}.toml").read_text(), f"{text}.toml")
