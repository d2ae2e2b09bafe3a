"""Pieces shared by the resumable experiments (``gva reproduce sim`` and ``gva reproduce real``).

- :func:`check_choices`: a comma-separated option checked against the allowed values;
- :func:`check_counts`: integer settings and the worker count;
- :func:`dataset_present`: whether a run folder already holds the dataset a run needs (and a
  refusal when it holds another);
- :func:`cost_bar`: the one progress bar of a run, measured in the jobs' estimated cost, so its
  time left stays honest while long jobs run;
- :func:`duration`: ``3 min 07 s`` for reports.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tqdm import tqdm

from perception.files import atomic_write
from sim.errors import InvalidInputError
from sim.records import RunFolderError, differences, json_form

if TYPE_CHECKING:  # sim.scene imports pinocchio: not for `gva --help`
    from sim.scene import SeedStream


def check_choices(name: str, values: Sequence[Any], allowed: Sequence[Any]) -> None:
    """Raises unless ``values`` is a non-empty list of distinct members of ``allowed``."""
    shown = ", ".join(str(a) for a in allowed)
    unknown = [v for v in values if v not in allowed]
    if not values or unknown or len(set(values)) != len(values):
        value = ",".join(str(v) for v in (unknown or values))
        raise InvalidInputError(name, value, f"distinct comma-separated values from {shown}")


def check_counts(settings: object, least: dict[str, int], workers: int | None) -> None:
    """Raises unless ``settings``' fields named in ``least`` are integers at least that large.

    ``workers`` must be None or an integer >= 1.
    """
    for name, minimum in least.items():
        value = getattr(settings, name)
        if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
            raise InvalidInputError(name, value, f"an integer >= {minimum}")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise InvalidInputError("workers", workers, "None or an integer >= 1")


def dataset_present(path: Path, scene: str, task: str, size: int, seed: int,
                    stream: SeedStream) -> bool:
    """Whether ``path`` holds the dataset asked for; refuses a file that holds another.

    Compared: scene, task name, size (in scenes: a yumi demonstration has an image per pick,
    a training scene of a task with a condition a sample per condition value), seed, seed
    stream, whether each scene is asked every condition (:class:`sim.collect.CollectSettings`
    ``every_condition``, at its default for the stream), the task's definition (a task whose
    TOML changed since is another dataset) and the scene's camera (other images).

    Raises:
        RunFolderError: ``path`` holds another dataset; the message names what differs.

    """
    if not path.exists():
        return False
    from perception.dataset_file import read_metadata
    from sim.camera import CameraConfig
    from sim.collect import CollectSettings
    from sim.scenes import scene_camera
    from sim.tasks import load_task
    from sim.trials import task_identity

    meta = read_metadata(path)
    asked = json_form({"scene": scene, "task": task, "size": size, "seed": seed,
                       "stream": stream.name.lower(),
                       "every_condition": CollectSettings(scene, task, size, seed,
                                                          stream).asks_every_condition,
                       "definition": task_identity(load_task(task)),
                       "camera": asdict(scene_camera(scene))})
    scenes = meta.extra.get("scenes", meta.size)  # a scene may give several samples
    found = {"scene": meta.scene, "task": meta.task, "size": scenes, "seed": meta.seed,
             "stream": meta.extra.get("stream"),
             "every_condition": meta.extra.get("every_condition", False),
             "definition": meta.extra.get("task"),
             "camera": json_form(asdict(CameraConfig.from_json(meta.camera)))}
    if found != asked:
        raise RunFolderError(f"{path} is not the dataset this run needs "
                             f"({differences(found, asked)}, stored vs asked); remove it to "
                             "collect it again")
    return True


def cost_bar(total: float, description: str, progress: bool) -> tqdm:
    """A bar over ``total`` estimated cost: percent done, elapsed, time left and a postfix."""
    return tqdm(total=total, disable=not progress or total <= 0, desc=description,
                file=sys.stderr,
                bar_format="{desc}: {percentage:3.0f}%|{bar}| [{elapsed}<{remaining}{postfix}]")


def duration(seconds: float) -> str:
    """``1 h 02 min`` or ``3 min 07 s``."""
    minutes, second = divmod(round(seconds), 60)
    hours, minute = divmod(minutes, 60)
    return f"{hours} h {minute:02d} min" if hours else f"{minute} min {second:02d} s"


def write_json(path: Path, data: Any) -> None:
    """Writes ``data`` as indented JSON, atomically (parents created)."""
    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda temporary: temporary.write_text(text, encoding="utf-8"))


def read_json(path: Path) -> Any:
    """The JSON in ``path``; a damaged file is a :class:`RunFolderError` naming it."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as error:
        raise RunFolderError(f"{path} is damaged ({error}); remove it to compute it again"
                             ) from None
