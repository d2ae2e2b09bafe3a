"""How far off may a grasp be and still hold? The tolerance map the grasp judge reads.

    python benchmarks/bench_grasp_tolerance.py [--n 5] [--workers 2]
        [--out perception/judge/grasp_tolerance.json]
        [--extend perception/judge/grasp_tolerance.json]

Oracle pick trials of the ``single`` task (yumi scene, test scenes of seed :data:`MAP_SEED`,
which no training or Table III run draws), each with the true grasp moved along one axis of
the grasp's own frame (the closing axis, across it, along the approach) and turned about the
approach axis, on a grid per object type: offsets along each axis crossed with turns up to 90
degrees, ``--n`` picks per cell, each on its own scene, a random sign for the offset (but along
the approach, where too deep and too shallow differ) and for the turn. The physics judges,
exactly as in ``gva trials`` (the same runner, planner and depth obstacles). The record is what
:mod:`perception.judge.grasp_tolerance` reads; it keeps how it was made under ``how``.

The grid was measured in passes (:data:`PASSES`: each adds rows and columns where the one before
went from every pick held to none within one step, or stopped while all held); each cell's
scenes and signs follow from its place in its pass, so a run from scratch measures the same
picks.
``--extend FILE`` keeps the cells FILE holds and measures the rest.

``--joint N`` adds, per object type, N picks with every error at once, each drawn uniformly
in a box read off the grid (per axis 1.5 times the largest offset, per turn 1.5 times the
largest turn, that held 3 of 5 or more alone): the grid sees one error at a time, the trials
see several, and a finger 10 mm off on a sponge that also comes 10 mm lower misses where either
alone holds. The judge fits its reading to every pick of both.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from results_file import write_record
from tqdm import tqdm

from harness.jobs import JobPool
from perception.interface import NO_CONDITION, Condition, Prediction, Target
from perception.judge.grasp_tolerance import AXES, READINGS, SIGNED_AXES, TOLERANCE_FORMAT
from perception.objects.catalog import OBJECT_TYPES
from perception.poses import rot_z
from robots.yumi import YUMI
from sim.tasks.scene_sampling import Scene, SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task
from sim.trials.oracle import OraclePerception
from sim.trials.records import TrialOutcome
from sim.trials.trial_runner import TrialRunner
from sim.world.head_camera import HeadCamera
from sim.world.yumi_world import World

MAP_SEED = 4242
"""The seed of the map's scenes: the single task's test stream at this seed."""
SCENES_PER_TYPE = 60
"""Scenes drawn per object type; cell c's picks take scenes c n, c n + 1, ... (wrapping)."""
FIRST_PASS_YAW_DEG = (0.0, 10.0, 20.0, 30.0, 45.0, 60.0, 90.0)
FIRST_PASS_OFFSETS_MM = {
    "closing": (0.0, 3.0, 6.0, 9.0, 12.0, 16.0, 20.0, 25.0),
    "across": (0.0, 5.0, 10.0, 20.0, 30.0, 40.0),
    "approach": (-20.0, -10.0, -5.0, 0.0, 5.0, 10.0, 20.0),
}
SECOND_PASS_OFFSETS_MM = {
    "closing": (0.0, 3.0, 6.0, 7.0, 8.0, 9.0, 12.0, 16.0, 20.0, 25.0, 30.0, 40.0),
    "across": (0.0, 5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 50.0),
    "approach": (-20.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0, 20.0),
}
YAW_DEG = (0.0, 10.0, 20.0, 25.0, 30.0, 35.0, 40.0, 45.0, 60.0, 90.0)
OFFSETS_MM = {**SECOND_PASS_OFFSETS_MM,
              "approach": (-40.0, -30.0, *SECOND_PASS_OFFSETS_MM["approach"], 30.0, 40.0)}
PASSES = (
    (FIRST_PASS_YAW_DEG, FIRST_PASS_OFFSETS_MM),
    (YAW_DEG, SECOND_PASS_OFFSETS_MM),
    (YAW_DEG, OFFSETS_MM),
)
"""The grids, in the order they were measured; each pass measures the cells its grid adds.

The second adds turns of 25, 35 and 40 degrees (the sponge and the bottle went from 5 of 5 to
none between 20 and 45), closing offsets of 7 and 8 mm (the bottle: 5 of 5 at 6 mm, none at 9)
and of 30 and 40 mm (the mug still held 3 of 5 at 25), across offsets of 15 and 50 mm, and an
approach 15 mm deeper (the bottle: all at 10, none at 20). The third adds approaches 30 and
40 mm short and deep: every type held 5 of 5 at 20 mm short, and trained models' picks came
29 mm short (issue 63: bottles the judge read by extrapolation at p = 0.97 missed)."""
THRESHOLD = 0.5
"""The estimated chance at or above which the judge predicts a pick holds (fixed a priori)."""
TASK = "single"


