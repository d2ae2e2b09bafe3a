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
"""

from __future__ import annotations

import enum
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from perception.interface import ConditionKind
from sim.errors import InvalidInputError

TASK_FILES = Path(__file__).resolve().parent / "task_files"
SIDES = ("left", "right")
"""Side condition values: ``left`` is +y (the robot's left, the image's left)."""


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
        where = f"task {self.name!r} ({self.source})"

        def bad(field: str, value: Any, allowed: str) -> InvalidInputError:
            return InvalidInputError(f"{where}: {field}", value, allowed)

        if self.count < 1:
            raise bad("objects.count", self.count, "an integer >= 1")
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
        low, high = self.yaw_range_rad
        if not (-2 * math.pi <= low < high <= 2 * math.pi):
            raise bad("placement.yaw_deg", [math.degrees(low), math.degrees(high)],
                      "[low, high] with -360 <= low < high <= 360")
        if self.min_spacing_m < 0.0:
            raise bad("placement.min_spacing_m", self.min_spacing_m, "a distance >= 0 m")
        for field, value in (("x_m", self.workspace_x_m), ("y_m", self.workspace_y_m)):
            if value is not None and not value[0] < value[1]:
                raise bad(f"placement.{field}", list(value), "[low, high] with low < high")
        if not 0.0 < self.brightness <= 2.0:
            raise bad("lighting.brightness", self.brightness, "a number in (0, 2]")


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
        return InvalidInputError(f"task file {self.source}: {field}", value, allowed)

    def check_keys(self) -> None:
        for section, allowed in _SECTIONS.items():
            table = self.data if not section else self.data.get(section, {})
            if not isinstance(table, dict):
                raise self.error(section, table, "a [table]")
            for key in table:
                if key not in allowed:
                    prefix = f"{section}." if section else ""
                    names = ", ".join(sorted(allowed))
                    raise self.error(f"{prefix}{key}", table[key], f"a known key: {names}")

    def get(self, section: str, key: str, kind: type | tuple[type, ...], default: Any) -> Any:
        table = self.data if not section else self.data.get(section, {})
        value = table.get(key, default)
        field = f"{section}.{key}" if section else key
        wrong_type = not isinstance(value, kind) or (isinstance(value, bool) and kind is not bool)
        if value is not default and wrong_type:
            kinds = (kind,) if isinstance(kind, type) else kind
            raise self.error(field, value, f"a {' or '.join(k.__name__ for k in kinds)}")
        return value

    def choice(self, section: str, key: str, enum_type: type[enum.Enum], default: enum.Enum) -> Any:
        value = self.get(section, key, str, default.value)
        try:
            return enum_type(value)
        except ValueError:
            allowed = ", ".join(repr(e.value) for e in enum_type)
            raise self.error(f"{section}.{key}", value, f"one of {allowed}") from None

    def pair(self, section: str, key: str) -> tuple[float, float] | None:
        value = self.get(section, key, list, None)
        if value is None:
            return None
        if len(value) != 2 or not all(isinstance(v, int | float) and not isinstance(v, bool)
                                      for v in value):
            raise self.error(f"{section}.{key}", value, "a list of two numbers [low, high]")
        return float(value[0]), float(value[1])


def task_from_toml(text: str, source: str = "<string>") -> TaskSpec:
    """Reads a task from TOML text; every mistake is an error naming the field."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise InvalidInputError(f"task file {source}", "not valid TOML",
                                f"TOML ({error})") from None
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
        count=reader.get("objects", "count", int, 1),
        targets=reader.choice("targets", "select", TargetSelection, TargetSelection.ALL),
        condition=reader.choice("condition", "kind", ConditionKind, ConditionKind.NONE),
        sides=reader.get("placement", "sides", bool, False),
        yaw_range_rad=(math.radians(yaw[0]), math.radians(yaw[1])),
        min_spacing_m=float(reader.get("placement", "min_spacing_m", (int, float), 0.12)),
        workspace_x_m=reader.pair("placement", "x_m"),
        workspace_y_m=reader.pair("placement", "y_m"),
        brightness=float(reader.get("lighting", "brightness", (int, float), 1.0)),
        distractors=tuple(distractors),
        source=source,
    )


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
        return task_from_toml(path.read_text(), path.name)
    if text not in builtin_tasks():
        raise InvalidInputError(
            "task", text, f"one of {', '.join(builtin_tasks())}, or the path of a .toml file"
        )
    return task_from_toml((TASK_FILES / f"{text}.toml").read_text(), f"{text}.toml")
