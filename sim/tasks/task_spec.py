"""Tasks as data: TOML files read into a frozen :class:`TaskSpec`.

A task says which objects are presented, which of them are the targets and in what order,
what the top-down condition names, and how the scene is drawn (placement, yaw, spacing,
lighting, distractors). The paper's four tasks (Table I) ship as ``sim/tasks/task_files/*.toml``;
a user writes a new one as a TOML file and passes its path wherever a task name is taken::

    name = "two-sponges-left"
    description = "Two sponges, one on each side; pick the one the condition names."

    [objects]
    choose = "same_type"      # random | one_of_each | same_type
    count = 2

    [targets]
    select = "condition"      # all | condition

    [condition]
    kind = "side"             # none | object_type | side

    [placement]
    sides = true              # one object each side of the workspace's centre line
    yaw_deg = [-180.0, 180.0]
    min_spacing_m = 0.12

    [lighting]
    brightness = 1.0          # 1 = the scene's normal light; 0.3 is a dim room

    [distractors]
    types = []                # extra objects that are never targets (yumi: also "block")

A task is valid in both scenes: the object types come from the scene (``paper-sim``: duck,
soccer ball, mug; ``yumi``: sponge, spray bottle, mug, plus a wooden block as a distractor
only), and so does the workspace unless the task narrows it with ``[placement] x_m = [lo, hi]``
and ``y_m = [lo, hi]``.

A task file is user input: every number must be finite and within the range below, and every
mistake is an :class:`~sim.errors.InvalidInputError` naming the file, the field, the value and
what is allowed. The ranges (and why each bound) are tabulated in ``docs/tasks.md``.
"""

from __future__ import annotations

import enum
import json
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from perception.interface import ConditionKind
from sim.errors import InvalidInputError

TASK_FILES = Path(__file__).resolve().parent / "task_files"
SIDES = ("left", "right")
"""Side condition values: ``left`` is +y (the robot's left, the image's left)."""

MAX_OBJECTS = 12
"""Most objects a scene presents, distractors included. The objects are ~10 cm across and the
larger workspace (``paper-sim``, 0.28 m x 0.36 m) holds 12 of them side by side (3 x 4 at 0.1 m);
more would overlap, and every body slows each physics step, depth image and plan."""
MAX_SPACING_M = 0.5
"""Largest ``placement.min_spacing_m`` [m]: wider than either scene's workspace is across."""
MAX_PLACEMENT_ABS_M = 1.0
"""``placement.x_m`` and ``y_m`` lie within +-1 m of the robot (its arms reach ~0.6 m); the scene
then checks them against its own workspace."""
MAX_YAW_DEG = 360.0
"""``placement.yaw_deg`` lies in [-360, 360] degrees."""
MAX_BRIGHTNESS = 2.0
"""``lighting.brightness`` lies in (0, 2]: from dark up to twice the scene's normal light."""
MAX_NAME_CHARS = 100
"""A task's name is 1-100 printable characters: it is shown in progress bars and one-line errors."""
MAX_DESCRIPTION_CHARS = 1000
"""A description is a sentence or two for people."""
MAX_TASK_FILE_BYTES = 64 * 1024
"""A task file is a few hundred bytes; a bigger file is refused unread (an image, a dataset)."""
_SHOWN_CHARS = 120
"""Longer values are shortened in error messages (a message stays one readable line)."""


class ObjectChoice(enum.Enum):
    """How the presented objects' types are drawn."""

    RANDOM = "random"  # ``count`` objects, each of a random type
    ONE_OF_EACH = "one_of_each"  # one object of every type of the scene
    SAME_TYPE = "same_type"  # ``count`` objects of one random type


class TargetSelection(enum.Enum):
    """Which presented objects are targets."""

    ALL = "all"  # every object, ordered by the scene's type order, then from right to left
    CONDITION = "condition"  # the one object the condition names


