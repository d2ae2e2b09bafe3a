"""``gva reproduce sim``: the paper's Table II (position error in the simulator), resumable.

The experiment. Every *cell* is one model x task x dataset size x training seed:

- models: ``kqv`` (the paper's model, q = min), ``keypoint-16``, ``keypoint-min``, ``dsae-16``,
  ``conv-ae``, ``fcn``; tasks: ``single``, ``multiple``, ``selected-type``,
  ``selected-position``; sizes: 4, 20, 100 training scenes; seeds ``S0 .. S0 + seeds - 1``.
- Data, scene ``paper-sim`` (or ``yumi``, whose scenes are oracle-verified demonstrations with
  grasp-pose labels: the same sweep offline on the robot's task): a training set per
  (task, size, seed), scenes ``0 .. size - 1`` of
  that seed's TRAIN stream, so the 4 scenes of a size-4 set are the first 4 of the size-20 set
  (each task and seed is collected once, at its largest size, and the smaller sets are its
  prefixes, byte for byte what ``gva collect`` writes). One test set per task, the first
  ``test_scenes`` (100) scenes of the TEST stream of ``S0``, scores every cell of that task:
  test scenes never equal training scenes (the streams are disjoint), and ``--seed`` moves
  every scene, training and test.
- Per cell: a fresh model seeded with the training seed, trained for ``steps`` optimiser steps
  (:class:`~perception.train.TrainConfig` defaults otherwise, torch on one thread), its
  checkpoint saved, then its mean position error in cm on the task's test set
  (:func:`~perception.evaluate.evaluate`).

Cells run in ``workers`` processes (:mod:`experiments.jobs`), longest first, so the end of
the run is not one straggler; one progress bar, measured in the cells' estimated cost, gives the
time left. Resumability: every finished cell is one JSON file in
``OUT/cells/``, written atomically and keyed by its identity (model and its hyper-parameters,
task definition, size, seed, training settings, test seed and size). Running the command again
skips finished cells, retries failed ones and computes the rest; an interrupted run loses only
the cells that were still training. ``OUT/run.json`` holds the settings every cell of the
folder shares (training settings, test seed, test scenes): a run with others is refused, as is
a cell file computed with other settings (e.g. a model whose defaults changed since), rather
than mixed into one table. A cell that raises is recorded in ``OUT/cells/<cell>-error.json`` and
the run goes on; the summary names it.

Layout of ``OUT``::

    run.json                    the shared settings
    datasets/<task>-train-<size>-s<seed>.gva, <task>-test-<n>-s<S0>.gva   (experiments.sim_datasets)
    checkpoints/<model>/<task>/<size>/s<seed>/   one checkpoint per cell
    cells/<model>-<task>-<size>-s<seed>.json     one result per cell (-error.json: it failed)
    table2.json, table2.md, table2.png, fig5.png (see :mod:`experiments.sim_report`)

The reports are rewritten from every cell file present at the end of each run, also when every
cell was skipped.
"""

from __future__ import annotations

import time
import traceback
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from experiments.runs import check_choices, check_counts, read_json, write_json
from experiments.sim_datasets import SCENE, SCENES, dataset_path
from sim.errors import InvalidInputError
from sim.records import RunFolderError, differences, json_form

if TYPE_CHECKING:
    from perception.data import Dataset

MODELS = ("kqv", "keypoint-16", "keypoint-min", "dsae-16", "conv-ae", "fcn")
"""The models of Table II, in the paper's row order (names :func:`new_model` takes)."""
TASKS = ("single", "multiple", "selected-type", "selected-position")
"""The tasks of Table II, in the paper's column order."""
SIZES = (4, 20, 100)
"""Training set sizes of Table II."""
TWO_PHASE_MODELS = ("dsae-16", "conv-ae")
"""Models trained in two phases (autoencoder, then targets): they take longer per cell."""
BOLD_BELOW_CM = 5.0
"""The paper bolds errors below 5 cm."""
NO_IMAGE = "no-image"
"""The row of :func:`perception.evaluate.label_mean_error_cm` in the tables."""
MODEL_TITLES = {
    "kqv": "Ours (kqv, q=min)", "keypoint-16": "Key Point (q=16)",
    "keypoint-min": "Key Point (q=min)", "dsae-16": "Deep Spatial AE (q=16)",
    "conv-ae": "Convolutional AE", "fcn": "FCN",
    NO_IMAGE: "No image (training-label mean)",
}
TASK_TITLES = {"single": "Single Object", "multiple": "Multiple Objects",
               "selected-type": "Selected Type", "selected-position": "Selected Position"}
