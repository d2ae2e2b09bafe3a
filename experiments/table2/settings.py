"""What ``gva reproduce sim`` runs: its settings, its cells and where a run folder keeps them.

A cell is one model x task x training set size x training seed. What defines a cell's result
(:meth:`ReproduceSimSettings.cell_identity`) is stored in its file, and a file computed with
other settings is refused, not mixed into the table.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from experiments.table2.options import SCENES, SIM
from experiments.tables import (
    ALL_TASKS,
    PAPER_MODELS,
    TASKS,
    TWO_PHASE_MODELS,
    check_choices,
    check_counts,
    check_model_configs,
    check_models,
    model_config,
    model_config_file,
    model_order,
    model_settings,
)
from harness.inputs.trial_settings import task_identity
from harness.jobs import LOCAL, Executor
from harness.run_folder import json_form
from perception.learning.train import TrainConfig, available_threads
from perception.model_config_file import ModelConfigFile
from sim.errors import InvalidInputError
from sim.tasks.task_sensor import seen_in_scene
from sim.tasks.task_toml import load_task
from sim.world.sensor import SensorKind

SIZES = (4, 20, 100)
"""Training set sizes of Table II."""
SCENE = "paper-sim"
"""The paper's simulator scene, Table II's."""
BOLD_BELOW_CM = 5.0
"""The paper bolds errors below 5 cm."""
Key = tuple[str, str, int]  # (model, task, size)
FORMAT_VERSION = 3
"""What a run folder holds; 2: a training scene of a task with a condition is asked each value
(:class:`harness.inputs.collector.CollectSettings` ``every_condition``); 3: ``kqv``'s attention
point is taught on paper-sim too (``KqvConfig.point_loss_weight``)."""


@dataclass(frozen=True)
class Cell:
    """One entry of Table II: a model trained on ``size`` scenes of ``task`` with ``seed``."""

    model: str
    task: str
    size: int
    seed: int

    @property
    def name(self) -> str:
        """``kqv-single-20-s0``: the stem of the cell's files."""
        return f"{self.model}-{self.task}-{self.size}-s{self.seed}"

    @property
    def cost(self) -> float:
        """Relative training time: samples per step (batches hold at most 16) x phases."""
        return min(self.size, 16) * (1.5 if self.model in TWO_PHASE_MODELS else 1.0)


CELL_THREADS = 1
"""Torch threads of a cell's training: one, so cells train side by side, one per core."""

