"""The Ray executor against the local pool on the same work: wall time, and the same results.

    python benchmarks/bench_ray_executor.py [--repeats 3] [--out FILE]

Runs the small Table II the issue names (``--models kqv,fcn --tasks single --sizes 4,20
--seeds 2``, otherwise the defaults: 1000 steps, 100 test scenes) and one one-task Table III
(``--tasks single --no-robustness``, 300 steps, 30 trials) with ``--executor local`` and
``--executor ray``, two workers each, ``--repeats`` times in alternating order, every run a
fresh ``gva`` process in a fresh folder. It reports each run's wall time (Ray's includes
starting and stopping its local Ray), the median ratio Ray / local (the bar: <= 1.15 on a 2-core
machine), and Ray's fixed cost measured alone: ``ray.init``, a first task's round trip and
``ray.shutdown``, the median of as many starts. A short run pays that as much as a long one
(what shorter runs gave: docs/decisions/ray-executor.md). It also checks that both
executors wrote the same ``table2.json`` cells and the same ``table3.json`` counts, and exits 1
where they differ.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from results_file import add_out_option, write_record

GVA = str(Path(sys.executable).with_name("gva"))
TABLE2 = ["reproduce", "sim", "--models", "kqv,fcn", "--tasks", "single", "--sizes", "4,20",
          "--seeds", "2", "--workers", "2"]
TABLE3 = ["reproduce", "real", "--tasks", "single", "--no-robustness", "--steps", "300",
          "--workers", "2"]
STARTUP = """
import time
started = time.perf_counter()
from harness.ray_jobs import ray, start_local_ray
start_local_ray(2)
ray.get(ray.remote(lambda: 0).remote())
ray.shutdown()
print(time.perf_counter() - started)
"""


def _run(command: list[str], executor: str, out: Path) -> float:
    """One fresh ``gva`` run into ``out``; its wall time [s]."""
    started = time.perf_counter()
    subprocess.run([GVA, *command, "--out", str(out), "--executor", executor, "--no-progress"],
                   check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started


def _table2_cells(out: Path) -> list[dict]:
    cells = json.loads((out / "table2.json").read_text())["cells"]
    return [{k: v for k, v in cell.items() if k != "train_s"} for cell in cells]


def _table3_counts(out: Path) -> dict:
    tasks = json.loads((out / "table3.json").read_text())["tasks"]
    return {task: [(s["seed"], s["successes"], s["n"]) for s in row["per_seed"]]
            for task, row in tasks.items()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    add_out_option(parser, "ray_executor")
    args = parser.parse_args()

    result: dict = {"machine": {"cpu_count": os.cpu_count(),
                                "python": platform.python_version(),
                                "platform": platform.platform()},
                    "workers": 2, "repeats": args.repeats}
    same = True
    for name, command, outcome in (("table2", TABLE2, _table2_cells),
                                   ("table3", TABLE3, _table3_counts)):
        wall: dict[str, list[float]] = {"local": [], "ray": []}
        seen: dict[str, list] = {"local": [], "ray": []}
        for repeat in range(args.repeats):
            order = ("local", "ray") if repeat % 2 == 0 else ("ray", "local")
            for executor in order:
                with tempfile.TemporaryDirectory() as folder:
                    wall[executor].append(_run(command, executor, Path(folder) / "run"))
                    seen[executor].append(outcome(Path(folder) / "run"))
                print(f"{name} {executor} run {repeat}: {wall[executor][-1]:.1f} s", flush=True)
        agree = all(result_ == seen["local"][0] for runs in seen.values() for result_ in runs)
        same &= agree
        ratios = [ray / local for ray, local in zip(wall["ray"], wall["local"], strict=True)]
        result[name] = {"command": "gva " + " ".join(command),
                        "wall_s": {k: [round(v, 1) for v in vs] for k, vs in wall.items()},
                        "median_wall_s": {k: round(statistics.median(vs), 1)
                                          for k, vs in wall.items()},
                        "median_ratio_ray_over_local": round(statistics.median(ratios), 3),
                        "identical_results": agree, "results": seen["local"][0]}
        print(f"{name}: median ray / local = {statistics.median(ratios):.3f}; "
              f"identical results: {agree}", flush=True)

    startup = [float(subprocess.run([sys.executable, "-c", STARTUP], check=True,
                                    capture_output=True, text=True).stdout.split()[-1])
               for _ in range(args.repeats)]
    result["ray_start_and_stop_s"] = {"runs": [round(s, 2) for s in startup],
                                      "median": round(statistics.median(startup), 2)}
    print(f"Ray's start and stop (init, a first task, shutdown): median "
          f"{statistics.median(startup):.1f} s")
    write_record(args.out, result)
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
