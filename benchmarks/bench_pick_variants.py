"""Oracle pick trials under the choices a trial makes for the robot: grip and hidden space.

    python benchmarks/bench_pick_variants.py [--n 30] [--seeds 0] [--variants untyped occupied]
        [--out benchmarks/results/pick_variants.json]

Each variant runs the oracle's trials on all four yumi tasks, from the same test scenes as
``gva trials --model oracle``, and counts successes, outcomes and picks per object type:

* ``stated``: as ``gva trials`` runs (the oracle names each target's type; hidden space free);
* ``untyped``: the oracle names no type, so every pick takes the default grip
  (:data:`sim.world.grip.DEFAULT_GRIP`): does it suit every catalog object?
* ``occupied``: hidden space behind what the camera sees counts as occupied
  (:class:`control.depth_obstacles.OccludedSpace`): what would the cautious choice cost?
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import time
from collections import Counter
from typing import Any

from results_file import add_out_option, write_record
from tqdm import tqdm

from control.depth_obstacles import OccludedSpace
from perception.interface import NO_CONDITION, Condition, Prediction
from robots.yumi import YUMI
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task
from sim.trials.oracle import OraclePerception
from sim.trials.planner_setup import depth_config
from sim.trials.trial_runner import TrialRunner

TASKS = ("single", "multiple", "selected-type", "selected-position")
VARIANTS = ("stated", "untyped", "occupied")


class UntypedOracle(OraclePerception):
    """The oracle's grasps without the object types: the trial falls back on the default grip."""

    def predict(self, image: Any, condition: Condition = NO_CONDITION) -> Prediction:
        """The oracle's prediction with ``object_type`` left out."""
        return super().predict(image, condition).without_types()


def run(variant: str, task_name: str, n: int, seed: int) -> dict[str, Any]:
    task = load_task(task_name)
    model = UntypedOracle if variant == "untyped" else OraclePerception
    depth = dataclasses.replace(depth_config(YUMI), occluded=OccludedSpace.OCCUPIED) \
        if variant == "occupied" else None
    outcomes: Counter[str] = Counter()
    picked: dict[str, list[int]] = {}
    failures: list[dict[str, Any]] = []
    started = time.perf_counter()
    with TrialRunner(task, model, depth=depth, robot=YUMI) as runner:
        for index in tqdm(range(n), desc=f"{variant} / {task_name} / seed {seed}", unit="trial"):
            scene = sample_scene(task, YUMI_SCENE, seed, SeedStream.TEST, index)
            record = runner.run(scene, index, seed, f"oracle-{variant}")
            outcomes[record.outcome.value] += 1
            if not record.success:
                failures.append({"index": index, "target": record.target,
                                 "outcome": record.outcome.value, "reason": record.reason[:300]})
            for pick in record.picks:
                counts = picked.setdefault(pick["target"], [0, 0])
                counts[0] += pick["outcome"] == "success"
                counts[1] += 1
    return {"variant": variant, "task": task_name, "seed": seed, "n": n,
            "successes": outcomes["success"], "outcomes": dict(outcomes),
            "picks_by_object": {k: f"{v[0]}/{v[1]}" for k, v in sorted(picked.items())},
            "failures": failures, "wall_s": round(time.perf_counter() - started, 1)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=30)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--variants", nargs="+", choices=VARIANTS, default=["untyped",
                                                                          "occupied"])
    add_out_option(parser, "pick_variants")
    args = parser.parse_args()
    runs = []
    for variant in args.variants:
        for seed in args.seeds:
            for task in TASKS:
                runs.append(run(variant, task, args.n, seed))
                last = runs[-1]
                print(f"{variant} / {task} / seed {seed}: {last['successes']}/{args.n} "
                      f"{last['outcomes']} picks {last['picks_by_object']}")
    result = {"machine": {"cpu_count": os.cpu_count(), "python": platform.python_version(),
                          "processor": platform.processor() or platform.machine()},
              "runs": runs}
    write_record(args.out, result)


if __name__ == "__main__":
    main()
