"""The jobs of ``gva reproduce real`` (collect, train, try, GIF); :mod:`.job_graph` runs them.

Each job is a small frozen dataclass handed to a function that runs in a worker process
(:mod:`harness.jobs`, or Ray: :mod:`harness.ray_jobs`); it writes its files itself and returns a
:class:`JobOutcome`. A job that raises is recorded in ``OUT/errors/<job>.json`` (message and
traceback) and the run goes on. :func:`trials_done` and :func:`gif_done` find finished work
on disk, so a re-run skips it.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from experiments.table3.gifs import record_gif
from experiments.table3.layout import (
    checkpoint_folder,
    dataset_file,
    error_file,
    gif_file,
    randomised_file,
    task_file,
    trained_file,
    trials_folder,
)
from experiments.table3.settings import SCENE, ReproduceRealSettings, TrialSet, Unit
from experiments.tables import TWO_PHASE_MODELS, model_config_file
from harness.inputs.collector import CollectSettings, collect
from harness.inputs.trial_settings import TrialSettings
from harness.jobs import ONE_CPU, JobResources
from harness.run_files import (
    Failed,
    guarded,
    read_json,
    write_json,
)
from harness.run_folder import json_form
from harness.run_loop import run_trials
from perception.learning.combined import concatenate, training_files
from perception.learning.dataset_file import DatasetError, load_dataset
from perception.learning.train import TrainConfig
from perception.learning.validation import fit_checked, write_check
from perception.models.torch_model import TorchModel
from perception.registry import new_model
from sim.tasks.scene_sampling import SeedStream
from sim.tasks.task_in_scene import target_count
from sim.tasks.task_toml import load_task
from sim.trials.trial_models import torch_threads

# Rough seconds per unit of work on one loaded core, only for the progress bar's time left.
COLLECT_S_PER_PICK = 1.2
RANDOMISED_S_PER_SCENE = 0.1
TRAIN_S_PER_STEP = 0.09
TRIAL_S_PER_PICK = 2.0
GIF_S_PER_PICK = 4.0


@dataclass(frozen=True)
class JobOutcome:
    """A finished job: its name, how long it took, and its failure or a one-line result.

    ``started_at`` (Unix time [s]), ``cpu_s`` (the worker's CPU time over the job, every
    thread), ``worker`` (its process id) and ``cpus`` (the cores it holds: a training its
    threads) place it on the run's timeline, so a profile can tell where the time went and
    how long a core waited (``history.jsonl`` keeps them).
    """

    name: str
    seconds: float
    result: str = ""
    failure: str | None = None
    started_at: float = 0.0
    cpu_s: float = 0.0
    worker: int = 0
    cpus: float = 1.0

    def timeline(self) -> dict[str, Any]:
        """The job on the run's timeline, as ``history.jsonl`` keeps it."""
        return {"name": self.name, "started_at": round(self.started_at, 3),
                "seconds": round(self.seconds, 3), "cpu_s": round(self.cpu_s, 3),
                "worker": self.worker, "cpus": self.cpus, "failed": self.failure is not None}


@dataclass(frozen=True)
class CollectJob:
    """Collect the demonstrations of one task, or (``randomised``) its randomised scenes.

    The randomised scenes (``--randomised-scenes``) are a job of their own, beside the
    demonstrations' collection: catalog labels pick nothing, so they take a fraction of its time.
    """

    name: str  # collect-<task>-s<seed> or collect-randomised-<task>-s<seed>
    task: str
    settings: ReproduceRealSettings
    out: Path
    randomised: bool = False

    @property
    def path(self) -> Path:
        """The dataset it writes."""
        return (randomised_file(self.out, self.task, self.settings.randomised_scenes,
                                self.settings.randomised_seed) if self.randomised
                else dataset_file(self.out, self.task, self.settings))


@dataclass(frozen=True)
class TrainJob:
    """Train one unit's model on its task's demonstrations."""

    name: str  # train-<model>-<task>-s<seed>
    unit: Unit
    settings: ReproduceRealSettings
    identity: dict[str, Any]
    out: Path


