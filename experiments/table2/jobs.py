"""The work ``gva reproduce sim`` hands its job pool: dataset collections, then cells.

Datasets live in ``OUT/datasets/``: per task and training seed, scenes ``0 .. size - 1`` of the
seed's TRAIN stream, collected once at the largest size with the smaller sets written as its
prefixes (byte for byte what ``gva collect`` writes); per task, the first ``test_scenes`` scenes
of the TEST stream of the first seed. A file already there is reused once its metadata checks
out, never overwritten. A cell trains a fresh model, saves it, scores it on its task's test set
and writes its result file (or its error file); :func:`sort_cells` finds the finished ones.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, NamedTuple

from experiments.table2.settings import (
    CELL_THREADS,
    SCENE,
    Cell,
    ReproduceSimSettings,
    cell_path,
    checkpoint_folder,
    error_path,
)
from harness.inputs.collector import CollectSettings, collect
from harness.jobs import JobResources
from harness.run_files import (
    Failed,
    dataset_path,
    dataset_present,
    guarded,
    read_json,
    refuse_other_settings,
    write_json,
)
from perception.learning.data import Dataset
from perception.learning.dataset_file import DatasetError, load_dataset, save_dataset
from perception.learning.evaluate import EvaluationResult, evaluate
from perception.learning.train import TrainConfig, TrainReport
from perception.model_config_file import ModelConfigFile
from perception.registry import new_model
from sim.tasks.scene_sampling import SeedStream
from sim.trials.trial_models import torch_threads
from sim.world.robot_choice import resolve_robot
from sim.world.sensor import SensorKind

# datasets


@dataclass(frozen=True)
class DatasetJob:
    """Datasets of one task and seed in one stream: ``sizes`` scenes each, all one prefix."""

    task: str
    seed: int
    stream: SeedStream
    sizes: tuple[int, ...]
    out: Path
    scene: str = SCENE
    sensor: SensorKind | None = None  # the yumi scene's --sensor; None: the task file's

    @property
    def name(self) -> str:
        """``collect-single-train-s0``: the job's name in Ray's task list."""
        return f"collect-{self.task}-{self.stream.name.lower()}-s{self.seed}"


def collect_datasets(job: DatasetJob) -> DatasetJob:
    """Collects the largest of ``job.sizes`` once and writes the smaller sets as its prefixes."""
    largest = max(job.sizes)
    settings = CollectSettings(job.scene, job.task, largest, job.seed, job.stream,
                               sensor=job.sensor)
    full = collect(settings, dataset_path(job.out, job.task, job.stream, largest, job.seed),
                   progress=False)
    for size in job.sizes:
        if size != largest:
            save_dataset(full.first_scenes(size),
                         dataset_path(job.out, job.task, job.stream, size, job.seed))
    return job


def dataset_jobs(out: Path, scene: str, tasks: Sequence[str], training_seeds: Sequence[int],
                 sizes: Sequence[int], test_seed: int, test_scenes: int,
                 sensor: SensorKind | None = None) -> list[DatasetJob]:
    """The collections still to do: training sets per task and seed, a test set per task."""
    wanted = [(task, seed, SeedStream.TRAIN, tuple(sizes)) for task in tasks
              for seed in training_seeds]
    wanted += [(task, test_seed, SeedStream.TEST, (test_scenes,)) for task in tasks]
    robot = resolve_robot(CollectSettings.robot)  # the robot collect_datasets' settings hold
    jobs = []
    for task, seed, stream, sizes in wanted:
        missing = tuple(sorted(s for s in sizes if not dataset_present(
            dataset_path(out, task, stream, s, seed), scene, task, s, seed, stream,
            robot=robot, sensor=sensor)))
        if missing:
            jobs.append(DatasetJob(task, seed, stream, missing, out, scene, sensor))
    return jobs


# cells


@dataclass(frozen=True)
class CellJob:
    """What a worker needs to compute one cell."""

    cell: Cell
    identity: dict[str, Any]
    steps: int
    test_scenes: int
    test_seed: int
    out: Path
    scene: str = SCENE
    model_config: ModelConfigFile | None = None  # the file that sets the model's settings

    @property
    def name(self) -> str:
        """``kqv-single-20-s0``: the cell's name, as in messages and Ray's task list."""
        return self.cell.name


@dataclass(frozen=True)
class CellOutcome:
    """A computed cell: its mean error [cm] and training time [s], or the error it raised."""

    cell: Cell
    error_cm: float | None
    train_s: float
    failure: str | None = None


class _Scored(NamedTuple):
    """A cell's trained model, scored: its training, its errors and the test set."""

    report: TrainReport
    result: EvaluationResult
    test: Dataset


