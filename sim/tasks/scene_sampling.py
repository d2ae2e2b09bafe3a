"""Scenes drawn from a task, a scene spec and a seed: objects, poses, targets, the condition.

Training and test scenes come from disjoint seed streams, so a trial never runs on a scene a
model was trained on: scene ``index`` of stream ``stream`` under seed ``seed`` is drawn from
``SeedSequence([seed, stream, index])``. A task's distractors are drawn after the scene, from
``SeedSequence([seed, stream, index, 1])``: a task with distractors presents the same scene
as the task without them (same objects, poses, targets and condition), plus the distractors.
A task with ``distractors.per_scene`` draws which of its distractors a scene presents from that
same stream, before placing them. A scene's look (:mod:`sim.tasks.appearance`) comes last, from
``SeedSequence([seed, stream, index, 3])``: a task that varies its looks presents the same
scene as the task that does not (a randomised look, which replaces it, from stream 4).

Placement is rejection sampling, bounded: a task that cannot fit is refused before sampling by
:func:`~sim.tasks.task_in_scene.check_task_fits` (an area bound, Groemer's packing inequality),
and one that the bound lets through but random placement cannot fill fails after
:data:`MAX_PLACEMENT_CANDIDATES` drawn positions, with an error that names the count, the
spacing and the region.
"""

from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass
from typing import Any

import numpy as np

from perception.interface import NO_CONDITION, Condition, ConditionKind
from sim.errors import InvalidInputError
from sim.tasks.queries import query_for
from sim.tasks.scene_specs import SceneSpec
from sim.tasks.task_in_scene import check_task_fits, describe_region, placement_region
from sim.tasks.task_spec import SIDES, ObjectChoice, TargetSelection, TaskSpec
from sim.world.lighting import Lighting
from sim.world.looks import SceneLook

MAX_PLACEMENT_TRIES = 200
"""Positions drawn for one object before the scene's placement starts over; also the restarts."""
MAX_PLACEMENT_CANDIDATES = 20_000
"""Positions drawn for one scene's objects before sampling gives up (a fraction of a second).
The built-in tasks draw at most 214 (1,800 scenes of each task in each scene): none nears it."""
DISTRACTOR_STREAM = 1
"""The distractors' own seed stream, beside the scene's (see the module docstring)."""
BALANCE_STREAM = 2
"""The seed stream of a balanced task's shuffled type blocks (``TaskSpec.balance_types``)."""
APPEARANCE_STREAM = 3
"""The seed stream of a scene's look (colours, textures, table, light, camera mount)."""
RANDOMISED_LOOK_STREAM = 4
"""The seed stream of a randomised look (:mod:`sim.trials.scene_sets.randomised_looks`), which
replaces the task's: its own, so the task's looks are never drawn again under another name."""


class SeedStream(enum.IntEnum):
    """Disjoint streams of scenes under one seed."""

    TRAIN = 0
    TEST = 1


@dataclass(frozen=True)
class PlacedObject:
    """One object of a scene: its type, its pose on the table, and whether it is a distractor."""

    object_type: str
    position_xy_m: tuple[float, float]
    yaw_rad: float
    distractor: bool = False


@dataclass(frozen=True)
class Scene:
    """A drawn scene: what lies where, and what the model is asked for.

    Args:
        task: The task's name.
        scene: The scene's name (``paper-sim`` or ``yumi``).
        seed, stream, index: Where in the seed streams this scene was drawn.
        objects: The presented objects, distractors last.
        targets: Indices into ``objects``, in target order.
        condition: The top-down condition: what it names, which the referee judges by.
        query: What the model is given for it where that differs (a sentence, a picture:
            :mod:`sim.tasks.queries`); None: the condition itself (one-hot tasks).
        look: What the scene looks like (:class:`~sim.world.looks.SceneLook`, one look per
            object); None: today's world.

    """

    task: str
    scene: str
    seed: int
    stream: SeedStream
    index: int
    objects: tuple[PlacedObject, ...]
    targets: tuple[int, ...]
    condition: Condition = NO_CONDITION
    query: Condition | None = None
    look: SceneLook | None = None

    @property
    def given(self) -> Condition:
        """The condition as the model is given it: the query, else the condition itself."""
        return self.condition if self.query is None else self.query

    def to_record(self) -> dict[str, Any]:
        """The scene as JSON-able data (datasets and trial records keep it)."""
        return {
            "task": self.task, "scene": self.scene, "seed": self.seed,
            "stream": self.stream.name.lower(), "index": self.index,
            "objects": [{"type": o.object_type, "position_xy_m": [round(v, 6) for v in
                                                                  o.position_xy_m],
                         "yaw_rad": round(o.yaw_rad, 6), "distractor": o.distractor}
                        for o in self.objects],
            "targets": list(self.targets),
            "condition": {"kind": self.condition.kind.value, "value": self.condition.value},
        } | ({} if self.query is None else {
            "query": {"kind": self.query.kind.value, "value": self.query.value}}) | (
            {} if self.look is None or not self.look.to_json() else {"look": self.look.to_json()})

    def asking(self, value: str, task: TaskSpec) -> Scene:
        """The same scene, objects and poses, asked for condition ``value`` and its target.

        A collector shows one image under every condition of its task this way (each with the
        target that condition names), so every Query learns from every scene.

        Raises:
            InvalidInputError: The scene has no condition, or ``value`` is not one of its
                choices.

        """
        if value not in self.askable():
            raise InvalidInputError("condition value", value,
                                    f"one of {list(self.askable())}" if self.askable()
                                    else "nothing: the scene's task has no condition")
        asked = Condition(self.condition.kind, value, self.condition.choices)
        target = _target_of(self.objects, asked)
        assert target is not None  # askable() holds only values with a target
        query = query_for(task, self.scene, asked, self.seed, self.stream, self.index)
        return dataclasses.replace(self, condition=asked, targets=(target,), query=query)

    def askable(self) -> tuple[str, ...]:
        """The condition values this scene has a target for, in one-hot order (() for none)."""
        kind, choices = self.condition.kind, self.condition.choices
        return tuple(value for value in choices
                     if _target_of(self.objects, Condition(kind, value, choices)) is not None)


