"""Runs ``gva reproduce real`` (:mod:`experiments.table3.settings`) into a run folder.

Claims the folder and each seed's, writes the variant task files, runs the jobs
(:mod:`experiments.table3.jobs`), appends the run to ``history.jsonl`` and rebuilds the reports
(:mod:`experiments.table3.report`). The settings, paths and layout live in
:mod:`experiments.table3.settings`, which imports none of these.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from experiments.table3.jobs import run_jobs
from experiments.table3.report import write_reports
from experiments.table3.settings import ReproduceRealSettings, seed_folder, write_variant_tasks
from sim.records import claim_run_folder


def append_history(out: Path, entry: dict[str, Any]) -> None:
    """Appends one run's line to ``history.jsonl`` (fsynced: a run's wall time is kept)."""
    with (out / "history.jsonl").open("a", encoding="utf-8") as handle:
        handle.write(json.dumps(entry, sort_keys=True) + "\n")
        handle.flush()
        os.fsync(handle.fileno())


@dataclass(frozen=True)
class ReproduceRealReport:
    """What a run did: jobs computed (with their failures) and skipped, and its outputs.

    ``wall_time_s`` covers collecting, training, trials and GIFs, not the reports after.
    """

    computed: tuple[Any, ...]
    skipped: tuple[str, ...]
    failed: tuple[dict[str, Any], ...]
    wall_time_s: float
    outputs: tuple[Path, ...] = field(default_factory=tuple)
    notes: tuple[str, ...] = field(default_factory=tuple)
    table: str = ""  # the successes table of table3.md


def run_reproduce_real(settings: ReproduceRealSettings, out: str | Path,
                       progress: bool = True) -> ReproduceRealReport:
    """Runs (or resumes) the experiment into ``out`` (:mod:`experiments.table3.settings`).

    Raises:
        RunFolderError: ``out`` holds a run with other shared settings, or a dataset or
            checkpoint made with other settings.
        KeyboardInterrupt: Ctrl-C; what finished is kept and the message says how to resume.

    """
    out = Path(out)
    started = time.perf_counter()
    claim_run_folder(out, settings.shared_identity())
    for seed in settings.training_seeds:
        claim_run_folder(seed_folder(out, seed), settings.for_seed(seed).run_identity())
        write_variant_tasks(settings, seed_folder(out, seed))
    try:
        computed, skipped = run_jobs(settings, out, progress)
    except KeyboardInterrupt:
        raise KeyboardInterrupt(f"finished datasets, checkpoints and trials are kept in {out}; "
                                f"resume with: {settings.command(out)}") from None
    wall_time_s = time.perf_counter() - started
    append_history(out, {"command": settings.command(out), "wall_time_s": round(wall_time_s, 1),
                         "computed": [o.name for o in computed], "skipped": len(skipped),
                         "workers": settings.worker_count(), "finished_at": time.time()})
    reports = write_reports(settings, out, wall_time_s)
    return ReproduceRealReport(tuple(computed), tuple(skipped), tuple(reports.failed),
                               wall_time_s, tuple(reports.paths), tuple(reports.notes),
                               reports.table)
