"""Wall time of closed-loop oracle pick trials on this machine.

    python benchmarks/bench_trials.py [--n 30] [--seeds 0 1] [--out benchmarks/results/trials.json]

Runs ``gva trials --model oracle --task single`` for each seed in a fresh folder and reports
the median wall time per trial (the bar: <= 2 s on a 2-core machine), with the time spent
planning and the simulated time per trial, plus successes per seed and per object type, and
what starting each trial from a rebuilt world costs (``World.rebuild``, the median of
``--rebuilds``, and its share of the median trial), and a physics step with three objects
resting on the table, awake against asleep (:attr:`WorldConfig.object_sleeping`): the ratio of
the two, measured side by side.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import tempfile
import time
from collections import Counter
from pathlib import Path

from results_file import add_out_option, write_record

from harness.inputs.trial_settings import TrialSettings
from harness.run_loop import run_trials
from perception.objects.catalog import get_object_spec
from robots.yumi import YUMI
from sim.world.world_config import WorldConfig
from sim.world.yumi_world import World


def resting_step_ms(sleeping: bool, steps: int = 480, repeats: int = 5) -> float:
    """Median over ``repeats`` of a step's wall time [ms], three objects at rest on the table."""
    with World(WorldConfig(object_sleeping=sleeping), robot=YUMI) as world:
        for name, xy in (("sponge", (0.35, 0.1)), ("spray_bottle", (0.4, -0.1)),
                         ("mug", (0.3, 0.0))):
            world.add_object(get_object_spec(name), xy, 0.3)
        world.step(60)
        world.sleep_resting_objects()
        times = []
        for _ in range(repeats):
            started = time.perf_counter()
            world.step(steps)
            times.append((time.perf_counter() - started) / steps * 1e3)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=30)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--task", default="single")
    add_out_option(parser, "trials")
    parser.add_argument("--rebuilds", type=int, default=30)
    args = parser.parse_args()

    runs, wall, sim = [], [], []
    picked: Counter[str] = Counter()
    for seed in args.seeds:
        with tempfile.TemporaryDirectory() as folder:
            started = time.perf_counter()
            summary = run_trials(TrialSettings("oracle", args.task, args.n, seed), folder)
            elapsed = time.perf_counter() - started
            records = [json.loads(line) for line in (Path(folder) / "trials.jsonl").open()]
        wall += [r["wall_time_s"] for r in records]
        sim += [r["sim_time_s"] for r in records]
        picked.update(r["target"] for r in records if r["outcome"] == "success")
        runs.append({"seed": seed, "successes": summary.successes, "n": summary.n,
                     "outcomes": {k: v for k, v in summary.outcomes.items() if v},
                     "run_wall_s": round(elapsed, 2)})
        print(f"seed {seed}: {summary.headline()}  ({elapsed:.1f} s for the run)")

    with World(robot=YUMI) as world:
        rebuild_s = []
        for _ in range(args.rebuilds):
            started = time.perf_counter()
            world.rebuild()
            rebuild_s.append(time.perf_counter() - started)
    awake_ms, asleep_ms = resting_step_ms(False), resting_step_ms(True)
    result = {
        "machine": {"cpu_count": __import__("os").cpu_count(), "python": platform.python_version(),
                    "processor": platform.processor() or platform.machine()},
        "task": args.task,
        "runs": runs,
        "median_trial_wall_s": round(statistics.median(wall), 3),
        "p90_trial_wall_s": round(sorted(wall)[int(0.9 * (len(wall) - 1))], 3),
        "median_trial_sim_s": round(statistics.median(sim), 3),
        "real_time_factor": round(statistics.median(sim) / statistics.median(wall), 2),
        "successes_by_object": dict(picked),
        "median_world_rebuild_s": round(statistics.median(rebuild_s), 4),
        "world_rebuild_share_of_median_trial": round(
            statistics.median(rebuild_s) / statistics.median(wall), 3),
        "resting_objects_step_ms": {"awake": round(awake_ms, 4), "asleep": round(asleep_ms, 4),
                                    "awake_over_asleep": round(awake_ms / asleep_ms, 1)},
        "load_average_1_5_15min": [round(v, 2) for v in __import__("os").getloadavg()],
    }
    print(f"median wall time per trial: {result['median_trial_wall_s']} s "
          f"(p90 {result['p90_trial_wall_s']} s; simulated {result['median_trial_sim_s']} s, "
          f"{result['real_time_factor']}x real time)")
    print("successes by object:", dict(picked))
    print(f"a world rebuilt per trial: {result['median_world_rebuild_s']} s (median of "
          f"{args.rebuilds}), {100 * result['world_rebuild_share_of_median_trial']:.1f} % of the "
          "median trial")
    print(f"a step, three objects resting: awake {awake_ms:.3f} ms, asleep {asleep_ms:.3f} ms")
    write_record(args.out, result)


if __name__ == "__main__":
    main()
