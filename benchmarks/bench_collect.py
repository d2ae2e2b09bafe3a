"""Wall time of ``gva collect`` for both scenes, median of repeated runs.

    python benchmarks/bench_collect.py [--repeats 3] [--tasks single,multiple,...]
        [--out benchmarks/results/collect.json]

The bars: a 100-scene ``paper-sim`` dataset in <= 60 s, a 20-demonstration ``yumi`` dataset
in <= 120 s, on a 2-core machine. Each run writes a fresh file in a temporary folder.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path

from results_file import add_out_option, write_record

from harness.inputs.collector import CollectSettings, collect
from perception.learning.dataset_file import read_metadata
from sim.tasks.task_toml import builtin_tasks

SIZES = {"paper-sim": 100, "yumi": 20}
BARS_S = {"paper-sim": 60.0, "yumi": 120.0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--tasks", default=",".join(builtin_tasks()))
    parser.add_argument("--scenes", default="paper-sim,yumi")
    add_out_option(parser, "collect")
    args = parser.parse_args()

    rows = []
    for scene in args.scenes.split(","):
        for task in args.tasks.split(","):
            times, redrawn = [], []
            for repeat in range(args.repeats):
                with tempfile.TemporaryDirectory() as folder:
                    path = Path(folder) / "data.gva"
                    started = time.perf_counter()
                    collect(CollectSettings(scene, task, SIZES[scene], seed=repeat), path,
                            progress=False)
                    times.append(time.perf_counter() - started)
                    redrawn.append(read_metadata(path).extra.get("demonstrations_redrawn", 0))
            median = statistics.median(times)
            rows.append({"scene": scene, "task": task, "size": SIZES[scene],
                         "median_s": round(median, 2), "runs_s": [round(t, 2) for t in times],
                         "bar_s": BARS_S[scene], "within_bar": median <= BARS_S[scene],
                         "demonstrations_redrawn": redrawn})
            print(f"{scene:<9} {task:<18} {SIZES[scene]:>3} scenes: median {median:6.1f} s "
                  f"(bar {BARS_S[scene]:.0f} s; runs {', '.join(f'{t:.1f}' for t in times)}; "
                  f"redrawn {redrawn})")
    result = {"machine": {"cpu_count": os.cpu_count(), "python": platform.python_version()},
              "repeats": args.repeats, "rows": rows}
    write_record(args.out, result)


if __name__ == "__main__":
    main()