@dataclass(frozen=True)
class Cell:
    """The picks of one grid cell: an object type, an axis, an offset and a turn."""

    object_type: str
    axis: str
    offset_mm: float
    yaw_deg: float
    scenes: tuple[int, ...]  # test-stream indices at MAP_SEED
    seed: int  # of the signs


@dataclass(frozen=True)
class CellResult:
    """How a cell's picks ended."""

    cell: Cell
    picked: int
    outcomes: dict[str, int]


class PerturbedOracle(OraclePerception):
    """The oracle with its grasp moved ``offset_tcp_m`` (in the grasp frame) and turned ``yaw``."""

    offset_tcp_m = np.zeros(3)
    yaw_rad = 0.0

    def predict(self, image: np.ndarray, condition: Condition = NO_CONDITION) -> Prediction:
        """The oracle's grasps, each moved and turned by the cell's error."""
        truth = super().predict(image, condition)
        targets = []
        for target in truth.targets:
            assert target.rotation is not None
            rotation = target.rotation @ rot_z(self.yaw_rad)  # about the TCP's own z
            position = target.position_m + target.rotation @ self.offset_tcp_m
            targets.append(Target(position, rotation, target.object_type))
        return Prediction(tuple(targets), truth.attention_px, truth.heatmaps)


@dataclass(frozen=True)
class JointPick:
    """One pick with several errors at once: offsets in the grasp frame [mm] and a turn [deg]."""

    object_type: str
    scene: int  # test-stream index at MAP_SEED
    offset_mm: tuple[float, float, float]  # closing, across, approach
    yaw_deg: float


@dataclass(frozen=True)
class JointResult:
    """How a joint pick ended."""

    pick: JointPick
    outcome: str


_RUNNER: TrialRunner | None = None


def _perturbed(world: World, camera: HeadCamera) -> PerturbedOracle:
    return PerturbedOracle(world, camera)


def _runner() -> TrialRunner:
    """The worker's runner, made at its first pick and kept for its life."""
    global _RUNNER
    if _RUNNER is None:
        _RUNNER = TrialRunner(load_task(TASK), _perturbed, robot=YUMI)
    return _RUNNER


def run_cell(cell: Cell) -> CellResult:
    """The cell's picks, in the worker's runner."""
    runner = _runner()
    task = runner.task
    model = runner.model
    assert isinstance(model, PerturbedOracle)
    rng = np.random.default_rng(cell.seed)
    picked, outcomes = 0, dict.fromkeys((o.value for o in TrialOutcome), 0)
    for index in cell.scenes:
        scene = sample_scene(task, YUMI_SCENE, MAP_SEED, SeedStream.TEST, index)
        sign = 1.0 if cell.axis in SIGNED_AXES else float(rng.choice([-1.0, 1.0]))
        offset = np.zeros(3)
        offset[AXES.index(cell.axis)] = sign * cell.offset_mm / 1000
        model.offset_tcp_m = offset
        model.yaw_rad = float(rng.choice([-1.0, 1.0])) * math.radians(cell.yaw_deg)
        record = runner.run(scene, index, MAP_SEED, "perturbed-oracle")
        picked += record.success
        outcomes[record.outcome.value] += 1
    return CellResult(cell, picked, {k: v for k, v in outcomes.items() if v})


def run_joint(pick: JointPick) -> JointResult:
    """One joint pick, in the worker's runner."""
    runner = _runner()
    model = runner.model
    assert isinstance(model, PerturbedOracle)
    model.offset_tcp_m = np.asarray(pick.offset_mm) / 1000
    model.yaw_rad = math.radians(pick.yaw_deg)
    scene = sample_scene(runner.task, YUMI_SCENE, MAP_SEED, SeedStream.TEST, pick.scene)
    return JointResult(pick, runner.run(scene, pick.scene, MAP_SEED, "joint").outcome.value)


