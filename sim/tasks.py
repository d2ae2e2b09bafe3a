"""Task conditions: which objects are presented, where, and which one is the target.

A task is data. For now the built-in ``single`` task (paper Table I (a)): one object of a
random type at a random untrained position and yaw; the remaining tasks of Table I join it as
TOML files with the datasets issue.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.errors import InvalidInputError
from sim.objects import OBJECT_TYPES


@dataclass(frozen=True)
class TaskSpec:
    """One task condition.

    Args:
        name: The task's name, as the command line takes it.
        object_types: Types the presented objects are drawn from.
        objects_presented: How many objects lie on the table.
        workspace_x_m: Range of object x positions (forward from the robot) [m].
        workspace_y_m: Range of object y positions (to the robot's left) [m].
        yaw_range_rad: Range of object yaw about the vertical [rad].
        min_spacing_m: Smallest distance between object centres [m].

    """

    name: str
    object_types: tuple[str, ...] = OBJECT_TYPES
    objects_presented: int = 1
    workspace_x_m: tuple[float, float] = (0.34, 0.50)
    workspace_y_m: tuple[float, float] = (-0.20, 0.20)
    yaw_range_rad: tuple[float, float] = (-math.pi, math.pi)
    min_spacing_m: float = 0.12

    def __post_init__(self) -> None:
        unknown = [t for t in self.object_types if t not in OBJECT_TYPES]
        if unknown or not self.object_types:
            raise InvalidInputError(
                f"task {self.name!r} object_types", self.object_types,
                f"a non-empty list drawn from {', '.join(OBJECT_TYPES)}",
            )
        if self.objects_presented < 1:
            raise InvalidInputError(f"task {self.name!r} objects_presented",
                                    self.objects_presented, "an integer >= 1")
        for field_name in ("workspace_x_m", "workspace_y_m", "yaw_range_rad"):
            low, high = getattr(self, field_name)
            if not low < high:
                raise InvalidInputError(f"task {self.name!r} {field_name}", (low, high),
                                        "a range (low, high) with low < high")
        if self.min_spacing_m < 0.0:
            raise InvalidInputError(f"task {self.name!r} min_spacing_m", self.min_spacing_m,
                                    "a distance >= 0 m")


BUILTIN_TASKS: dict[str, TaskSpec] = {
    "single": TaskSpec(name="single", objects_presented=1),
}


def get_task(name: str) -> TaskSpec:
    """The built-in task called ``name``; an unknown name lists the allowed ones."""
    try:
        return BUILTIN_TASKS[name]
    except KeyError:
        raise InvalidInputError("task", name, f"one of {', '.join(BUILTIN_TASKS)}") from None
