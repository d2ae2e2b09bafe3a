"""How accurate must a perception model be? Oracle pick trials with a fixed error added.

    python benchmarks/bench_grasp_tolerance.py [--error 1,0 --error 0,30 ...] [--n 30]
        [--task single] [--out benchmarks/results/grasp_tolerance.json]

Each ``--error CM,DEG`` runs ``--n`` trials of the task (test scenes of seed 0) with the
oracle's grasp moved ``CM`` centimetres in a random horizontal direction and turned ``±DEG``
degrees about the world's vertical axis: the accuracy a learned model needs for the pick to
succeed (issue 6). Success is judged by physics, exactly as in ``gva trials``.
"""

from __future__ import annotations

import argparse
import json
import math
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from perception.interface import NO_CONDITION, Condition, Prediction, Target
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task
from sim.trials.oracle import OraclePerception
from sim.trials.trial_runner import TrialRunner
from sim.world.head_camera import HeadCamera
from sim.world.yumi_world import World


def rot_z(angle_rad: float) -> np.ndarray:
    """A turn about the world's z axis."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def perturbed_oracle(error_cm: float, error_deg: float, seed: int) -> Any:
    """A model factory: the oracle, each grasp moved ``error_cm`` and turned ``±error_deg``."""
    rng = np.random.default_rng(seed)

    class Perturbed(OraclePerception):
        def predict(self, image: np.ndarray, condition: Condition = NO_CONDITION) -> Prediction:
            truth = super().predict(image, condition)
            targets = []
            for target in truth.targets:
                direction = rng.uniform(0.0, 2.0 * math.pi)
                shift_m = error_cm / 100 * np.array([math.cos(direction), math.sin(direction), 0])
                turn = rot_z(float(rng.choice([-1.0, 1.0])) * math.radians(error_deg))
                rotation = None if target.rotation is None else turn @ target.rotation
                targets.append(Target(target.position_m + shift_m, rotation, target.object_type))
            return Prediction(tuple(targets), truth.attention_px, truth.heatmaps)

    def factory(world: World, camera: HeadCamera) -> OraclePerception:
        return Perturbed(world, camera)

    return factory


def run(task_name: str, error_cm: float, error_deg: float, n: int) -> dict[str, Any]:
    """``n`` trials with one error; outcome counts overall and per object type."""
    task = load_task(task_name)
    outcomes: Counter[str] = Counter()
    per_object: Counter[str] = Counter()
    with TrialRunner(task, perturbed_oracle(error_cm, error_deg, seed=7)) as runner:
        for index in range(n):
            scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, index)
            record = runner.run(scene, index, 0, "perturbed-oracle")
            outcomes[record.outcome.value] += 1
            per_object[f"{scene.objects[scene.targets[0]].object_type}: "
                       f"{record.outcome.value}"] += 1
    row = {"error_cm": error_cm, "error_deg": error_deg, "n": n,
           "successes": outcomes["success"], "outcomes": dict(outcomes),
           "per_object": dict(sorted(per_object.items()))}
    print(f"{error_cm} cm, ±{error_deg}°: {row['successes']}/{n}  {row['per_object']}")
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--error", action="append", default=[], metavar="CM,DEG",
                        help="grasp error to add (repeatable; default: 1,0 2,0 0,15 0,30)")
    parser.add_argument("--n", type=int, default=30)
    parser.add_argument("--task", default="single")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/grasp_tolerance.json"))
    args = parser.parse_args()
    errors = [tuple(float(v) for v in e.split(",")) for e in args.error] or \
        [(1.0, 0.0), (2.0, 0.0), (0.0, 15.0), (0.0, 30.0)]
    rows = [run(args.task, cm, deg, args.n) for cm, deg in errors]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"benchmark": "grasp_tolerance", "task": args.task,
                                    "rows": rows}, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
