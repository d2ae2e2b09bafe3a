"""A Ray node lost in the middle of a run: the run still finishes with every cell, none twice.

    python studies/check_ray_node_loss.py [--out benchmarks/results/ray_node_loss.json]

Starts a two-node Ray on this machine (``ray.cluster_utils.Cluster``: a head and a worker
node of one CPU each, both seeing this machine's disk as a cluster sees shared storage), runs
a small ``gva reproduce sim`` on it with ``--executor ray --ray-address``, and removes the
worker node, its raylet and worker processes killed, while one of its cells runs. It then
checks that every cell was computed exactly once and that ``table2.json`` holds each cell, and
writes what it saw. Exit status 1 if not, or if no cell was running on the node when it went.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import ray
from ray.cluster_utils import Cluster
from results_file import add_out_option, write_record

from experiments.table2.run import run_reproduce_sim
from experiments.table2.settings import ReproduceSimSettings
from harness.jobs import Executor, ExecutorKind

SETTINGS = ReproduceSimSettings(models=("kqv", "fcn"), tasks=("single",), sizes=(4, 20),
                                seeds=1, steps=200, test_scenes=20, workers=2)


def _running_on(node: Any) -> list[str]:
    """The names of the tasks running on a node now: its raylet's workers that are not idle.

    Ray titles a worker process ``ray::<task name>`` while it runs a task (``ray::IDLE``
    between tasks); the state API would need the dashboard, which a run does not start.
    """
    raylet = node.all_processes["raylet"][0].process.pid
    names = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            parent = int(stat.read_text().rsplit(")", 1)[1].split()[1])
            title = (stat.parent / "cmdline").read_bytes().split(b"\0")[0].decode()
        except (OSError, IndexError, ValueError):
            continue  # the process ended while we read it
        if parent == raylet and title.startswith("ray::") and title != "ray::IDLE":
            names.append(title.removeprefix("ray::"))
    return names


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_out_option(parser, "ray_node_loss")
    args = parser.parse_args()

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    worker = cluster.add_node(num_cpus=1)
    cluster.wait_for_nodes()
    ray.init(address=cluster.address)
    executor = Executor(ExecutorKind.RAY, ray_address=cluster.address)
    report: list = []
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "run"
        run = threading.Thread(target=lambda: report.append(run_reproduce_sim(
            dataclasses.replace(SETTINGS, executor=executor), out, progress=False)))
        started = time.perf_counter()
        run.start()
        cells = {cell.name for cell in SETTINGS.cells()}
        lost: list[str] = []
        while run.is_alive() and not lost:  # wait until a cell runs on the worker node
            time.sleep(1.0)
            lost = [name for name in _running_on(worker) if name in cells]
        if lost:
            time.sleep(5.0)  # well into its training
            lost = [name for name in _running_on(worker) if name in cells]
            cluster.remove_node(worker)
            print(f"removed the worker node while it ran {lost}", flush=True)
        run.join()
        wall_s = time.perf_counter() - started
        table = json.loads((out / "table2.json").read_text())["cells"]
        computed = Counter(outcome.cell.name for outcome in report[0].computed)
    ray.shutdown()
    cluster.shutdown()

    expected = sorted(cell.name for cell in SETTINGS.cells())
    in_table = sorted(f"{c['model']}-{c['task']}-{c['size']}-s{c['seed']}" for c in table)
    ok = bool(lost) and sorted(computed) == expected and in_table == expected and \
        all(count == 1 for count in computed.values()) and not report[0].failed
    result = {"settings": "gva reproduce sim --models kqv,fcn --tasks single --sizes 4,20 "
                          "--seeds 1 --steps 200 --test-scenes 20 --executor ray",
              "nodes": "head 1 CPU + worker 1 CPU on one machine (ray.cluster_utils.Cluster)",
              "running_on_the_lost_node": lost, "cells_expected": len(expected),
              "cells_computed": dict(computed), "cells_in_table2": len(in_table),
              "failed": [o.cell.name for o in report[0].failed], "wall_s": round(wall_s, 1),
              "passed": ok}
    write_record(args.out, result, announce=False)
    print(json.dumps(result, indent=2))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
