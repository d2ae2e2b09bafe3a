"""Files of a run folder: JSON and text written atomically, the error file of a job that raised.

:func:`guarded` runs a job and writes the error file of one that raised (the run goes on with
the others); :func:`refuse_other_settings` refuses files made with other settings;
:func:`dataset_present` says whether a run folder holds the dataset a run would collect, and
refuses one that holds another.
"""

from __future__ import annotations

import json
import traceback
from collections.abc import Callable, Iterable, Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, TypeVar

from harness.inputs.collector import (
    APPROACH_HIDDEN_SHARE_MAX,
    APPROACH_MASKED_KEY,
    HIDDEN_SHARE_KEY,
    CollectSettings,
    LabelSource,
    LookSource,
)
from harness.inputs.trial_settings import task_identity
from harness.run_folder import differences, json_form, read_json_file
from perception.files import atomic_write
from perception.learning.dataset_file import read_metadata
from robots import robot_identity
from robots.description import RobotDescription
from sim.errors import RunFolderError
from sim.tasks.scene_sampling import SeedStream
from sim.tasks.scene_specs import scene_camera
from sim.tasks.task_sensor import seen_in_scene
from sim.tasks.task_toml import load_task
from sim.trials.scene_sets.randomised_looks import RandomisedLooks
from sim.world.head_camera import CameraConfig
from sim.world.sensor import SensorKind


def write_json(path: Path, data: Any) -> None:
    """Writes ``data`` as indented JSON, atomically (parents created)."""
    write_text(path, json.dumps(data, indent=2, allow_nan=False) + "\n")