@dataclass(frozen=True)
class TaskSpec:
    """One task, as read from its TOML file (see the module docstring for the layout).

    Args:
        name: The task's name.
        description: One sentence for people.
        objects: How object types are drawn.
        count: How many objects are presented (``one_of_each``: the scene's type count).
        targets: Which objects are targets.
        condition: What the top-down condition names.
        sides: Place one object on each side of the workspace's centre line (y = centre).
        yaw_range_rad: Range of object yaw about the vertical [rad].
        min_spacing_m: Smallest distance between object centres [m].
        workspace_x_m, workspace_y_m: Narrower placement ranges than the scene's [m]; None
            keeps the scene's.
        brightness: Light level, 1 = the scene's normal light.
        distractors: Types of extra objects that are presented but never targets.
        source: The file the task came from.

    """

    name: str
    description: str = ""
    objects: ObjectChoice = ObjectChoice.RANDOM
    count: int = 1
    targets: TargetSelection = TargetSelection.ALL
    condition: ConditionKind = ConditionKind.NONE
    sides: bool = False
    yaw_range_rad: tuple[float, float] = (-math.pi, math.pi)
    min_spacing_m: float = 0.12
    workspace_x_m: tuple[float, float] | None = None
    workspace_y_m: tuple[float, float] | None = None
    brightness: float = 1.0
    distractors: tuple[str, ...] = ()
    source: str = "<code>"

    def __post_init__(self) -> None:
        if not (isinstance(self.name, str) and 0 < len(self.name) <= MAX_NAME_CHARS
                and self.name.isprintable()):
            raise InvalidInputError(f"task file {self.source}: name", _brief(self.name),
                                    f"1-{MAX_NAME_CHARS} printable characters")
        where = f"task {self.name!r} ({self.source})"

        def bad(field: str, value: Any, allowed: str) -> InvalidInputError:
            return InvalidInputError(f"{where}: {field}", _brief(value), allowed)

        if len(self.description) > MAX_DESCRIPTION_CHARS:
            raise bad("description", self.description,
                      f"at most {MAX_DESCRIPTION_CHARS} characters")
        if not 1 <= self.count <= MAX_OBJECTS:
            raise bad("objects.count", self.count, f"an integer in [1, {MAX_OBJECTS}] (the most "
                      "objects a scene presents, distractors included)")
        if self.count + len(self.distractors) > MAX_OBJECTS:
            raise bad("distractors.types", list(self.distractors),
                      f"at most {MAX_OBJECTS - self.count} types (objects.count + distractors "
                      f"<= {MAX_OBJECTS})")
        if self.targets is TargetSelection.CONDITION and self.condition is ConditionKind.NONE:
            raise bad("condition.kind", "none", "object_type or side when targets.select = "
                      "'condition' (the condition must name the target)")
        if self.targets is TargetSelection.ALL and self.condition is not ConditionKind.NONE:
            raise bad("targets.select", "all", "'condition' when condition.kind is "
                      f"{self.condition.value!r}")
        one_of_each = self.objects is ObjectChoice.ONE_OF_EACH
        if self.condition is ConditionKind.OBJECT_TYPE and not one_of_each:
            raise bad("objects.choose", self.objects.value, "'one_of_each' with condition.kind = "
                      "'object_type' (the type must name exactly one object)")
        if self.condition is ConditionKind.SIDE and not (self.sides and self.count == 2):
            raise bad("placement.sides", self.sides, "true, with objects.count = 2, when "
                      "condition.kind = 'side' (one object on each side)")
        if self.sides and self.count != 2:
            raise bad("objects.count", self.count, "2 when placement.sides = true")
        low, high = (math.degrees(a) for a in self.yaw_range_rad)
        if not (_finite(low, high) and -MAX_YAW_DEG <= low < high <= MAX_YAW_DEG):
            raise bad("placement.yaw_deg", [low, high],
                      "[low, high] with -360 <= low < high <= 360")
        if not (_finite(self.min_spacing_m) and 0.0 <= self.min_spacing_m <= MAX_SPACING_M):
            raise bad("placement.min_spacing_m", self.min_spacing_m,
                      f"a distance in [0, {MAX_SPACING_M}] m")
        for field, value in (("x_m", self.workspace_x_m), ("y_m", self.workspace_y_m)):
            if value is not None and not (_finite(*value) and -MAX_PLACEMENT_ABS_M <= value[0]
                                          < value[1] <= MAX_PLACEMENT_ABS_M):
                raise bad(f"placement.{field}", list(value), "[low, high] in metres with "
                          f"-{MAX_PLACEMENT_ABS_M:g} <= low < high <= {MAX_PLACEMENT_ABS_M:g}")
        if not (_finite(self.brightness) and 0.0 < self.brightness <= MAX_BRIGHTNESS):
            raise bad("lighting.brightness", self.brightness,
                      f"a number in (0, {MAX_BRIGHTNESS:g}]")


def _finite(*values: float) -> bool:
    return all(_finite_number(v) for v in values)


def _finite_number(value: Any) -> bool:
    """Whether ``value`` is an int or float (no bool) that a float holds, and not NaN or inf."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an int beyond the float range
        return False


class _Shown:
    """A value too long for a one-line message, shown by the start of its repr and its length."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return f"{self.text[:_SHOWN_CHARS - 20]}... ({len(self.text)} characters)"


