"""Whether the Panda holds a sponge grasp turned about its approach, opened 50 mm or 80 mm.

The catalog opens every grasp to 50 mm, the YuMi's full stroke; the Panda's hand opens 80 mm.
This runs the oracle's grasp turned on purpose by 0-50 degrees about the approach axis (the sign
alternating scene by scene), the Panda picking through the trial runner (the same planner,
depth obstacles and physics as ``gva trials``), with the opening the grasp states, on the
sponge scenes of the ``single`` task's test stream at :data:`SEED` (no Table III run draws it),
seen through the D435-like sensor as Table III is.

Usage:
    python studies/check_panda_opening.py [--scenes 8] [--openings-mm 50,80]
        [--turns-deg 0,20,30,40,50] [--out benchmarks/results/panda_opening.json]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import numpy as np
from results_file import write_record
from tqdm import tqdm

from perception.interface import NO_CONDITION, Condition, Prediction, Target
from perception.poses import rot_z
from robots import get_robot
from sim.tasks.scene_sampling import Scene, SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_spec import TaskSpec, spaced_for
from sim.tasks.task_toml import load_task
from sim.trials.oracle import OraclePerception
from sim.trials.trial_runner import TrialRunner
from sim.world.sensor import SensorConfig, SensorKind

SEED = 777
"""The test stream the scenes come from."""
OBJECT = "sponge"


class TurnedOracle(OraclePerception):
    """The oracle's grasps turned ``turn_rad`` about the TCP's z, opened ``opening_m``."""

    turn_rad = 0.0
    opening_m = 0.05

    def predict(self, image: np.ndarray, condition: Condition = NO_CONDITION) -> Prediction:
        """The true grasps, each turned and stating the opening."""
        truth = super().predict(image, condition)
        targets = tuple(Target(t.position_m, t.rotation @ rot_z(self.turn_rad), t.object_type,
                               opening_m=self.opening_m)
                        for t in truth.targets if t.rotation is not None)
        return Prediction(targets, truth.attention_px, truth.heatmaps)


def panda_task() -> TaskSpec:
    """``single`` as Table III runs it on the Panda: spaced for its hand, through a D435."""
    task = replace(load_task("single"), camera=SensorConfig(SensorKind.D435))
    return spaced_for(task, get_robot("panda").neighbour_spacing_m)


def sponge_scenes(task: TaskSpec, count: int) -> list[Scene]:
    """The first ``count`` scenes of ``task``'s test stream whose target is a sponge."""
    scenes = []
    for index in range(50 * count):
        scene = sample_scene(task, YUMI_SCENE, SEED, SeedStream.TEST, index)
        if scene.objects[scene.targets[0]].object_type == OBJECT:
            scenes.append(scene)
            if len(scenes) == count:
                return scenes
    raise RuntimeError(f"fewer than {count} {OBJECT} scenes in {50 * count}")


def main(argv: list[str] | None = None) -> dict[str, dict[str, list[str]]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=8, help="sponge scenes per cell")
    parser.add_argument("--openings-mm", default="50,80")
    parser.add_argument("--turns-deg", default="0,20,30,40,50")
    parser.add_argument("--out", type=Path, default=None, help="write the record here")
    args = parser.parse_args(argv)
    openings = [float(v) for v in args.openings_mm.split(",")]
    turns = [float(v) for v in args.turns_deg.split(",")]
    task = panda_task()
    scenes = sponge_scenes(task, args.scenes)
    outcomes: dict[str, dict[str, list[str]]] = {}
    start = time.perf_counter()
    with TrialRunner(task, TurnedOracle, robot=get_robot("panda")) as runner, tqdm(
            total=len(openings) * len(turns) * len(scenes), unit="pick") as bar:
        model = runner.model
        assert isinstance(model, TurnedOracle)
        for opening_mm in openings:
            row = outcomes.setdefault(f"{opening_mm:g}", {})
            model.opening_m = opening_mm / 1000
            for turn_deg in turns:
                picks = []
                for k, scene in enumerate(scenes):
                    model.turn_rad = math.radians(turn_deg) * (1 if k % 2 else -1)
                    picks.append(runner.run(scene, scene.index, SEED, "turned").outcome.value)
                    bar.update()
                row[f"{turn_deg:g}"] = picks
    for opening, row in outcomes.items():
        held = ", ".join(f"{turn} deg {p.count('success')}/{len(p)}" for turn, p in row.items())
        print(f"opened {opening} mm: {held}")
    if args.out is not None:
        write_record(args.out, {
            "how": {"seed": SEED, "object": OBJECT, "scenes": [s.index for s in scenes],
                    "robot": "panda", "wall_time_s": round(time.perf_counter() - start, 1)},
            "outcomes_by_opening_mm_and_turn_deg": outcomes}, indent=1, announce=False)
    return outcomes


if __name__ == "__main__":
    main()
