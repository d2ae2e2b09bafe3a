"""How long the paper's Table II takes in simulation: ``gva reproduce sim``, timed.

    python benchmarks/bench_reproduce_sim.py --out runs/table2 [other gva reproduce sim options]
    python benchmarks/bench_reproduce_sim.py --from runs/table2   # read a finished run's table

Every argument but ``--from`` and ``--result`` goes to ``gva reproduce sim``. The record
(``benchmarks/results/reproduce_sim.json`` by default) holds the wall time of the command's
last run and how many cells it computed (a resumed run computes only the rest, so its wall
time is the whole table's only when it computed every cell), the cell count, the median and
total training time per model, and the machine (CPUs, load average), so a time can be judged
against how busy the machine was.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

from results_file import add_out_option, write_record

from experiments.cli import build_parser, main
from experiments.tables import PAPER_MODELS


def record(folder: Path, measured_s: float | None) -> dict[str, Any]:
    """The timing record of the run folder ``folder`` (its ``table2.json``)."""
    table = json.loads((folder / "table2.json").read_text())
    train_s: dict[str, list[float]] = defaultdict(list)
    for cell in table["cells"]:
        train_s[cell["model"]].append(cell["train_s"])
    return {
        "benchmark": "reproduce_sim",
        "command": table["settings"]["command"],
        "folder": str(folder),
        "wall_time_s": round(table["wall_time_s"], 1),
        "measured_wall_time_s": None if measured_s is None else round(measured_s, 1),
        "cells": len(table["cells"]),
        "cells_computed_in_last_run": table["cells_computed"],
        "whole_table_in_last_run": table["cells_computed"] == len(table["cells"]) + len(
            table["failed"]),
        "failed": len(table["failed"]),
        "workers": table["settings"]["workers"],
        "steps": table["settings"]["train"]["steps"],
        "seeds": table["settings"]["seeds"],
        "median_train_s": {m: round(statistics.median(train_s[m]), 1)
                           for m in PAPER_MODELS if m in train_s},
        "total_train_s": {m: round(sum(train_s[m]), 1) for m in PAPER_MODELS if m in train_s},
        "judged": judged(table["cells"]),
        "machine": machine(),
    }


def judged(cells: list[dict[str, Any]]) -> dict[str, Any] | None:
    """Per model and task, the grasp judge's predicted success: per seed, pooled, per object.

    Pooled over the seeds' targets (each seed scores the same number of test scenes); None
    where no cell was judged (position labels, or cells made before the judge).
    """
    found: dict[str, dict[str, Any]] = {}
    for cell in cells:
        result = cell.get("judged")
        if not result:
            continue
        entry = found.setdefault(cell["model"], {}).setdefault(
            f"{cell['task']} ({cell['size']})", {"per_seed": {}, "targets": 0, "picked": 0.0,
                                                 "per_object": {}})
        rate = result["all"]["predicted_success_rate"]
        entry["per_seed"][str(cell["seed"])] = round(rate, 4)
        entry["targets"] += result["all"]["targets"]
        entry["picked"] += rate * result["all"]["targets"]
        for name, group in result["per_object"].items():
            counts = entry["per_object"].setdefault(name, [0.0, 0])
            counts[0] += group["predicted_success_rate"] * group["targets"]
            counts[1] += group["targets"]
    for tasks in found.values():
        for entry in tasks.values():
            entry["pooled"] = round(entry.pop("picked") / entry["targets"], 4)
            entry["worst_seed"] = min(entry["per_seed"].values())
            entry["per_object"] = {name: round(picked / n, 4)
                                   for name, (picked, n) in sorted(entry["per_object"].items())}
    return found or None


def machine() -> dict[str, Any]:
    """The machine a timing was taken on: CPUs, load average, Python, platform."""
    return {"cpus": os.cpu_count(), "cpus_usable": len(os.sched_getaffinity(0)),
            "load_average_1_5_15min": [round(v, 2) for v in os.getloadavg()],
            "python": platform.python_version(), "platform": platform.platform()}


def run_or_read(experiment: str, record_name: str,
                record: Callable[[Path, float | None], dict[str, Any]]) -> tuple[int, Any]:
    """Runs ``gva reproduce EXPERIMENT`` timed, or reads ``--from``; writes the record.

    The script's other arguments go to the command; ``record(folder, measured_s)`` is written
    to ``--result`` (default ``benchmarks/results/<record_name>.json``). Returns (exit status,
    the record or None where the run failed outright).
    """
    parser = argparse.ArgumentParser(description=sys.modules["__main__"].__doc__.splitlines()[0],
                                     allow_abbrev=False)
    parser.add_argument("--from", dest="source", type=Path,
                        help="a finished run folder: read its tables, run nothing")
    add_out_option(parser, record_name, flag="--result")
    args, rest = parser.parse_known_args()
    measured = None
    folder = args.source
    if folder is None:
        folder = build_parser().parse_args(["reproduce", experiment, *rest]).out
        started = time.perf_counter()
        status = main(["reproduce", experiment, *rest])
        measured = time.perf_counter() - started
        if status not in (0, 1):  # 1: finished, some jobs failed (the record says how many)
            return status, None
    elif rest:
        parser.error(f"--from reads a finished run; these go nowhere: {' '.join(rest)}")
    result = record(folder, measured)
    write_record(args.result, result)
    return 0, result


def main_bench() -> int:
    status, result = run_or_read("sim", "reproduce_sim", record)
    if result is not None:
        print(f"{result['cells']} cells ({result['cells_computed_in_last_run']} in the last "
              f"run), last run {result['wall_time_s']:.0f} s on {result['workers']} worker(s); "
              f"median training s per model: {result['median_train_s']}")
    return status


if __name__ == "__main__":
    sys.exit(main_bench())