def joint_box(entry: dict[str, Any]) -> tuple[tuple[float, float, float], float]:
    """Half-widths of a type's joint box: per axis [mm] and the turn [deg] (see ``--joint``)."""
    def held(axis: str) -> float:
        table = entry["axes"][axis]
        return max(abs(o) for o, row in zip(table["offsets_mm"], table["picked"], strict=True)
                   if row[0] >= 3)

    zero = entry["axes"]["closing"]["picked"][0]
    turn = max(y for y, count in zip(entry["yaw_deg"], zero, strict=True) if count >= 3)
    return (1.5 * held("closing"), 1.5 * held("across"), 1.5 * held("approach")), 1.5 * turn


def joint_picks(record: dict[str, Any], n: int) -> list[JointPick]:
    """``n`` joint picks per type, drawn in each type's box, each on the next scene of its pool."""
    pools = scenes_by_type(SCENES_PER_TYPE)
    picks = []
    for kind, object_type in enumerate(OBJECT_TYPES):
        rng = np.random.default_rng(MAP_SEED + 300_000 + kind)
        widths, turn = joint_box(record["types"][object_type])
        for k in range(n):
            offset = tuple(float(rng.uniform(-w, w)) for w in widths)
            picks.append(JointPick(object_type, pools[object_type][k % SCENES_PER_TYPE],
                                   (offset[0], offset[1], offset[2]),
                                   float(rng.uniform(-turn, turn))))
    return picks


def scenes_by_type(count: int) -> dict[str, list[int]]:
    """The first ``count`` test-stream scenes of each object type at :data:`MAP_SEED`."""
    task = load_task(TASK)
    found: dict[str, list[int]] = {t: [] for t in OBJECT_TYPES}
    index = 0
    while min(len(v) for v in found.values()) < count:
        scene: Scene = sample_scene(task, YUMI_SCENE, MAP_SEED, SeedStream.TEST, index)
        kind = scene.objects[scene.targets[0]].object_type
        if len(found[kind]) < count:
            found[kind].append(index)
        index += 1
    return found


def _grid(yaws: tuple[float, ...], offsets: dict[str, tuple[float, ...]]
          ) -> list[tuple[str, float, float]]:
    """(axis, offset, turn) of a grid, the zero offset once per turn (as "closing")."""
    return [(axis, offset, yaw) for axis in AXES for offset in offsets[axis] for yaw in yaws
            if offset != 0.0 or axis == "closing"]


def cells(n: int) -> list[Cell]:
    """Every cell of the map, pass by pass (see :data:`PASSES`)."""
    pools = scenes_by_type(SCENES_PER_TYPE)
    passes: list[list[tuple[str, float, float]]] = []
    for grid in PASSES:
        earlier = {key for keys in passes for key in keys}
        passes.append([key for key in _grid(*grid) if key not in earlier])
    made: list[Cell] = []
    for object_type in OBJECT_TYPES:
        pool = pools[object_type]
        kind = OBJECT_TYPES.index(object_type)
        for p, keys in enumerate(passes):
            for k, (axis, offset, yaw) in enumerate(keys):
                number, seed = 1000 * p + k, MAP_SEED + 100_000 * p + 1000 * kind + k
                scenes = tuple(pool[(number * n + j) % len(pool)] for j in range(n))
                made.append(Cell(object_type, axis, offset, yaw, scenes, seed))
    return made


def kept_results(path: Path, n: int) -> dict[tuple[str, str, float, float], CellResult]:
    """The cells a map file already holds, measured with ``n`` picks each."""
    data = json.loads(path.read_text())
    kept = {}
    for object_type, entry in data["types"].items():
        for axis, table in entry["axes"].items():
            for i, offset in enumerate(table["offsets_mm"]):
                for j, yaw in enumerate(entry["yaw_deg"]):
                    if table["trials"][i][j] != n:
                        continue
                    key = (object_type, "closing" if offset == 0.0 else axis, offset, yaw)
                    cell = Cell(object_type, key[1], offset, yaw, (), 0)
                    kept[key] = CellResult(cell, table["picked"][i][j],
                                           table["outcomes"][i][j])
    return kept