def write_text(path: Path, text: str) -> None:
    """Writes ``text`` atomically (parents created)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda temporary: temporary.write_text(text, encoding="utf-8"))


def read_json(path: Path) -> Any:
    """The JSON in ``path``; a damaged file is a :class:`RunFolderError` naming it."""
    return read_json_file(path, "remove it to compute it again")


Result = TypeVar("Result")


@dataclass(frozen=True)
class Failed:
    """A job that raised: ``message`` is ``"Type: message"``, as its error file says."""

    message: str


def guarded(work: Callable[[], Result], error_path: Path, record: Mapping[str, Any],
            extra: Mapping[str, Any] | None = None) -> Result | Failed:
    """Runs ``work``: its result, or :class:`Failed` with the exception written to a file.

    The error file ``error_path`` holds ``record``, then ``error`` and ``traceback``, then
    ``extra``; the run goes on with the other jobs. When ``work`` succeeds, the error file an
    earlier try left is removed.
    """
    try:
        result = work()
    except Exception as error:  # one job's failure is recorded; the others go on
        message = f"{type(error).__name__}: {error}"
        write_json(error_path, {**record, "error": message,
                                "traceback": traceback.format_exc(), **(extra or {})})
        return Failed(message)
    error_path.unlink(missing_ok=True)
    return result


def refuse_other_settings(identities: Iterable[tuple[str, Any, Any]], what: str) -> None:
    """Raises unless every file was made with the settings asked now.

    Args:
        identities: Per file: its name as shown, the identity it stores, the identity asked.
        what: What the files are, e.g. ``"checkpoint(s)"``.

    Raises:
        RunFolderError: Some differ; the message lists them and what differs.

    """
    stale = [f"{name} ({differences(stored, asked)})" for name, stored, asked in identities
             if stored != asked]
    if stale:
        raise RunFolderError(
            f"{len(stale)} {what} made with other settings, stored vs now: "
            f"{'; '.join(stale[:3])}{' ...' if len(stale) > 3 else ''}; remove them to "
            "compute them again with the current code, or use another --out")


def dataset_path(out: Path, task: str, stream: SeedStream, size: int, seed: int) -> Path:
    """Where a training (TRAIN) or test (TEST) dataset of a run folder lives."""
    return out / "datasets" / f"{task}-{stream.name.lower()}-{size}-s{seed}.gva"


def dataset_present(path: Path, scene: str, task: str, size: int, seed: int,
                    stream: SeedStream, approach_hz: float | None = None, *,
                    robot: RobotDescription, sensor: SensorKind | None = None,
                    labels: LabelSource = LabelSource.PICKED,
                    looks: LookSource = LookSource.TASK) -> bool:
    """Whether ``path`` holds the dataset asked for; refuses a file that holds another.

    ``task`` is a built-in task's name or a task file's path. Compared: scene, task name,
    size (in scenes: a yumi demonstration has an image per pick, a training scene of a task
    with a condition a sample per condition value), seed, seed stream, whether each scene is
    asked every condition
    (:class:`harness.inputs.collector.CollectSettings` ``every_condition``, at its default for the
    stream), the task's definition (a task whose TOML changed since is another dataset), the
    scene's camera (other images; in the yumi scene, ``robot``'s: the robot that collects,
    resolved where the run starts), the robot where it is not the YuMi, and the approach
    images' rate (``approach_hz``, if any), whether the arm is masked out of them (datasets
    from before the mask have it in view: another dataset) and how much of a target it may hide
    in one (``APPROACH_HIDDEN_SHARE_MAX``; a dataset that records none is issue 36's: 0).
    ``sensor``: the yumi scene's ``--sensor`` (None: the task file's), part of the definition.
    ``labels`` and ``looks``: what the set is (:class:`~harness.inputs.collector.CollectSettings`'
    own; by default demonstrations in the task's looks): a set labelled otherwise or in other
    looks (``extra["labels"]``, ``extra["looks"]``, the randomised draw included) is another
    dataset, so a run's demonstrations are never taken for its randomised scenes nor back.

    Raises:
        RunFolderError: ``path`` holds another dataset; the message names what differs.

    """
    if not path.exists():
        return False
    meta = read_metadata(path)
    wanted = CollectSettings(scene, task, size, seed, stream, labels=labels, looks=looks)
    definition = seen_in_scene(load_task(task), scene, sensor)  # as collect sees it
    if looks is LookSource.RANDOMISED:
        definition = RandomisedLooks().with_look_alikes(definition)
    asked = json_form({"scene": scene, "task": definition.name, "size": size, "seed": seed,
                       "stream": stream.name.lower(),
                       "every_condition": wanted.asks_every_condition,
                       "definition": task_identity(definition),
                       "camera": asdict(scene_camera(scene, robot))}
                      | ({} if approach_hz is None else {
                          "approach_hz": approach_hz, APPROACH_MASKED_KEY: True,
                          HIDDEN_SHARE_KEY: APPROACH_HIDDEN_SHARE_MAX})
                      | robot_identity(robot.name) | wanted.recorded())
    scenes = meta.extra.get("scenes", meta.size)  # a scene may give several samples
    found = {"scene": meta.scene, "task": meta.task, "size": scenes, "seed": meta.seed,
             "stream": meta.extra.get("stream"),
             "every_condition": meta.extra.get("every_condition", False),
             "definition": meta.extra.get("task"),
             "camera": json_form(asdict(CameraConfig.from_json(meta.camera)))} | (
                 {} if "approach_hz" not in meta.extra else
                 {"approach_hz": meta.extra["approach_hz"],
                  APPROACH_MASKED_KEY: meta.extra.get(APPROACH_MASKED_KEY, False),
                  HIDDEN_SHARE_KEY: meta.extra.get(HIDDEN_SHARE_KEY, 0.0)}) | (
                 {} if "robot" not in meta.extra else {"robot": meta.extra["robot"]}) | {
                 key: meta.extra[key] for key in ("labels", "looks") if key in meta.extra}
    if found != asked:
        raise RunFolderError(f"{path} is not the dataset this run needs "
                             f"({differences(found, asked)}, stored vs asked); remove it to "
                             "collect it again")
    return True