def scene_rng(seed: int, stream: SeedStream, index: int) -> np.random.Generator:
    """The generator scene ``index`` of ``stream`` under ``seed`` is drawn from."""
    if seed < 0 or index < 0:
        raise InvalidInputError("seed/index", (seed, index), "non-negative integers")
    return np.random.default_rng(np.random.SeedSequence([seed, int(stream), index]))


def sample_scene(
    task: TaskSpec, spec: SceneSpec, seed: int, stream: SeedStream, index: int
) -> Scene:
    """Draws scene ``index`` of ``stream``: types, then spaced positions, yaws, the condition."""
    check_task_fits(task, spec)
    rng = scene_rng(seed, stream, index)
    if task.objects is ObjectChoice.ONE_OF_EACH:
        types = list(spec.object_types)
    elif task.objects is ObjectChoice.SAME_TYPE:
        types = [str(rng.choice(spec.object_types))] * task.count
    else:
        types = [str(t) for t in rng.choice(spec.object_types, size=task.count)]
    if task.balance_types and stream is SeedStream.TRAIN and task.draws_one_type:
        types = [balanced_type(spec, seed, index)] * len(types)  # drawn above: the rest as before
    positions = _place(task, spec, len(types), rng)
    objects = tuple(PlacedObject(t, p, float(rng.uniform(*task.yaw_range_rad)))
                    for t, p in zip(types, positions, strict=True))
    condition, targets = _targets(task, spec, objects, rng)
    if task.balance_types and stream is SeedStream.TRAIN and not task.draws_one_type:
        condition = Condition(ConditionKind.OBJECT_TYPE, balanced_type(spec, seed, index),
                              spec.object_types)  # the named type in turn; drawn above alike
        named = _target_of(objects, condition)
        assert named is not None  # one object of each type
        targets = (named,)
    if task.distractors:
        distractor_rng = np.random.default_rng(np.random.SeedSequence(
            [seed, int(stream), index, DISTRACTOR_STREAM]))
        objects += _place_distractors(task, spec, objects, _draw_distractors(task, distractor_rng),
                                      distractor_rng)
    look = None
    if task.appearance.draws_anything(tuple(o.object_type for o in objects)):
        look = task.appearance.draw(
            tuple(o.object_type for o in objects), tuple(o.distractor for o in objects), targets,
            stream is SeedStream.TEST, Lighting(), np.random.default_rng(
                np.random.SeedSequence([seed, int(stream), index, APPEARANCE_STREAM])))
    return Scene(task.name, spec.name, seed, stream, index, objects, targets, condition,
                 query_for(task, spec.name, condition, seed, stream, index), look)