Key = tuple[str, str, int]  # (model, task, size)
FORMAT_VERSION = 3
"""What a run folder holds; 2: a training scene of a task with a condition is asked each value
(:class:`sim.collect.CollectSettings` ``every_condition``); 3: ``kqv``'s attention point is taught
on paper-sim too (``KqvConfig.point_loss_weight``)."""


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


@dataclass(frozen=True)
class ReproduceSimSettings:
    """What ``gva reproduce sim`` runs.

    Args:
        models: Models, from :data:`MODELS`.
        tasks: Tasks, from :data:`TASKS`.
        sizes: Training set sizes, from :data:`SIZES`.
        seeds: Number of training seeds.
        seed: S0, the first training seed and the seed of the test scenes.
        steps: Optimiser steps per training phase.
        test_scenes: Test scenes per task (the paper's 100; fewer for a quick check).
        scene: ``paper-sim`` (the paper's Table II) or ``yumi`` (the robot's scenes, offline).
        workers: Processes running cells at once; None: the cores this process may use. One
            runs everything in this process.

    """

    models: tuple[str, ...] = MODELS
    tasks: tuple[str, ...] = TASKS
    sizes: tuple[int, ...] = SIZES
    seeds: int = 3
    seed: int = 0
    steps: int = 1000
    test_scenes: int = 100
    workers: int | None = None
    scene: str = SCENE

    def __post_init__(self) -> None:
        check_choices("scene", (self.scene,), SCENES)
        check_choices("models", self.models, MODELS)
        check_choices("tasks", self.tasks, TASKS)
        check_choices("sizes", self.sizes, SIZES)
        check_counts(self, {"seeds": 1, "seed": 0, "steps": 1, "test_scenes": 1}, self.workers)

    @property
    def training_seeds(self) -> range:
        """S0 .. S0 + seeds - 1."""
        return range(self.seed, self.seed + self.seeds)

    def cells(self) -> list[Cell]:
        """Every cell, in the paper's order (models, tasks, sizes, then seeds)."""
        return [Cell(m, t, s, seed) for m in MODELS if m in self.models
                for t in TASKS if t in self.tasks for s in SIZES if s in self.sizes
                for seed in self.training_seeds]

    def worker_count(self) -> int:
        """The processes to run: ``workers``, or the cores this process may use."""
        if self.workers is not None:
            return self.workers
        from perception.train import available_threads

        return available_threads()

    def run_identity(self) -> dict[str, Any]:
        """What every cell of a folder shares; ``run.json`` holds it."""
        from perception.train import TrainConfig

        train = asdict(TrainConfig(steps=self.steps, threads=1))
        train.pop("seed")  # each cell's own
        return {"format_version": FORMAT_VERSION, "experiment": "reproduce-sim",
                "scene": self.scene,
                "train": train, "test_seed": self.seed, "test_scenes": self.test_scenes}

    def cell_identity(self, cell: Cell) -> dict[str, Any]:
        """What defines a cell's result, in JSON form: a cell file is reused only if equal."""
        from sim.tasks import load_task
        from sim.trials import task_identity

        return json_form(self.run_identity() | {
            "model": cell.model, "model_config": model_config(cell.model, cell.seed),
            "task": task_identity(load_task(cell.task)), "size": cell.size, "seed": cell.seed})

    def command(self, out: Path) -> str:
        """The ``gva reproduce sim`` command line of these settings (workers left out)."""
        parts = ["gva reproduce sim", f"--out {out}", f"--seeds {self.seeds}",
                 f"--seed {self.seed}", f"--steps {self.steps}"]
        for name, given, everything in (("models", self.models, MODELS),
                                        ("tasks", self.tasks, TASKS),
                                        ("sizes", self.sizes, SIZES)):
            if set(given) != set(everything):
                parts.append(f"--{name} {','.join(str(v) for v in given)}")
        if self.test_scenes != 100:
            parts.append(f"--test-scenes {self.test_scenes}")
        if self.scene != SCENE:
            parts.append(f"--scene {self.scene}")
        return " ".join(parts)


def model_config(model: str, seed: int) -> dict[str, Any]:
    """The hyper-parameters ``new_model(model, dataset, seed=seed)`` builds with, as a dict."""
    from perception.models.torch_model import TorchModel
    from perception.registry import PRESETS, model_class

    name, preset = PRESETS.get(model, (model, {}))
    cls = model_class(name)
    if not issubclass(cls, TorchModel):  # every model of MODELS is one
        raise InvalidInputError("model", model, f"a model that trains: {', '.join(MODELS)}")
    return asdict(cls.config_class(**preset, seed=seed))


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


