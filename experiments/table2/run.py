"""Runs ``gva reproduce sim`` into a run folder, or resumes it.

Claims the folder, collects the datasets, computes the missing cells in a job pool under one
progress bar, and rebuilds the reports from every cell file present.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

from tqdm import tqdm

from experiments.table2.jobs import (
    CellJob,
    CellOutcome,
    cell_resources,
    collect_datasets,
    compute_cell,
    dataset_jobs,
    sort_cells,
)
from experiments.table2.report import write_reports
from experiments.table2.settings import Cell, ReproduceSimSettings
from harness.executors import open_pool
from harness.jobs import Pool
from harness.run_folder import started_run
from harness.run_report import RunReport, cost_bar

ReproduceSimReport = RunReport[CellOutcome, Cell]


def run_reproduce_sim(settings: ReproduceSimSettings, out: str | Path,
                      progress: bool = True) -> ReproduceSimReport:
    """Runs (or resumes) the experiment into ``out``: cells computed and skipped, outputs.

    Raises:
        RunFolderError: ``out`` holds a run with other shared settings, or a cell or dataset
            file made with other settings.
        KeyboardInterrupt: Ctrl-C; finished cells are kept and the message says so.
        RunFolderError: Another run holds ``out`` (one run per folder).

    """
    out = Path(out)
    with started_run(out, settings.run_identity()) as (started, session):
        todo, done = sort_cells(settings, out)
        workers = settings.worker_count()
        collections = dataset_jobs(out, settings.scene, settings.tasks,
                                   settings.training_seeds, settings.sizes, settings.seed,
                                   settings.test_scenes, settings.sensor) if todo else []
        computed: list[CellOutcome] = []
        try:
            with open_pool(settings.executor, workers, out) as pool:
                with tqdm(total=len(collections), disable=not progress or not collections,
                          desc="collect datasets", unit="set") as bar:
                    def collected(_: object) -> None:
                        bar.update()

                    pool.run(collect_datasets, collections, collected)
                _run_cells(settings, out, todo, len(done), pool, progress, computed)
        except KeyboardInterrupt:
            finished = len(list((out / "cells").glob("*[0-9].json")))
            raise KeyboardInterrupt(
                f"{finished} finished cell(s) kept in {out / 'cells'} ({len(computed)} from this "
                f"run); resume with: {settings.command(out)}") from None
        wall_time_s = time.perf_counter() - started
        outputs, failed, notes = write_reports(settings, out, wall_time_s, len(computed),
                                                 session)
        return RunReport(tuple(computed), tuple(done), tuple(failed), wall_time_s, tuple(outputs),
                         tuple(notes))


def _run_cells(settings: ReproduceSimSettings, out: Path, todo: Sequence[Cell], skipped: int,
               pool: Pool, progress: bool, computed: list[CellOutcome]) -> None:
    """Computes ``todo`` into ``computed`` under one bar whose length is the cells' cost."""
    jobs = [CellJob(cell, settings.cell_identity(cell), settings.steps, settings.test_scenes,
                    settings.seed, out, settings.scene, settings.model_config_file(cell.model))
            for cell in todo]
    earlier = f", {skipped} done earlier" if skipped else ""
    bar = cost_bar(sum(cell.cost for cell in todo), "reproduce sim", progress)
    bar.set_postfix_str(f"0/{len(jobs)} cells{earlier}")

    def done(outcome: CellOutcome) -> None:
        computed.append(outcome)
        shown = "FAILED" if outcome.error_cm is None else f"{outcome.error_cm:.2f} cm"
        bar.set_postfix_str(f"{len(computed)}/{len(jobs)} cells{earlier}; last "
                            f"{outcome.cell.name} {shown}", refresh=False)
        bar.update(outcome.cell.cost)

    with bar:
        pool.run(compute_cell, jobs, done, cell_resources)
