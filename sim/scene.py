"""Scenes drawn from a task and a seed: object types and poses, the targets, the condition.

Training and test scenes come from disjoint seed streams, so a trial never runs on a scene a
model was trained on: scene ``index`` of stream ``stream`` under seed ``seed`` is drawn from
``SeedSequence([seed, stream, index])``.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from perception.interface import NO_CONDITION, Condition
from sim.errors import InvalidInputError
from sim.tasks import TaskSpec


class SeedStream(enum.IntEnum):
    """Disjoint streams of scenes under one seed."""

    TRAIN = 0
    TEST = 1


@dataclass(frozen=True)
class PlacedObject:
    """One object of a scene: its type and its pose on the table."""

    object_type: str
    position_xy_m: tuple[float, float]
    yaw_rad: float


@dataclass(frozen=True)
class Scene:
    """A scene of a task: what lies where, and what the robot is asked to pick.

    Args:
        task: The task's name.
        seed, stream, index: Where in the seed streams this scene was drawn.
        objects: The presented objects.
        targets: Indices into ``objects``, in the order they are to be picked.
        condition: The top-down condition the model is given.

    """

    task: str
    seed: int
    stream: SeedStream
    index: int
    objects: tuple[PlacedObject, ...]
    targets: tuple[int, ...]
    condition: Condition = NO_CONDITION


def scene_rng(seed: int, stream: SeedStream, index: int) -> np.random.Generator:
    """The generator scene ``index`` of ``stream`` under ``seed`` is drawn from."""
    if seed < 0 or index < 0:
        raise InvalidInputError("seed/index", (seed, index), "non-negative integers")
    return np.random.default_rng(np.random.SeedSequence([seed, int(stream), index]))


def sample_scene(
    task: TaskSpec, seed: int, stream: SeedStream, index: int, max_draws: int = 1000
) -> Scene:
    """Draws a scene: types, then positions spaced at least ``task.min_spacing_m`` apart."""
    rng = scene_rng(seed, stream, index)
    types = [str(t) for t in rng.choice(task.object_types, size=task.objects_presented)]
    positions: list[tuple[float, float]] = []
    for _ in range(max_draws):
        if len(positions) == len(types):
            break
        candidate = (float(rng.uniform(*task.workspace_x_m)),
                     float(rng.uniform(*task.workspace_y_m)))
        if all(np.hypot(candidate[0] - x, candidate[1] - y) >= task.min_spacing_m
               for x, y in positions):
            positions.append(candidate)
    if len(positions) < len(types):
        raise InvalidInputError(
            f"task {task.name!r}", f"{len(types)} objects {task.min_spacing_m} m apart",
            "a workspace large enough to place them (widen it or lower min_spacing_m)",
        )
    objects = tuple(
        PlacedObject(t, p, float(rng.uniform(*task.yaw_range_rad)))
        for t, p in zip(types, positions, strict=True)
    )
    return Scene(task.name, seed, stream, index, objects, targets=tuple(range(len(objects))))