@dataclass(frozen=True)
class ReproduceSimSettings:
    """What ``gva reproduce sim`` runs; its fields' defaults are the command's.

    Args:
        models: Models, names ``new_model`` takes (the paper's
            :data:`~experiments.tables.PAPER_MODELS` by default; a preset such as ``kqv-paper``
            or a plug-in too).
        tasks: Tasks, from :data:`~experiments.tables.ALL_TASKS` (default: the paper's).
        sizes: Training set sizes, from :data:`SIZES`.
        seeds: Number of training seeds.
        seed: S0, the first training seed and the seed of the test scenes.
        steps: Optimiser steps per training phase (other training settings:
            :class:`~perception.learning.train.TrainConfig`'s, torch on one thread).
        test_scenes: Test scenes per task (the paper's 100; fewer for a quick check).
        scene: ``paper-sim`` (the paper's Table II) or ``yumi`` (the robot's scenes, offline).
        sensor: ``yumi`` scene only: what the head camera renders through (``--sensor``),
            replacing each task file's ``[camera] sensor``; None: the file's, else the D435
            (:mod:`sim.tasks.task_sensor`). Named in the run's identity only where given.
        workers: Processes running cells at once; None: the cores this process may use. One
            runs everything in this process.
        executor: Where the jobs run: this machine's process pool (default) or Ray
            (:class:`~harness.jobs.Executor`); the results are the same.
        model_configs: Settings of some of ``models`` read from files (``--model-config
            MODEL=FILE.toml``), at most one per model. They reach ``new_model`` and the
            model's hyper-parameters in each cell's identity, so a cell computed with other
            settings is refused; with none, identities are as before files existed.

    """

    models: tuple[str, ...] = PAPER_MODELS
    tasks: tuple[str, ...] = TASKS
    sizes: tuple[int, ...] = SIZES
    seeds: int = 3
    seed: int = 0
    steps: int = TrainConfig.steps
    test_scenes: int = 100
    workers: int | None = None
    scene: str = SCENE
    sensor: SensorKind | None = None
    executor: Executor = LOCAL
    model_configs: tuple[ModelConfigFile, ...] = ()

    def __post_init__(self) -> None:
        check_choices("scene", (self.scene,), SCENES)
        if self.sensor is not None:
            if not isinstance(self.sensor, SensorKind):
                raise InvalidInputError("sensor", self.sensor, "None or one of " + ", ".join(
                    f"SensorKind.{k.name}" for k in SensorKind))
            if self.scene != "yumi":
                raise InvalidInputError("sensor", self.sensor.value, "none for the paper-sim "
                                        "scene: it renders through its own camera, an ideal "
                                        "pinhole (--sensor is for --scene yumi)")
        check_models(self.models)
        check_choices("tasks", self.tasks, ALL_TASKS)
        check_choices("sizes", self.sizes, SIZES)
        check_model_configs([(f.model, f.path) for f in self.model_configs], self.models)
        check_counts(self, {"seeds": 1, "seed": 0, "steps": 1, "test_scenes": 1}, self.workers)

    @property
    def training_seeds(self) -> range:
        """S0 .. S0 + seeds - 1."""
        return range(self.seed, self.seed + self.seeds)

    def cells(self) -> list[Cell]:
        """Every cell, in the paper's order (models, tasks, sizes, then seeds)."""
        return [Cell(m, t, s, seed) for m in sorted(self.models, key=model_order)
                for t in ALL_TASKS if t in self.tasks for s in SIZES if s in self.sizes
                for seed in self.training_seeds]

    def worker_count(self) -> int:
        """The processes to run: ``workers``, or the cores this process may use."""
        return self.workers if self.workers is not None else available_threads()

    def run_identity(self) -> dict[str, Any]:
        """What every cell of a folder shares; ``run.json`` holds it."""
        train = asdict(TrainConfig(steps=self.steps, threads=CELL_THREADS))
        train.pop("seed")  # each cell's own
        sensor = {} if self.sensor is None else {"sensor": self.sensor.value}
        return sensor | {"format_version": FORMAT_VERSION, "experiment": "reproduce-sim",
                         "scene": self.scene, "train": train, "test_seed": self.seed,
                         "test_scenes": self.test_scenes}

    def cell_identity(self, cell: Cell) -> dict[str, Any]:
        """What defines a cell's result, in JSON form: a cell file is reused only if equal.

        The model and its hyper-parameters, the task's definition, size, seed, training
        settings, test seed and test scenes.
        """
        return json_form(self.run_identity() | {
            "model": cell.model,
            "model_config": model_config(cell.model, cell.seed, self.model_settings(cell.model)),
            "task": task_identity(seen_in_scene(load_task(cell.task), self.scene, self.sensor)),
            "size": cell.size, "seed": cell.seed})

    def model_config_file(self, model: str) -> ModelConfigFile | None:
        """The file of ``model_configs`` for ``model``; None: it trains with its own settings."""
        return model_config_file(self.model_configs, model)

    def model_settings(self, model: str) -> dict[str, Any]:
        """The settings ``model_configs`` give ``model`` (``new_model``'s keywords); {}: none."""
        return model_settings(self.model_configs, model)

    def command(self, out: Path) -> str:
        """The ``gva reproduce sim`` command line of these settings (workers left out).

        Derived from the options' one table, :data:`experiments.table2.options.SIM`.
        """
        return SIM.line(self, out)


# files of a run folder


def cell_path(out: Path, cell: Cell) -> Path:
    """The result file of a finished cell."""
    return out / "cells" / f"{cell.name}.json"


def error_path(out: Path, cell: Cell) -> Path:
    """The record of a cell that raised."""
    return out / "cells" / f"{cell.name}-error.json"


def checkpoint_folder(out: Path, cell: Cell) -> Path:
    """The checkpoint folder of a cell."""
    return out / "checkpoints" / cell.model / cell.task / str(cell.size) / f"s{cell.seed}"