def balanced_type(spec: SceneSpec, seed: int, index: int) -> str:
    """The type of training scene ``index`` of a balanced task (``TaskSpec.balance_types``).

    Block ``index // k`` of ``k`` scenes is a seeded shuffle of the scene's ``k`` types.
    """
    count = len(spec.object_types)
    block = np.random.default_rng(np.random.SeedSequence(
        [seed, int(SeedStream.TRAIN), index // count, BALANCE_STREAM])).permutation(count)
    return spec.object_types[int(block[index % count])]


def _draw_distractors(task: TaskSpec, rng: np.random.Generator) -> tuple[str, ...]:
    """The distractor types a scene presents: all of them, or ``per_scene`` draws of them.

    With ``distractors.per_scene = [low, high]``: a count uniform in [low, high], then that many
    distinct types in a random order. Without it nothing is drawn, so ``rng`` is left as before.
    """
    if task.distractors_per_scene is None:
        return task.distractors
    low, high = task.distractors_per_scene
    count = int(rng.integers(low, high + 1))
    return tuple(task.distractors[int(i)] for i in rng.permutation(len(task.distractors))[:count])


def _place_distractors(task: TaskSpec, spec: SceneSpec, objects: tuple[PlacedObject, ...],
                       types: tuple[str, ...], rng: np.random.Generator
                       ) -> tuple[PlacedObject, ...]:
    """The distractors ``types``, ``min_spacing_m`` from every object placed before them.

    Each goes in the workspace where it has room, else in a band ``min_spacing_m / 2`` wide
    around it (three objects can leave the workspace no room for a fourth).
    """
    (x_low, x_high), (y_low, y_high) = placement_region(task, spec)
    placed = [o.position_xy_m for o in objects]
    added: list[PlacedObject] = []
    for object_type in types:
        for grow in (0.0, task.min_spacing_m / 2):
            for _ in range(MAX_PLACEMENT_TRIES):
                candidate = (float(rng.uniform(x_low - grow, x_high + grow)),
                             float(rng.uniform(y_low - grow, y_high + grow)))
                if all(np.hypot(candidate[0] - x, candidate[1] - y) >= task.min_spacing_m
                       for x, y in placed):
                    break
            else:
                continue
            break
        else:
            raise InvalidInputError(
                f"task {task.name!r} ({task.source}) in scene {spec.name!r}: distractors.types",
                list(task.distractors), f"distractors that fit {task.min_spacing_m} m from "
                "every object (fewer, or lower placement.min_spacing_m)")
        placed.append(candidate)
        added.append(PlacedObject(object_type, candidate,
                                  float(rng.uniform(*task.yaw_range_rad)), distractor=True))
    return tuple(added)


def _place(
    task: TaskSpec, spec: SceneSpec, count: int, rng: np.random.Generator
) -> list[tuple[float, float]]:
    """``count`` positions ``min_spacing_m`` apart, by rejection sampling.

    Each object gets up to ``MAX_PLACEMENT_TRIES`` draws, else the scene starts over; after
    ``MAX_PLACEMENT_CANDIDATES`` draws in all it gives up with an error naming the packing.
    """
    x_range, (y_low, y_high) = placement_region(task, spec)
    margin = task.min_spacing_m / 2
    drawn = 0
    for _ in range(MAX_PLACEMENT_TRIES):
        placed: list[tuple[float, float]] = []
        for number in range(count):
            y_range = (y_low, y_high)
            if task.sides and number == 0:
                y_range = (spec.centre_y_m + margin, y_high)  # the left (+y) object
            elif task.sides and number == 1:
                y_range = (y_low, spec.centre_y_m - margin)  # the right (-y) object
            for _ in range(MAX_PLACEMENT_TRIES):
                if drawn == MAX_PLACEMENT_CANDIDATES:
                    break
                drawn += 1
                candidate = (float(rng.uniform(*x_range)), float(rng.uniform(*y_range)))
                if all(np.hypot(candidate[0] - x, candidate[1] - y) >= task.min_spacing_m
                       for x, y in placed):
                    placed.append(candidate)
                    break
            else:
                break
            if len(placed) == number:  # this object found no room within the draws left
                break
        if len(placed) == count:
            return placed
        if drawn == MAX_PLACEMENT_CANDIDATES:
            break
    raise InvalidInputError(
        f"task {task.name!r} ({task.source}) in scene {spec.name!r}: objects.count", count,
        f"a count that fits: could not place {count} objects {task.min_spacing_m} m apart in "
        f"the placement region {describe_region(task, spec)} after {drawn} attempts; lower "
        "objects.count or placement.min_spacing_m",
    )


def _targets(
    task: TaskSpec, spec: SceneSpec, objects: tuple[PlacedObject, ...], rng: np.random.Generator
) -> tuple[Condition, tuple[int, ...]]:
    candidates = [i for i, o in enumerate(objects) if not o.distractor]
    if task.targets is TargetSelection.ALL:
        order = sorted(candidates, key=lambda i: (spec.object_types.index(objects[i].object_type),
                                                  objects[i].position_xy_m[1]))
        return NO_CONDITION, tuple(order)
    if task.condition is ConditionKind.OBJECT_TYPE:
        value = str(rng.choice([objects[i].object_type for i in candidates]))
        condition = Condition(ConditionKind.OBJECT_TYPE, value, spec.object_types)
    else:
        condition = Condition(ConditionKind.SIDE, str(rng.choice(SIDES)), SIDES)
    target = _target_of(objects, condition)
    assert target is not None  # a type drawn from the objects', a side of two or more
    return condition, (target,)


def _target_of(objects: tuple[PlacedObject, ...], condition: Condition) -> int | None:
    """The index of the object ``condition`` names (the first of its type, or the side's)."""
    candidates = [i for i, o in enumerate(objects) if not o.distractor]
    if condition.kind is ConditionKind.NONE or not candidates:
        return None
    if condition.kind is ConditionKind.OBJECT_TYPE:
        return next((i for i in candidates if objects[i].object_type == condition.value), None)
    by_y = sorted(candidates, key=lambda i: objects[i].position_xy_m[1])
    return by_y[-1] if condition.value == "left" else by_y[0]
