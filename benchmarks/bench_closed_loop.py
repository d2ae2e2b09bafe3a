"""Benchmark: one re-prediction cycle of a closed-loop pick (issue 36), each part timed.

For each of ``--n`` test scenes of ``--task`` (seed ``--seed``), the pick is planned from the
first image as a trial plans it, the arm is put at a drawn sample of its approach (moving), the
target is moved 5 cm, and one cycle runs as :class:`sim.trials.closed_loop.loop.ApproachLoop` runs
it, on one thread: the head camera's frame (rendered through the task's sensor, self-filtered:
the arm masked out), the model's prediction, reading the grasp, the view check (the footprint
of the grasp followed, and whether the grasp named is in plain view: both, the worst case), the
depth obstacles, and the re-plan
for the moving arm (IK, every segment's checks, the re-targeted approach:
``PickPlanner.replan``). The record gives each part's median and 95th percentile [ms] and the
rate the whole cycle sustains.

Usage:
    python benchmarks/bench_closed_loop.py --n 30 [--model CHECKPOINT] [--task single]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np
import pinocchio as pin
from results_file import add_out_option, write_record

from control.depth_obstacles import GraspRegion
from control.retarget import trajectory_state
from harness.inputs.trial_settings import TrialSettings, load_trial_model
from perception.objects.catalog import clear_of_table
from robots import yumi
from sim.trials.closed_loop.loop import remembered_points
from sim.trials.closed_loop.loop_settings import LoopSettings
from sim.trials.closed_loop.view import hidden_share, in_plain_view
from sim.trials.planner_setup import pick_obstacles
from sim.trials.trial_models import torch_threads
from sim.trials.trial_runner import TrialRunner
from sim.trials.trial_scenes import trial_scene

T = TypeVar("T")
PARTS = ("render", "predict", "read grasp", "view", "depth obstacles", "re-plan")


def timed(times: dict[str, list[float]], part: str, call: Callable[[], T]) -> T:
    """``call()``, its wall time appended to ``times[part]`` [ms]."""
    started = time.perf_counter()
    result = call()
    times[part].append((time.perf_counter() - started) * 1e3)
    return result


def cycle(runner: TrialRunner, index: int, seed: int, rng: np.random.Generator,
          times: dict[str, list[float]]) -> str:
    """One cycle on scene ``index``; what the re-plan answered."""
    scene = trial_scene(runner.task, seed, index)
    body = runner.setup(scene)[scene.targets[0]]
    first = runner.sight(body)
    planned = runner.plan_pick(first.frame, runner.model.predict_frame(first.frame, scene.given),
                               0, 1)
    if planned.plan is None:
        return f"no first plan: {planned.reason}"
    approach = planned.plan.segments[0].trajectory
    k = int(rng.integers(len(approach.times_s) // 2, len(approach.times_s) - 1))
    state = trajectory_state(approach, k)
    runner.world.robot.reset(dict(zip(yumi.ARM_JOINTS[planned.plan.arm], state.positions,
                                      strict=True)))
    runner.world.move_object(body, 0.05 * np.cos(k), 0.05 * np.sin(k), 0.3)
    sighting = timed(times, "render", lambda: runner.sight(body, self_filter=True))
    prediction = timed(times, "predict",
                       lambda: runner.model.predict_frame(sighting.frame, scene.given))
    read = timed(times, "read grasp", lambda: runner.read_grasp(prediction, 0, 1))
    if read.predicted is None or read.grip is None:
        return f"unseen: {read.reason}"
    followed, named, radius_m = planned.predicted, read.predicted, LoopSettings.footprint_radius_m
    assert followed is not None  # a plan was made from a grasp
    timed(times, "view", lambda: (hidden_share(sighting.frame, followed.position, radius_m),
                                  in_plain_view(sighting.frame, named.position, radius_m)))
    started = time.perf_counter()
    _, remembered = remembered_points(planned.obstacle_image, sighting.frame)
    replanned = runner.plan_pick(sighting.frame, prediction, 0, 1, moving=state,
                                 remembered=remembered)
    whole_ms = (time.perf_counter() - started) * 1e3
    # the obstacles alone, to split the plan phase into perception of space and planning
    raised, _ = clear_of_table(read.predicted, read.grip.opening_m,
                               runner.world.description.arms[0].gripper.fingers)
    region = GraspRegion(pin.SE3(raised.matrix), read.grip.opening_m)
    timed(times, "depth obstacles", lambda: pick_obstacles(
        runner.world, runner.obstacle_source, runner.depth, sighting.frame, region, remembered))
    times["re-plan"].append(max(whole_ms - times["depth obstacles"][-1], 0.0))
    return "retargeted" if replanned.plan is not None else f"kept: {replanned.reason}"


def main(argv: list[str] | None = None) -> int:
    """Times ``--n`` cycles and writes the record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--task", default="single")
    parser.add_argument("--model", default="oracle", help="oracle or a checkpoint folder")
    add_out_option(parser, "closed_loop_cycle")
    args = parser.parse_args(argv)
    settings = TrialSettings(model=args.model, task=args.task, allow_sensor_change=True)
    model = load_trial_model(settings)
    times: dict[str, list[float]] = {part: [] for part in PARTS}
    answers: list[str] = []
    rng = np.random.default_rng(args.seed)
    with torch_threads(1), TrialRunner(settings.task_spec, model.factory,
                                       robot=settings.description()) as runner:
        for index in range(args.n):
            answers.append(cycle(runner, index, args.seed, rng, times))
    medians = {part: statistics.median(values) for part, values in times.items() if values}
    total = sum(medians.values())
    record: dict[str, Any] = {
        "benchmark": "closed_loop_cycle", "model": args.model, "task": args.task,
        "n": args.n, "seed": args.seed, "sensor": settings.task_spec.sensor.kind.value,
        "parts_ms": {part: {"median": round(medians[part], 2),
                            "p95": round(float(np.percentile(times[part], 95)), 2),
                            "share": round(medians[part] / total, 3)}
                     for part in medians},
        "cycle_median_ms": round(total, 2), "sustained_hz": round(1e3 / total, 1),
        "answers": {a: answers.count(a) for a in sorted(set(answers))},
        "machine": {"cpus": os.cpu_count(), "load_average_1_5_15min":
                    [round(v, 2) for v in os.getloadavg()],
                    "python": platform.python_version(), "platform": platform.platform()}}
    write_record(args.out, record, announce=False)
    for part in medians:
        print(f"{part:16s} median {medians[part]:7.1f} ms  ({100 * medians[part] / total:.0f} %)")
    print(f"cycle (sum of medians) {total:.1f} ms: {1e3 / total:.1f} Hz on one core; "
          f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