@dataclass(frozen=True)
class TrialsJob:
    """Run (or resume) one set of trials."""

    name: str  # trials-<model>-<task>[-<variant>]-s<seed>
    trial_set: TrialSet
    trials: TrialSettings
    out: Path


@dataclass(frozen=True)
class GifJob:
    """Record a unit's first trials again, as a GIF."""

    name: str  # gif-<model>-<task>-s<seed>
    unit: Unit
    trials: TrialSettings
    count: int
    out: Path


Job = CollectJob | TrainJob | TrialsJob | GifJob


def job_resources(job: Job) -> JobResources:
    """What a job holds: a training its torch threads (and a GPU on CUDA), others one core."""
    if isinstance(job, TrainJob):
        train = job.settings.train_config()
        return JobResources.training(train["threads"], train["device"])
    return ONE_CPU


def task_targets(task: str) -> int:
    """How many targets a trial of ``task`` picks (``multiple``: three)."""
    return target_count(load_task(task))


def cost(job: Job) -> float:
    """The job's estimated seconds on one core (for the progress bar)."""
    if isinstance(job, CollectJob) and job.randomised:
        return RANDOMISED_S_PER_SCENE * job.settings.randomised_scenes
    if isinstance(job, CollectJob):
        return COLLECT_S_PER_PICK * job.settings.demos * task_targets(job.task)
    if isinstance(job, TrainJob):
        phases = 1.5 if job.unit.model in TWO_PHASE_MODELS else 1.0
        return TRAIN_S_PER_STEP * job.settings.steps * phases
    if isinstance(job, TrialsJob):
        return TRIAL_S_PER_PICK * job.trials.n * task_targets(job.trial_set.unit.task)
    return GIF_S_PER_PICK * job.count * task_targets(job.unit.task)


def run_job(job: Job) -> JobOutcome:
    """Runs one job in a worker; an exception becomes its error file and a failed outcome."""
    started_at, started, cpu = time.time(), time.perf_counter(), time.process_time()
    result = guarded(lambda: _work(job), error_file(job.out, job.name), {"job": job.name})
    failure = result.message if isinstance(result, Failed) else None
    return JobOutcome(job.name, time.perf_counter() - started,
                      "" if failure is not None else str(result), failure, started_at,
                      time.process_time() - cpu, os.getpid(), job_resources(job).cpus)


def _work(job: Job) -> str:
    """Does one job; a line that says what it gave."""
    if isinstance(job, CollectJob):
        return _collect(job)
    if isinstance(job, TrainJob):
        return _train(job)
    if isinstance(job, TrialsJob):
        return _trials(job)
    return _gif(job)


def _collect(job: CollectJob) -> str:
    if job.randomised:
        randomised = job.settings.randomised_collect(str(task_file(job.out, job.task)))
        dataset = collect(randomised, job.path, progress=False)
        return f"{randomised.size} randomised scenes ({len(dataset)} samples)"
    settings = CollectSettings(SCENE, str(task_file(job.out, job.task)), job.settings.demos,
                               job.settings.seed, SeedStream.TRAIN,
                               approach_hz=job.settings.approach_hz, robot=job.settings.robot)
    dataset = collect(settings, job.path, progress=False)
    extra = dataset.metadata.extra
    return f"{extra.get('scenes', len(dataset))} demonstrations ({len(dataset)} " \
           f"samples), {extra.get('demonstrations_redrawn', 0)} redrawn"