@dataclass(frozen=True)
class CellOutcome:
    """A computed cell: its mean error [cm] and training time [s], or the error it raised."""

    cell: Cell
    error_cm: float | None
    train_s: float
    failure: str | None = None


def load_scenes(path: Path, scene: str, task: str, scenes: int, seed: int) -> Dataset:
    """The dataset at ``path``, checked to hold ``scenes`` scenes of ``task`` under ``seed``.

    A scene may give several samples (one per condition value, or per pick): counted are
    scenes (``extra["scenes"]``), not samples.
    """
    from perception.dataset_file import DatasetError, load_dataset

    dataset = load_dataset(path, expect={"scene": scene, "task": task, "seed": seed})
    held = dataset.metadata.extra.get("scenes", len(dataset))
    if held != scenes:
        raise DatasetError(path, f"holds {held} scenes, the cell asks for {scenes}")
    return dataset


def compute_cell(job: CellJob) -> CellOutcome:
    """Trains, saves and scores one cell; writes its result (or its failure) file."""
    from perception.evaluate import evaluate
    from perception.registry import new_model
    from perception.train import TrainConfig
    from sim.scene import SeedStream
    from sim.trials import torch_threads

    cell, out = job.cell, job.out
    started = time.perf_counter()
    try:
        with torch_threads(1):
            train = load_scenes(dataset_path(out, cell.task, SeedStream.TRAIN, cell.size,
                                             cell.seed), job.scene, cell.task, cell.size,
                                cell.seed)
            test = load_scenes(dataset_path(out, cell.task, SeedStream.TEST, job.test_scenes,
                                            job.test_seed), job.scene, cell.task,
                               job.test_scenes, job.test_seed)
            model = new_model(cell.model, train, seed=cell.seed)
            report = model.fit(train, TrainConfig(steps=job.steps, seed=cell.seed, threads=1),
                               progress=False)
            model.save(checkpoint_folder(out, cell))
            result = evaluate(model, test)
    except Exception as error:  # one cell's failure is recorded; the table goes on
        failure = f"{type(error).__name__}: {error}"
        write_json(error_path(out, cell), asdict(cell) | {
            "error": failure, "traceback": traceback.format_exc(), "identity": job.identity})
        return CellOutcome(cell, None, time.perf_counter() - started, failure)
    write_json(cell_path(out, cell), asdict(cell) | {
        "error_cm": result.mean_position_error_cm,
        "median_error_cm": result.median_position_error_cm,
        "per_target_error_cm": list(result.per_target_mean_position_error_cm),
        "per_condition_error_cm": result.per_condition_mean_position_error_cm,
        "per_stage_error_cm": list(result.per_stage_mean_position_error_cm),
        "median_heatmap_entropy_nats": result.median_heatmap_entropy_nats,
        "train_s": report.wall_time_s, "cell_s": time.perf_counter() - started,
        "steps": report.steps, "final_loss": report.final_loss,
        "test_scenes": test.metadata.extra.get("scenes", len(test)),
        "checkpoint": str(checkpoint_folder(out, cell).relative_to(out)),
        "identity": job.identity})
    error_path(out, cell).unlink(missing_ok=True)
    return CellOutcome(cell, result.mean_position_error_cm, report.wall_time_s)


def sort_cells(settings: ReproduceSimSettings, out: Path) -> tuple[list[Cell], list[Cell]]:
    """(cells to compute, longest first; finished cells to skip).

    Raises:
        RunFolderError: A cell file of the folder (of this run's cells or any other) was
            computed with other settings; the message lists them and what differs.

    """
    wanted = set(settings.cells())
    done: list[Cell] = []
    stale: list[str] = []
    for path in sorted((out / "cells").glob("*.json")):
        if path.name.endswith("-error.json"):
            continue
        stored = read_json(path)
        cell = Cell(stored["model"], stored["task"], stored["size"], stored["seed"])
        asked = settings.cell_identity(cell)
        if stored["identity"] != asked:
            stale.append(f"{path.name} ({differences(stored['identity'], asked)})")
        elif cell in wanted:
            done.append(cell)
    if stale:
        raise RunFolderError(
            f"{out / 'cells'} holds {len(stale)} cell(s) computed with other settings, stored "
            f"vs now: {'; '.join(stale[:3])}{' ...' if len(stale) > 3 else ''}; remove those "
            "files to compute them again with the current code, or use another --out")
    todo = [cell for cell in settings.cells() if cell not in done]
    todo.sort(key=lambda cell: -cell.cost)  # stable: the paper's order among equals
    return todo, done
