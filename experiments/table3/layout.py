"""Where a ``gva reproduce real`` folder keeps what: each seed's datasets, checkpoints, trials.

The run's settings (:mod:`experiments.table3.settings`) say what is made; these say where it
lies, so that every job, report and test finds a file by one rule.
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

from harness.run_files import dataset_path
from sim.tasks.scene_sampling import SeedStream


class Unit(Protocol):
    """What a path reads of a unit (:class:`experiments.table3.settings.Unit`)."""

    @property
    def model(self) -> str:
        """The model's name."""
    @property
    def task(self) -> str:
        """The task's name."""
    @property
    def name(self) -> str:
        """``model-task``."""


class TrialSet(Protocol):
    """What a path reads of a set of trials (:class:`experiments.table3.settings.TrialSet`)."""

    @property
    def unit(self) -> Unit:
        """Its unit."""
    @property
    def task_name(self) -> str:
        """The task it runs (variant included)."""


class Demonstrated(Protocol):
    """What a path reads of a run's settings: how many demonstrations, of which seed."""

    @property
    def demos(self) -> int:
        """Demonstrations per task."""
    @property
    def seed(self) -> int:
        """The seed."""



def seed_folder(out: Path, seed: int) -> Path:
    """The folder of one seed's run: datasets, checkpoints, trials, GIFs, errors."""
    return out / f"s{seed}"


def dataset_file(out: Path, task: str, settings: Demonstrated) -> Path:
    """The demonstrations of a task."""
    return dataset_path(out, task, SeedStream.TRAIN, settings.demos, settings.seed)


def randomised_file(out: Path, task: str, size: int, seed: int) -> Path:
    """A task's ``size`` scenes in randomised looks labelled by the catalog, drawn at ``seed``.

    ``seed`` is the run's randomised seed, not its own: the file names what it holds.
    """
    return out / "datasets" / f"{task}-randomised-{size}-s{seed}.gva"


def checkpoint_folder(out: Path, unit: Unit) -> Path:
    """The checkpoint of a unit (``trained.json`` beside its weights once complete)."""
    return out / "checkpoints" / unit.model / unit.task


def trained_file(out: Path, unit: Unit) -> Path:
    """What a finished checkpoint was trained with; written after the checkpoint."""
    return checkpoint_folder(out, unit) / "trained.json"


def task_file(out: Path, task_name: str) -> Path:
    """The task TOML a set runs, by :attr:`TrialSet.task_name` (a plain one's: its demos' too)."""
    return out / "tasks" / f"{task_name}.toml"


def trials_folder(out: Path, trial_set: TrialSet) -> Path:
    """The trial folder of a set (``run.json``, ``trials.jsonl``, ``summary.json``)."""
    return out / "trials" / trial_set.unit.model / trial_set.task_name


def gif_file(out: Path, unit: Unit) -> Path:
    """The GIF of a unit's first trials; a ``.json`` beside it says what it shows."""
    return out / "gifs" / f"{unit.name}.gif"


def error_file(out: Path, job: str) -> Path:
    """The record of a job that raised."""
    return out / "errors" / f"{job}.json"
