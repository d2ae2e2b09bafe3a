"""Runs ``gva reproduce sim`` (:mod:`experiments.table2.settings`) into a run folder.

Claims the folder, collects the datasets, computes the missing cells in a job pool under one
progress bar, and rebuilds the reports (:mod:`experiments.table2.report`). The settings, cells
and layout live in :mod:`experiments.table2.settings`, which imports none of these.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from experiments.jobs import JobPool
from experiments.table2.datasets import collect_datasets, dataset_jobs
from experiments.table2.report import write_reports
from experiments.table2.settings import (
    Cell,
    CellJob,
    CellOutcome,
    ReproduceSimSettings,
    compute_cell,
    sort_cells,
)
from sim.records import claim_run_folder


@dataclass(frozen=True)
class ReproduceSimReport:
    """What a run did: cells computed and skipped, the folder's failed cells, its outputs.

    ``wall_time_s`` covers collecting, training and scoring, not drawing the reports after.
    """

    computed: tuple[CellOutcome, ...]
    skipped: tuple[Cell, ...]
    failed: tuple[dict[str, Any], ...]
    wall_time_s: float
    outputs: tuple[Path, ...] = field(default_factory=tuple)
    notes: tuple[str, ...] = field(default_factory=tuple)


def run_reproduce_sim(settings: ReproduceSimSettings, out: str | Path,
                      progress: bool = True) -> ReproduceSimReport:
    """Runs (or resumes) the experiment into ``out`` (:mod:`experiments.table2.settings`).

    Raises:
        RunFolderError: ``out`` holds a run with other shared settings, or a cell or dataset
            file made with other settings.
        KeyboardInterrupt: Ctrl-C; finished cells are kept and the message says so.

    """
    out = Path(out)
    started = time.perf_counter()
    claim_run_folder(out, settings.run_identity())
    todo, done = sort_cells(settings, out)
    workers = settings.worker_count()
    collections = dataset_jobs(out, settings.scene, settings.tasks, settings.training_seeds,
                               settings.sizes, settings.seed, settings.test_scenes) if todo else []
    computed: list[CellOutcome] = []
    try:
        with JobPool(workers) as pool:
            with tqdm(total=len(collections), disable=not progress or not collections,
                      desc="collect datasets", unit="set") as bar:
                pool.run(collect_datasets, collections, lambda job: bar.update())
            _run_cells(settings, out, todo, len(done), pool, progress, computed)
    except KeyboardInterrupt:
        finished = len(list((out / "cells").glob("*[0-9].json")))
        raise KeyboardInterrupt(
            f"{finished} finished cell(s) kept in {out / 'cells'} ({len(computed)} from this "
            f"run); resume with: {settings.command(out)}") from None
    wall_time_s = time.perf_counter() - started
    outputs, failed, notes = write_reports(settings, out, wall_time_s, len(computed))
    return ReproduceSimReport(tuple(computed), tuple(done), tuple(failed), wall_time_s,
                              tuple(outputs), tuple(notes))


def _run_cells(settings: ReproduceSimSettings, out: Path, todo: Sequence[Cell], skipped: int,
               pool: JobPool, progress: bool, computed: list[CellOutcome]) -> None:
    """Computes ``todo`` into ``computed`` under one bar whose length is the cells' cost.

    Measuring the bar in estimated cost rather than in cells keeps its time-left estimate
    honest while the long cells, which run first, are still going.
    """
    jobs = [CellJob(cell, settings.cell_identity(cell), settings.steps, settings.test_scenes,
                    settings.seed, out, settings.scene) for cell in todo]
    earlier = f", {skipped} done earlier" if skipped else ""
    bar = tqdm(total=sum(cell.cost for cell in todo), disable=not progress or not jobs,
               desc="reproduce sim", file=sys.stderr,
               bar_format="{desc}: {percentage:3.0f}%|{bar}| [{elapsed}<{remaining}{postfix}]")
    bar.set_postfix_str(f"0/{len(jobs)} cells{earlier}")

    def done(outcome: CellOutcome) -> None:
        computed.append(outcome)
        shown = "FAILED" if outcome.error_cm is None else f"{outcome.error_cm:.2f} cm"
        bar.set_postfix_str(f"{len(computed)}/{len(jobs)} cells{earlier}; last "
                            f"{outcome.cell.name} {shown}", refresh=False)
        bar.update(outcome.cell.cost)

    with bar:
        pool.run(compute_cell, jobs, done)