def tolerance_record(results: list[CellResult], n: int, command: str, wall_time_s: float
                     ) -> dict[str, Any]:
    """The map as :mod:`perception.judge.grasp_tolerance` reads it, with how it was made."""
    found = {(r.cell.object_type, r.cell.axis, r.cell.offset_mm, r.cell.yaw_deg): r
             for r in results}
    types: dict[str, Any] = {}
    for object_type in OBJECT_TYPES:
        axes = {}
        for axis in AXES:
            picked, trials, outcomes = [], [], []
            for offset in OFFSETS_MM[axis]:
                kept = "closing" if offset == 0.0 else axis
                row = [found[(object_type, kept, offset, yaw)] for yaw in YAW_DEG]
                picked.append([r.picked for r in row])
                trials.append([sum(r.outcomes.values()) for r in row])
                outcomes.append([r.outcomes for r in row])
            axes[axis] = {"offsets_mm": list(OFFSETS_MM[axis]), "picked": picked,
                          "trials": trials, "outcomes": outcomes}
        types[object_type] = {"yaw_deg": list(YAW_DEG), "axes": axes}
    commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                            check=False).stdout.strip()
    return {
        "format": TOLERANCE_FORMAT,
        "threshold": THRESHOLD,
        "how": {
            "command": command, "commit": commit,
            "date": datetime.date.today().isoformat(),
            "task": TASK, "scene": "yumi", "seed": MAP_SEED, "stream": "test",
            "picks_per_cell": n, "scenes_per_type": SCENES_PER_TYPE,
            "wall_time_s": round(wall_time_s, 1),
            "what": "oracle picks with the grasp moved along one axis of its own frame "
                    "(random sign, but along the approach: + deeper) and turned about the "
                    "approach axis (random sign); judged by physics as in gva trials",
        },
        "types": types,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=5, help="picks per cell (5)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("perception/judge/grasp_tolerance.json"))
    parser.add_argument("--extend", type=Path, metavar="FILE",
                        help="keep the cells FILE holds (same --n) and measure the rest")
    parser.add_argument("--joint", type=int, default=0, metavar="N",
                        help="also N picks per type with every error at once (0: none)")
    parser.add_argument("--reading", choices=READINGS, default="product",
                        help="how the judge reads the map (product: the grid alone; logistic: "
                        "fitted to every pick, which needs --joint); see "
                        "studies/check_tolerance_reading.py")
    args = parser.parse_args()
    kept = {} if args.extend is None else kept_results(args.extend, args.n)
    todo = [c for c in cells(args.n)
            if (c.object_type, c.axis, c.offset_mm, c.yaw_deg) not in kept]
    results: list[CellResult] = list(kept.values())
    started = time.perf_counter()
    with JobPool(args.workers) as pool, tqdm(total=len(todo), unit="cell") as bar:
        def measured(result: CellResult) -> None:
            results.append(result)
            bar.update()

        pool.run(run_cell, todo, on_done=measured)
    command = "python benchmarks/bench_grasp_tolerance.py " + " ".join(sys.argv[1:])
    record = tolerance_record(results, args.n, command.strip(), 0.0)
    joint = joint_picks(record, args.joint)
    done: list[JointResult] = []
    with JobPool(args.workers) as pool, tqdm(total=len(joint), unit="pick") as bar:
        def finished(result: JointResult) -> None:
            done.append(result)
            bar.update()

        pool.run(run_joint, joint, on_done=finished)
    wall = time.perf_counter() - started
    record["how"]["wall_time_s"] = round(wall, 1)
    record["reading"] = args.reading
    for object_type in OBJECT_TYPES:
        these = sorted((r for r in done if r.pick.object_type == object_type),
                       key=lambda r: joint.index(r.pick))
        if these:
            record["types"][object_type]["joint"] = {
                "errors": [[round(v, 3) for v in (*r.pick.offset_mm, r.pick.yaw_deg)]
                           for r in these],
                "columns": ["closing_mm", "across_mm", "approach_mm", "yaw_deg"],
                "picked": [int(r.outcome == TrialOutcome.SUCCESS.value) for r in these],
                "outcomes": [r.outcome for r in these]}
    if args.extend is not None:  # the passes before this one, as their record says
        earlier = json.loads(args.extend.read_text())["how"]
        record["how"]["earlier_passes"] = [*earlier.pop("earlier_passes", []), earlier]
    write_record(args.out, record, indent=1, announce=False)
    for object_type, entry in record["types"].items():
        zero = dict(zip(YAW_DEG, entry["axes"]["closing"]["picked"][0], strict=True))
        print(f"{object_type}: no offset, picked per turn {zero} of {args.n}")
    print(f"{len(todo)} cells measured ({len(kept)} kept), {len(todo) * args.n} picks in "
          f"{wall:.0f} s; wrote {args.out}")


if __name__ == "__main__":
    main()