def load_scenes(path: Path, scene: str, task: str, scenes: int, seed: int) -> Dataset:
    """The dataset at ``path``, checked to hold ``scenes`` scenes of ``task`` under ``seed``.

    A scene may give several samples (one per condition value, or per pick): counted are
    scenes (``extra["scenes"]``), not samples.
    """
    dataset = load_dataset(path, expect={"scene": scene, "task": task, "seed": seed})
    held = dataset.metadata.extra.get("scenes", len(dataset))
    if held != scenes:
        raise DatasetError(path, f"holds {held} scenes, the cell asks for {scenes}")
    return dataset


def _train_and_score(job: CellJob) -> _Scored:
    """Trains a fresh model on the cell's training set, saves it, scores it on the test set."""
    cell, out = job.cell, job.out
    with torch_threads(1):
        train = load_scenes(dataset_path(out, cell.task, SeedStream.TRAIN, cell.size, cell.seed),
                            job.scene, cell.task, cell.size, cell.seed)
        test = load_scenes(dataset_path(out, cell.task, SeedStream.TEST, job.test_scenes,
                                        job.test_seed), job.scene, cell.task, job.test_scenes,
                           job.test_seed)
        file = job.model_config
        model = new_model(cell.model, train, seed=cell.seed,
                          **({} if file is None else file.hyperparameters()))
        config = TrainConfig(steps=job.steps, seed=cell.seed, threads=CELL_THREADS)
        report = model.fit(train, config, progress=False)
        if file is not None:
            file.record(model)
        model.save(checkpoint_folder(out, cell))
        return _Scored(report, evaluate(model, test), test)


def compute_cell(job: CellJob) -> CellOutcome:
    """Trains, saves and scores one cell; writes its result (or its error) file."""
    cell, out = job.cell, job.out
    started = time.perf_counter()
    scored = guarded(lambda: _train_and_score(job), error_path(out, cell), asdict(cell),
                     {"identity": job.identity})
    if isinstance(scored, Failed):
        return CellOutcome(cell, None, time.perf_counter() - started, scored.message)
    report, result, test = scored
    write_json(cell_path(out, cell), asdict(cell) | {
        "error_cm": result.mean_position_error_cm,
        "median_error_cm": result.median_position_error_cm,
        "per_target_error_cm": list(result.per_target_mean_position_error_cm),
        "per_condition_error_cm": result.per_condition_mean_position_error_cm,
        "per_stage_error_cm": list(result.per_stage_mean_position_error_cm),
        "median_heatmap_entropy_nats": result.median_heatmap_entropy_nats,
        "judged": None if result.judged is None else result.judged.to_json(),
        "train_s": report.wall_time_s, "cell_s": time.perf_counter() - started,
        "steps": report.steps, "final_loss": report.final_loss,
        "test_scenes": test.metadata.extra.get("scenes", len(test)),
        "checkpoint": str(checkpoint_folder(out, cell).relative_to(out)),
        "identity": job.identity})
    return CellOutcome(cell, result.mean_position_error_cm, report.wall_time_s)


def sort_cells(settings: ReproduceSimSettings, out: Path) -> tuple[list[Cell], list[Cell]]:
    """(cells to compute, longest first; finished cells to skip).

    Raises:
        RunFolderError: A cell file of the folder (of this run's cells or any other) was
            computed with other settings; the message lists them and what differs.

    """
    wanted = set(settings.cells())
    done: list[Cell] = []
    identities: list[tuple[str, Any, Any]] = []
    for path in sorted((out / "cells").glob("*.json")):
        if path.name.endswith("-error.json"):
            continue
        stored = read_json(path)
        cell = Cell(stored["model"], stored["task"], stored["size"], stored["seed"])
        asked = settings.cell_identity(cell)
        identities.append((path.name, stored["identity"], asked))
        if stored["identity"] == asked and cell in wanted:
            done.append(cell)
    refuse_other_settings(identities, f"cell file(s) in {out / 'cells'}")
    todo = [cell for cell in settings.cells() if cell not in done]
    todo.sort(key=lambda cell: -cell.cost)  # stable: the paper's order among equals
    return todo, done


def cell_resources(job: CellJob) -> JobResources:
    """What a cell holds while it runs: its training's one thread (and a GPU were it on CUDA)."""
    return JobResources.training(CELL_THREADS, TrainConfig.device)
