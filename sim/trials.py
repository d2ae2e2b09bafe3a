"""Runs of closed-loop pick trials: settings, the resumable loop, the summary.

Trial ``i`` of a run with seed ``s`` runs test scene ``i`` of seed ``s`` (see
:mod:`sim.scene`), so the same seed gives the same trials, and no trial runs on a scene a model
was trained on. Every finished trial is appended to ``trials.jsonl`` before the next one starts;
running the same command again resumes where an interrupted run stopped.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from perception.files import atomic_write
from perception.interface import PerceptionModel
from sim.camera import HeadCamera
from sim.errors import InvalidInputError
from sim.execution import ExecutionSettings
from sim.oracle import OraclePerception
from sim.records import TrialLog, TrialSummary
from sim.runner import TrialRunner
from sim.scene import SeedStream, check_task_fits, sample_scene
from sim.scenes import YUMI_SCENE
from sim.tasks import TaskSpec, load_task
from sim.world import World

ModelFactory = Callable[[World, HeadCamera], PerceptionModel]

MODELS: dict[str, ModelFactory] = {"oracle": OraclePerception}
"""Perception models the trial runner can build by name."""


def task_identity(task: TaskSpec) -> dict[str, Any]:
    """A task's settings as JSON-able data (a resumed run must use the same task)."""
    data = asdict(task)
    data.pop("source")
    for key, value in data.items():
        if hasattr(value, "value"):
            data[key] = value.value
    return data


@dataclass(frozen=True)
class TrialSettings:
    """What a run of trials does; the fields of ``run.json``.

    Args:
        model: Perception model name (see :data:`MODELS`).
        task: A built-in task name, or the path of a task TOML file.
        n: Number of trials.
        seed: Seed of the test scenes.
        settle_s: Time objects settle on the table before the image is taken [s].
        execution: How picks are executed and judged.

    """

    model: str
    task: str
    n: int = 30
    seed: int = 0
    settle_s: float = 0.25
    execution: ExecutionSettings = field(default_factory=ExecutionSettings)

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise InvalidInputError("model", self.model, f"one of {', '.join(MODELS)}")
        check_task_fits(self.task_spec, YUMI_SCENE)  # also: an unknown task names the allowed
        if self.n < 1:
            raise InvalidInputError("n", self.n, "an integer >= 1")
        if self.seed < 0:
            raise InvalidInputError("seed", self.seed, "an integer >= 0")

    @property
    def task_spec(self) -> TaskSpec:
        """The task, read from its name or file."""
        return load_task(self.task)

    def identity(self) -> dict[str, Any]:
        """What identifies a run: a folder is only resumed by a run with the same identity."""
        return {"model": self.model, "task": task_identity(self.task_spec), "seed": self.seed,
                "scene": YUMI_SCENE.name, "settle_s": self.settle_s,
                "execution": asdict(self.execution)}


def run_trials(
    settings: TrialSettings, out_dir: str | Path, progress: bool = True
) -> TrialSummary:
    """Runs (or resumes) ``settings.n`` trials into ``out_dir``; writes ``summary.json``."""
    out = Path(out_dir)
    log = TrialLog(out, settings.identity())
    todo = [i for i in range(settings.n) if not log.done(i)]
    task = settings.task_spec
    if todo:
        with TrialRunner(task, MODELS[settings.model], settings.settle_s,
                         settings.execution) as runner, tqdm(
            total=settings.n, initial=settings.n - len(todo), disable=not progress,
            desc=f"{settings.model} / {task.name}", unit="trial",
        ) as bar:
            for index in todo:
                scene = sample_scene(task, YUMI_SCENE, settings.seed, SeedStream.TEST, index)
                log.append(runner.run(scene, index, settings.seed, settings.model))
                summary = log.summary(settings.n)
                bar.set_postfix_str(f"{summary.successes}/{summary.n} ok")
                bar.update()
    summary = log.summary(settings.n)
    data = {"settings": settings.identity() | {"n": settings.n}} | summary.to_dict()
    text = json.dumps(data, indent=2, sort_keys=True) + "\n"
    atomic_write(out / "summary.json", lambda temporary: temporary.write_text(text))
    return summary

