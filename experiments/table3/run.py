"""Runs ``gva reproduce real`` into a run folder, or resumes it.

Claims the folder and each seed's, writes the task files it runs, runs the jobs, appends the
run to ``history.jsonl`` and rebuilds the reports from what every seed's folder holds.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

from experiments.table3.job_graph import run_jobs
from experiments.table3.jobs import JobOutcome
from experiments.table3.layout import seed_folder, task_file
from experiments.table3.report import write_reports
from experiments.table3.settings import ReproduceRealSettings
from harness.run_files import write_text
from harness.run_folder import claim_run_folder, started_run
from harness.run_report import RunReport
from sim.tasks.task_toml import task_to_toml

ReproduceRealReport = RunReport[JobOutcome, str]


def append_history(out: Path, entry: dict[str, Any]) -> None:
    """Appends one run's line to ``history.jsonl`` (fsynced: a run's wall time is kept)."""
    with (out / "history.jsonl").open("a", encoding="utf-8") as handle:
        handle.write(json.dumps(entry, sort_keys=True) + "\n")
        handle.flush()
        os.fsync(handle.fileno())


def run_task_files(settings: ReproduceRealSettings) -> dict[str, str]:
    """The task TOML of every set the run needs, plain or a variant, by task name.

    Each is the task as run, under the run's sensor, so a reader sees what was run. Built
    before anything is written: a variant whose values a task refuses (a mount offset of 5 m)
    stops the run before it claims a folder.
    """
    return {trial_set.task_name: f"# the task {trial_set.unit.task} ({trial_set.variant}, "
            f"sensor {settings.sensor.value}), written by gva reproduce real\n"
            + task_to_toml(settings.run_task(trial_set)) for trial_set in settings.trial_sets()}


def write_run_tasks(files: dict[str, str], out: Path) -> None:
    """Writes each task file of :func:`run_task_files` into ``out`` (where it changed)."""
    for name, text in files.items():
        path = task_file(out, name)
        if not path.exists() or path.read_text(encoding="utf-8") != text:
            write_text(path, text)


def run_reproduce_real(settings: ReproduceRealSettings, out: str | Path,
                       progress: bool = True) -> ReproduceRealReport:
    """Runs (or resumes) the experiment into ``out``: jobs computed and skipped, outputs.

    Raises:
        RunFolderError: ``out`` holds a run with other shared settings, or a dataset or
            checkpoint made with other settings.
        KeyboardInterrupt: Ctrl-C; what finished is kept and the message says how to resume.
        RunFolderError: Another run holds ``out`` (one run per folder).

    """
    out = Path(out)
    files = run_task_files(settings)  # every task checked before the folder is touched
    with started_run(out, settings.shared_identity()) as (started, session):
        for seed in settings.training_seeds:
            claim_run_folder(seed_folder(out, seed), settings.for_seed(seed).run_identity())
            write_run_tasks(files, seed_folder(out, seed))
        try:
            computed, skipped = run_jobs(settings, out, progress)
        except KeyboardInterrupt:
            raise KeyboardInterrupt(f"finished datasets, checkpoints and trials are kept in {out}; "
                                    f"resume with: {settings.command(out)}") from None
        wall_time_s = time.perf_counter() - started
        append_history(out, {"command": settings.command(out), "wall_time_s": round(wall_time_s, 1),
                             "computed": [o.name for o in computed], "skipped": len(skipped),
                             "jobs": [o.timeline() for o in computed],
                             "workers": settings.worker_count(), "finished_at": time.time()})
        reports = write_reports(settings, out, wall_time_s, session)
        return RunReport(tuple(computed), tuple(skipped), tuple(reports.failed), wall_time_s,
                         tuple(reports.paths), tuple(reports.notes), reports.table)