def _train(job: TrainJob) -> str:
    settings, unit = job.settings, job.unit
    with torch_threads(settings.train_threads):
        paths = train_inputs(job)
        path = paths[0]
        data = load_dataset(path, expect={"scene": SCENE,  # the task as run (its world's name)
                                          "task": settings.run_task(TrialSet(unit)).name,
                                          "seed": settings.seed})
        demonstrations = data.metadata.extra.get("scenes", len(data))
        if demonstrations != settings.demos:  # a demonstration has an image per pick
            raise DatasetError(path, f"holds {demonstrations} demonstrations, the run asks "
                               f"for {settings.demos}")
        if len(paths) > 1:  # as gva train --data DEMOS --data RANDOMISED joins them
            randomised = settings.randomised_collect(str(task_file(job.out, unit.task)))
            extra = load_dataset(paths[1], expect={"scene": SCENE, "seed": randomised.seed,
                                                   "task": randomised.task_spec.name})
            data = concatenate([data, extra], [str(p) for p in paths])
        hyperparameters = settings.model_settings(unit.model)
        fit = fit_checked(lambda seed: new_model(unit.model, data, seed=seed, **hyperparameters),
                          data, TrainConfig(**settings.train_config()), settings.check,
                          progress=False)
        if (file := model_config_file(settings.model_configs, unit.model)) is not None:
            file.record(fit.model)
        if len(paths) > 1 and isinstance(fit.model, TorchModel):
            fit.model.provenance["datasets"] = training_files(data, paths)
        fit.model.save(checkpoint_folder(job.out, unit))
        write_check(checkpoint_folder(job.out, unit), fit)
    report, check = fit.report, fit.check
    write_json(trained_file(job.out, unit), {  # last: it marks the checkpoint finished
        "identity": job.identity, "train_s": report.wall_time_s, "steps": report.steps,
        "final_loss": report.final_loss, "samples": report.samples,
        "phases": [phase._asdict() for phase in report.phases],
        "attempts": len(fit.checks), "attempt_times": [t._asdict() for t in fit.times],
        "check": None if check is None else check.to_json()})
    shown = "" if check is None else "; " + check.headline()
    return f"final loss {report.final_loss:.4g} in {report.wall_time_s:.0f} s{shown}"


def train_inputs(job: TrainJob) -> list[Path]:
    """The datasets a unit trains on: its demonstrations, then its randomised scenes if any.

    The randomised scenes are the run's ``--randomised-scenes``, of the unit's task.
    """
    settings, task = job.settings, job.unit.task
    return [dataset_file(job.out, task, settings)] + (
        [randomised_file(job.out, task, settings.randomised_scenes, settings.randomised_seed)]
        if settings.randomised_scenes else [])


def collect_name(task: str, seed: int, randomised: bool = False) -> str:
    """A collection job's name: ``collect-single-s0``, ``collect-randomised-single-s0``."""
    return f"collect-{'randomised-' if randomised else ''}{task}-s{seed}"


def train_needs(job: TrainJob) -> list[str]:
    """The collections a training waits for: its demonstrations', and its randomised scenes'."""
    seed, task = job.settings.seed, job.unit.task
    return [collect_name(task, seed)] + (
        [collect_name(task, seed, True)] if job.settings.randomised_scenes else [])


def _trials(job: TrialsJob) -> str:
    summary = run_trials(job.trials, trials_folder(job.out, job.trial_set), progress=False)
    return f"{summary.successes}/{summary.n}"


def _gif(job: GifJob) -> str:
    path = gif_file(job.out, job.unit)
    shown = record_gif(job.unit.model, job.trials, job.count, path)
    write_json(path.with_suffix(".json"), {"identity": gif_identity(job), "trials": shown})
    return ", ".join(t["outcome"] for t in shown)


# finding finished work


def trials_done(job: TrialsJob) -> bool:
    """Whether the set's ``summary.json`` holds all its trials, run with these settings."""
    path = trials_folder(job.out, job.trial_set) / "summary.json"
    if not path.exists():
        return False
    stored = read_json(path)
    return bool(stored["n"] == job.trials.n and stored["settings"] == _summary_settings(job.trials))


def _summary_settings(trials: TrialSettings) -> dict[str, Any]:
    return json_form(trials.identity() | {"n": trials.n})


def gif_identity(job: GifJob) -> dict[str, Any]:
    """What a GIF shows: the trials' settings and how many of them."""
    return _summary_settings(job.trials) | {"gif_trials": job.count}


def gif_done(job: GifJob) -> bool:
    """Whether the GIF exists and its ``.json`` says it shows these trials."""
    meta = gif_file(job.out, job.unit).with_suffix(".json")
    return (gif_file(job.out, job.unit).exists() and meta.exists()
            and read_json(meta).get("identity") == gif_identity(job))