def _brief(value: Any) -> Any:
    """``value``, or a shortened stand-in when its repr would not fit a one-line message."""
    try:
        text = repr(value)
    except RecursionError:  # lists nested hundreds deep: tomllib read them, repr cannot
        return _Shown("[" * _SHOWN_CHARS)
    return _Shown(text) if len(text) > _SHOWN_CHARS else value


def _key(key: str) -> str:
    """A TOML key as written: bare if it can be, else quoted (no newline reaches a message)."""
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)


_SECTIONS: dict[str, set[str]] = {
    "": {"name", "description", "objects", "targets", "condition", "placement", "lighting",
         "distractors"},
    "objects": {"choose", "count"},
    "targets": {"select"},
    "condition": {"kind"},
    "placement": {"sides", "yaw_deg", "min_spacing_m", "x_m", "y_m"},
    "lighting": {"brightness"},
    "distractors": {"types"},
}


class _Reader:
    """Typed access to a parsed TOML table, with errors that name the file and the field."""

    def __init__(self, data: dict[str, Any], source: str) -> None:
        self.data, self.source = data, source

    def error(self, field: str, value: Any, allowed: str) -> InvalidInputError:
        return InvalidInputError(f"task file {self.source}: {field}", _brief(value), allowed)

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
        if len(value) != 2 or not all(_finite_number(v) for v in value):
            raise self.error(f"{section}.{key}", value, "a list of two finite numbers [low, high]")
        return float(value[0]), float(value[1])


def task_from_toml(text: str, source: str = "<string>") -> TaskSpec:
    """Reads a task from TOML text; every mistake is an error naming the file and the field."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise InvalidInputError(f"task file {source}", "not valid TOML",
                                f"TOML ({error})") from None
    except RecursionError:  # tomllib recurses per level: ~300 nested arrays exhaust the stack
        raise InvalidInputError(f"task file {source}", "arrays or tables nested too deeply",
                                "TOML nested as a task is (tables of keys, lists of values)"
                                ) from None
    reader = _Reader(data, source)
    reader.check_keys()
    name = reader.get("", "name", str, None)
    if not name:
        raise reader.error("name", name, "a non-empty string")
    yaw = reader.pair("placement", "yaw_deg") or (-180.0, 180.0)
    distractors = reader.get("distractors", "types", list, [])
    if not all(isinstance(t, str) for t in distractors):
        raise reader.error("distractors.types", distractors, "a list of object type names")
    return TaskSpec(
        name=name,
        description=reader.get("", "description", str, ""),
        objects=reader.choice("objects", "choose", ObjectChoice, ObjectChoice.RANDOM),
        count=reader.get("objects", "count", int, 1, f"an integer in [1, {MAX_OBJECTS}]"),
        targets=reader.choice("targets", "select", TargetSelection, TargetSelection.ALL),
        condition=reader.choice("condition", "kind", ConditionKind, ConditionKind.NONE),
        sides=reader.get("placement", "sides", bool, False, "true or false"),
        yaw_range_rad=(math.radians(yaw[0]), math.radians(yaw[1])),
        min_spacing_m=reader.number("placement", "min_spacing_m", 0.12),
        workspace_x_m=reader.pair("placement", "x_m"),
        workspace_y_m=reader.pair("placement", "y_m"),
        brightness=reader.number("lighting", "brightness", 1.0),
        distractors=tuple(distractors),
        source=source,
    )


def task_from_bytes(data: bytes, source: str = "<bytes>") -> TaskSpec:
    """Reads a task from a file's bytes: UTF-8 text (a leading BOM is skipped), then TOML."""
    if len(data) > MAX_TASK_FILE_BYTES:
        raise InvalidInputError(f"task file {source}", f"{len(data)} bytes or more",
                                f"a task file of at most {MAX_TASK_FILE_BYTES} bytes")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise InvalidInputError(f"task file {source}", "not UTF-8 text", "a TOML text file in "
                                f"UTF-8 (byte {error.start} is {data[error.start]:#04x})"
                                ) from None
    return task_from_toml(text, source)


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
        "objects": {"choose": task.objects.value, "count": task.count},
        "targets": {"select": task.targets.value},
        "condition": {"kind": task.condition.value},
        "placement": placement,
        "lighting": {"brightness": task.brightness},
        "distractors": {"types": list(task.distractors)},
    }
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
        return task_from_bytes(data, source)
    if text not in builtin_tasks():
        raise InvalidInputError(
            "task", text, f"one of {', '.join(builtin_tasks())}, or the path of a .toml file"
        )
    return task_from_toml((TASK_FILES / f"{text}.toml").read_text(), f"{text}.toml")
