"""A task read against a scene, before any scene is drawn: what it asks there, and whether it fits.

Functions of a task and a scene spec alone, no seed: the one-hot order of the task's condition
in the scene, how many targets each of its scenes has, the region its objects are placed in,
and :func:`check_task_fits`, which refuses a task the scene cannot present (unknown types,
ranges outside the workspace, more objects than an area bound lets fit: Groemer's packing
inequality, :func:`max_spaced_points`) before :mod:`sim.tasks.scene_sampling` draws anything.
"""

from __future__ import annotations

import math

from perception.interface import ConditionKind
from sim.errors import InvalidInputError
from sim.tasks.appearance_toml import appearance_keys
from sim.tasks.scene_specs import SceneSpec
from sim.tasks.task_spec import MAX_OBJECTS, SIDES, ObjectChoice, TargetSelection, TaskSpec


def condition_choices(task: TaskSpec, spec: SceneSpec) -> tuple[str, ...]:
    """The one-hot order of a task's condition in a scene; () without a condition."""
    if task.condition is ConditionKind.OBJECT_TYPE:
        return spec.object_types
    if task.condition is ConditionKind.SIDE:
        return SIDES
    return ()


def target_count(task: TaskSpec) -> int:
    """q, the targets of each of a task's scenes: every presented object, or the one named."""
    return task.count if task.targets is TargetSelection.ALL else 1


def check_task_fits(task: TaskSpec, spec: SceneSpec) -> None:
    """Raises a clear error if ``task`` cannot be drawn in ``spec``'s scene.

    Besides the types and ranges, it refuses a packing no placement could achieve: more objects
    ``min_spacing_m`` apart than the region's area bound (:func:`max_spaced_points`) allows, or
    sides that leave no room for an object on one side of the centre line.
    """
    where = f"task {task.name!r} ({task.source}) in scene {spec.name!r}"
    if task.objects is ObjectChoice.ONE_OF_EACH and task.count != len(spec.object_types):
        raise InvalidInputError(f"{where}: objects.count", task.count,
                                f"{len(spec.object_types)} (one of each of "
                                f"{', '.join(spec.object_types)})")
    if spec.name != "yumi" and task.appearance.draws_anything(task.distractors):
        keys = appearance_keys(task.appearance) or {
            "distractors.types": [t for t in task.distractors if t == "colour_twin"]}
        field, value = next(iter(keys.items()))
        raise InvalidInputError(f"{where}: {field}", value,
                                "today's looks: the paper-sim scene keeps its URDF objects' "
                                "colours, table and light (appearance varies in the yumi scene)")
    presentable = spec.object_types + spec.distractor_types
    unknown = [t for t in task.distractors if t not in presentable]
    if unknown:
        raise InvalidInputError(f"{where}: distractors.types", unknown,
                                f"types of the scene: {', '.join(presentable)}")
    for field, own, scene_range in (("x_m", task.workspace_x_m, spec.workspace_x_m),
                                    ("y_m", task.workspace_y_m, spec.workspace_y_m)):
        if own is not None and not (scene_range[0] <= own[0] and own[1] <= scene_range[1]):
            raise InvalidInputError(f"{where}: placement.{field}", list(own),
                                    f"a range within the scene's workspace {list(scene_range)}")
    (x_low, x_high), (y_low, y_high) = placement_region(task, spec)
    spacing = task.min_spacing_m
    region = f"the placement region {describe_region(task, spec)}"
    if task.sides:
        centre, margin = spec.centre_y_m, spacing / 2
        if not (y_low < centre - margin and centre + margin < y_high):
            field = "placement.y_m" if task.workspace_y_m is not None else "placement.min_spacing_m"
            value = list(task.workspace_y_m) if task.workspace_y_m is not None else spacing
            raise InvalidInputError(
                f"{where}: {field}", value, f"room for an object on each side of y = {centre} m, "
                f"{margin} m (min_spacing_m / 2) clear of it, within y {y_low} to {y_high} m")
    else:
        most = max_spaced_points(x_high - x_low, y_high - y_low, spacing)
        if task.count > most:
            raise InvalidInputError(
                f"{where}: objects.count", task.count,
                f"a count that can fit: no more than {most} objects {spacing} m apart fit in "
                f"{region}, however placed (an area bound); lower objects.count or "
                "placement.min_spacing_m")
    if task.phrasings is not None:
        task.phrasings.check_targets(condition_choices(task, spec), where)
    most_distractors = task.distractor_count_range[1]
    total = task.count + most_distractors
    most = max_spaced_points(x_high - x_low + spacing, y_high - y_low + spacing, spacing)
    if most_distractors and total > most:
        per_scene = task.distractors_per_scene
        raise InvalidInputError(
            f"{where}: distractors.{'types' if per_scene is None else 'per_scene'}",
            list(task.distractors) if per_scene is None else list(per_scene),
            f"at most {max(most - task.count, 0)} distractors: no more than {most} objects "
            f"{spacing} m apart fit in {region} and the {spacing / 2} m band around it, however "
            "placed (an area bound); fewer distractors, or lower placement.min_spacing_m")


def max_spaced_points(width_m: float, height_m: float, spacing_m: float) -> int:
    """An upper bound on how many points ``spacing_m`` apart fit in a ``width_m x height_m`` box.

    Groemer's inequality (1960): in a convex region of area A and perimeter P, at most
    2 A / (sqrt(3) d^2) + P / (2 d) + 1 points lie at mutual distances >= d. A count above it
    cannot be placed however the placement is tried, so it is refused before sampling. Any
    count fits at spacing 0 (the bound is :data:`~sim.tasks.task_spec.MAX_OBJECTS` then).
    """
    if spacing_m <= 0.0:
        return MAX_OBJECTS
    across, along = width_m / spacing_m, height_m / spacing_m  # inf for a tiny spacing, not 0
    bound = 2.0 / math.sqrt(3.0) * across * along + across + along + 1.0
    return MAX_OBJECTS if not bound < MAX_OBJECTS else math.floor(bound + 1e-9)


def placement_region(task: TaskSpec, spec: SceneSpec
                     ) -> tuple[tuple[float, float], tuple[float, float]]:
    """Where the task's objects are placed: its own ranges, else the scene's workspace [m]."""
    return task.workspace_x_m or spec.workspace_x_m, task.workspace_y_m or spec.workspace_y_m


def describe_region(task: TaskSpec, spec: SceneSpec) -> str:
    """The placement region in words, for errors: its x and y ranges [m]."""
    (x_low, x_high), (y_low, y_high) = placement_region(task, spec)
    return f"x {x_low:.2f} to {x_high:.2f} m, y {y_low:.2f} to {y_high:.2f} m"
