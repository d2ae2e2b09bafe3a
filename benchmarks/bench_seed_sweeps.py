"""How long Table III over several seeds takes: ``gva reproduce real --seeds``, timed.

    python benchmarks/bench_seed_sweeps.py --out runs/table3 --seeds 5 [other options]
    python benchmarks/bench_seed_sweeps.py --from runs/table3   # read a finished run

Every argument but ``--from`` and ``--result`` goes to ``gva reproduce real``. The record
(``benchmarks/results/seed_sweeps.json`` by default) holds the wall time of every run into the
folder together (its ``history.jsonl``), the seeds, where the time went (each training's wall
time from its ``trained.json``, the trials' median per trial), the held-out checks, and the
machine, so a time can be judged against how busy the machine was. Table II's sweeps over
seeds are timed by ``bench_reproduce_sim.py``.
"""

from __future__ import annotations

import json
import statistics
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

from bench_reproduce_sim import machine, run_or_read


def record(folder: Path, measured_s: float | None) -> dict[str, Any]:
    """The timing record of the run folder ``folder`` (its ``table3.json`` and seed folders)."""
    table = json.loads((folder / "table3.json").read_text())
    train_s: dict[str, list[float]] = defaultdict(list)
    for seed in table["seeds"]:
        for trained in sorted((folder / f"s{seed}" / "checkpoints").glob("*/*/trained.json")):
            train_s[trained.parent.name].append(json.loads(trained.read_text())["train_s"])
    trials = {f"{model}/{task}": entry["median_wall_time_s"]
              for model, tasks in table["models"].items() for task, entry in tasks.items()}
    return {
        "benchmark": "seed_sweeps",
        "command": table["settings"]["command"],
        "folder": str(folder),
        "seeds": table["seeds"],
        "wall_time_all_runs_s": round(table["wall_time_all_runs_s"], 1),
        "wall_time_last_run_s": round(table["wall_time_s"], 1),
        "measured_wall_time_s": None if measured_s is None else round(measured_s, 1),
        "workers": table["settings"]["workers"],
        "train_threads": table["settings"]["train"]["threads"],
        "median_train_s": {task: round(statistics.median(v), 1) for task, v in train_s.items()},
        "total_train_s": round(sum(sum(v) for v in train_s.values()), 1),
        "median_trial_s": {key: round(value, 2) for key, value in trials.items()},
        "checks_failed": sum(not c["passed"] for c in table["checks"]),
        "checks": len(table["checks"]),
        "failed_jobs": len(table["failed"]),
        "machine": machine(),
    }


def main_bench() -> int:
    """Runs ``gva reproduce real`` (or reads ``--from``) and writes the record."""
    status, result = run_or_read("real", "seed_sweeps", record)
    if result is not None:
        print(json.dumps(result, indent=2))
    return status


if __name__ == "__main__":
    sys.exit(main_bench())
