"""Where a Table III run's time goes: each job, each training's phases, the workers' idle time.

    python benchmarks/bench_table3_profile.py --out runs/profile --seeds 1 --seed 10 \
        --workers 2 --no-robustness          # runs gva reproduce real, then profiles it
    python benchmarks/bench_table3_profile.py --from runs/table3   # profiles a finished run

Every argument but ``--from`` and ``--result`` goes to ``gva reproduce real``. Read from the run
folder: ``history.jsonl`` (the last run's jobs: start, wall and CPU time, worker) and each
checkpoint's ``trained.json`` (the training's phases: kqv's starts, the main phase, the type
head; the held-out check and any retry). The record (``benchmarks/results/table3_profile.json``)
holds per kind of job and task the wall and CPU seconds, per training its phases, the cores'
idle time (a core that waits while a job could run is time lost), and, where
``benchmarks/results/train.json`` exists (``bench_train.py``), the work of a training in GFLOP
and the rate a step reaches against the core's matmul rate.
"""

from __future__ import annotations

import json
import re
import statistics
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

from bench_reproduce_sim import machine, run_or_read

JOB_NAME = re.compile(r"(?P<kind>collect|train|trials|gif)-(?P<what>.+)-s(?P<seed>\d+)")
TRAIN_STEP_FILE = Path("benchmarks/results/train.json")


def last_run(folder: Path) -> dict[str, Any]:
    """The last line of the run folder's ``history.jsonl``."""
    lines = (folder / "history.jsonl").read_text().splitlines()
    return json.loads(lines[-1])


def job_kinds(jobs: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Wall and CPU seconds per kind of job and what it is for (``train/kqv-single``)."""
    groups: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for job in jobs:
        match = JOB_NAME.fullmatch(job["name"])
        key = f"{match['kind']}/{match['what']}" if match else job["name"]
        groups[key].append(job)
    return {key: {"jobs": len(group), "wall_s": round(sum(j["seconds"] for j in group), 1),
                  "cpu_s": round(sum(j["cpu_s"] for j in group), 1),
                  "median_wall_s": round(statistics.median(j["seconds"] for j in group), 1)}
            for key, group in sorted(groups.items())}


def workers(jobs: list[dict[str, Any]], cores: int) -> dict[str, Any]:
    """The span from the first job's start to the last one's end, and the cores' idle time.

    A job holds its ``cpus`` (a training on two threads two cores) for its wall time; the
    cores are the run's workers.
    """
    if not jobs:
        return {"cores": cores, "span_s": 0.0, "core_s_held": 0.0, "idle_core_s": 0.0,
                "idle_fraction": None}
    start = min(j["started_at"] for j in jobs)
    span = max(j["started_at"] + j["seconds"] for j in jobs) - start
    held = sum(j["seconds"] * j.get("cpus", 1.0) for j in jobs)
    idle = max(0.0, cores * span - held)
    return {"cores": cores, "span_s": round(span, 1), "core_s_held": round(held, 1),
            "idle_core_s": round(idle, 1), "idle_fraction": round(idle / (cores * span), 3)}


def trainings(folder: Path, seeds: list[int]) -> dict[str, dict[str, Any]]:
    """Each training's phases and attempts, from its ``trained.json``."""
    rows = {}
    for seed in seeds:
        for path in sorted((folder / f"s{seed}" / "checkpoints").glob("*/*/trained.json")):
            trained = json.loads(path.read_text())
            config = json.loads((path.parent / "config.json").read_text())
            settings = config.get("hyperparameters", {})
            times = trained.get("attempt_times", [])
            rows[f"{path.parent.parent.name}-{path.parent.name}-s{seed}"] = {
                "train_s": round(trained["train_s"], 1), "steps": trained["steps"],
                "batch_size": config["training"]["config"]["batch_size"],
                "starts": {key: settings[key] for key in ("starts", "start_steps",
                                                          "start_batch_size") if key in settings},
                "phases": {p["name"]: {"steps": p["steps"], "wall_s": round(p["wall_time_s"], 1)}
                           for p in trained.get("phases", [])},
                "attempts": trained["attempts"],
                "retry_train_s": round(sum(t["train_s"] for t in times[:-1]), 1),
                "check_s": round(sum(t["check_s"] for t in times), 1)}
    return rows


def work(rows: dict[str, dict[str, Any]]) -> dict[str, Any] | None:
    """A kqv training's GFLOP from ``bench_train.py``'s per-step work, and its steps' rate.

    A step's work is taken as proportional to its batch: the starts' steps on smaller batches
    (``start_batch_size``) count as that fraction of a step, and every start counts.
    """
    if not TRAIN_STEP_FILE.exists():
        return None
    steps = json.loads(TRAIN_STEP_FILE.read_text())
    step = steps["rows"].get("yumi/single")
    if step is None:
        return None
    per_training = {}
    for name, row in rows.items():
        if not name.startswith("kqv-"):
            continue
        phases = row["phases"]
        pose = sum(p["steps"] for key, p in phases.items() if key != "object types")
        if "starts" in phases:  # every start's steps, not the kept one's alone
            starts, batch = row["starts"], row["batch_size"]
            fraction = (starts.get("start_batch_size") or batch) / batch  # work ~ batch
            pose += starts["start_steps"] * (starts["starts"] * fraction - 1)
        types = phases.get("object types", {}).get("steps", 0)
        per_training[name] = round(pose * step["step_gflop"]
                                   + types * step.get("type_step_gflop", 0.0), 1)
    return {"step_gflop": step["step_gflop"], "step_gflop_per_s": step["step_gflop_per_s"],
            "matmul_gflop_per_s": steps["matmul_1024_gflop_per_s"],
            "fraction_of_matmul_rate": step["fraction_of_matmul_rate"],
            "gflop_per_training": per_training}


def record(folder: Path, measured_s: float | None) -> dict[str, Any]:
    """The profile of the run folder ``folder``'s last run."""
    table = json.loads((folder / "table3.json").read_text())
    run = last_run(folder)
    jobs = run.get("jobs", [])
    rows = trainings(folder, table["seeds"])
    kinds = job_kinds(jobs)
    by_kind: dict[str, float] = defaultdict(float)
    for key, entry in kinds.items():
        by_kind[key.split("/")[0]] += entry["wall_s"]
    return {
        "benchmark": "table3_profile", "command": table["settings"]["command"],
        "folder": str(folder), "seeds": table["seeds"],
        "wall_time_s": run["wall_time_s"],
        "measured_wall_time_s": None if measured_s is None else round(measured_s, 1),
        "jobs_in_last_run": len(jobs),
        "wall_s_by_kind": {k: round(v, 1) for k, v in sorted(by_kind.items())},
        "jobs": kinds, "cores": workers(jobs, run["workers"]), "trainings": rows,
        "work": work(rows), "machine": machine(),
    }


def main_bench() -> int:
    """Runs ``gva reproduce real`` (or reads ``--from``) and writes the profile."""
    status, result = run_or_read("real", "table3_profile", record)
    if result is not None:
        print(json.dumps({k: result[k] for k in ("wall_time_s", "wall_s_by_kind", "cores",
                                                 "work")}, indent=2))
    return status


if __name__ == "__main__":
    sys.exit(main_bench())
