"""Which sensor a task is seen through: ``--sensor``, else its file's, else the command's default.

One rule for every command that renders (``gva collect``, ``gva trials``, ``gva show scene``,
the Gymnasium env; ``gva reproduce real`` writes its choice into each task file it runs):

1. ``--sensor`` (a :class:`~sim.world.sensor.SensorKind`) replaces the task's camera, as
   ``gva reproduce real --sensor`` does;
2. else the task file's ``[camera] sensor``;
3. else a fallback the command knows: a checkpoint's trials, the sensor its datasets were
   rendered by (:func:`sim.trials.model_fit.trained_sensor`), so a model is tried in the
   world it was trained in;
4. else :data:`~sim.world.sensor.DEFAULT_SENSOR`, the D435.

The ``paper-sim`` scene (Table II) renders through its own camera, an ideal pinhole: it takes
no ``--sensor``, and a task file that names none records the ideal camera there, so its
datasets and cells keep the identity they had before the default was the D435.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from sim.errors import InvalidInputError
from sim.tasks.task_spec import TaskSpec
from sim.world.sensor import SensorConfig, SensorKind, sensor_kind

PAPER_SCENE = "paper-sim"


def as_sensor_kind(value: Any) -> SensorKind | None:
    """``value`` (None, a :class:`SensorKind` or its name, e.g. ``"d435"``) as a sensor kind.

    Raises:
        InvalidInputError: Anything else, naming the kinds allowed.

    """
    if value is None:
        return None
    try:
        return sensor_kind(value)
    except InvalidInputError as error:  # None is allowed here too
        raise InvalidInputError(error.field, error.value, f"None or {error.allowed}") from None


def seen_through(task: TaskSpec, sensor: SensorKind | str | None = None,
                 fallback: SensorConfig | None = None) -> TaskSpec:
    """``task`` with the sensor it renders through named: ``sensor``, its own, ``fallback``.

    Args:
        task: The task as read from its file (``camera`` None where the file names none).
        sensor: ``--sensor`` (a kind or its name): replaces the task's camera (the D435 at its
            defaults, or the ideal camera); None: the task's own.
        fallback: The sensor where neither names one; None: the D435 (``DEFAULT_SENSOR``).

    """
    kind = as_sensor_kind(sensor)
    if kind is not None:
        return replace(task, camera=SensorConfig(kind))
    if task.camera is not None:
        return task
    return replace(task, camera=task.sensor if fallback is None else fallback)


def seen_in_scene(task: TaskSpec, scene: str,
                  sensor: SensorKind | str | None = None) -> TaskSpec:
    """``task`` with the sensor ``scene`` renders it through named.

    In ``yumi``, :func:`seen_through`; in ``paper-sim``, the scene's own camera, the ideal
    pinhole, where the file names none, and no ``--sensor``.

    Raises:
        InvalidInputError: ``sensor`` is given for the paper-sim scene.

    """
    if scene != PAPER_SCENE:
        return seen_through(task, sensor)
    if sensor is not None:
        raise InvalidInputError("sensor", getattr(sensor, "value", sensor), "none for the "
                                "paper-sim scene: it renders through its own camera, an ideal "
                                "pinhole (--sensor is for the yumi scene)")
    return seen_through(task, None, SensorConfig())


__all__ = ["as_sensor_kind", "seen_in_scene", "seen_through"]
