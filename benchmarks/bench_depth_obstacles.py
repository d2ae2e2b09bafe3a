"""Cost of planning from the depth image: building the obstacles, and planning around them.

    python benchmarks/bench_depth_obstacles.py [--scenes 10] [--repeats 5] [--sensor d435]
        [--out benchmarks/results/depth_obstacles.json]

For the first ``--scenes`` test scenes of each yumi task (seed 0), at the first pick: renders
the head camera's RGB-D frame, then times :func:`control.depth_obstacles.depth_obstacles`
around the oracle's grasp (median of ``--repeats``), with hidden space free (the default) and
occupied. The bar: <= 30 ms per pick (median). Peers in the same run: coal's ``makeOctree`` on
the same points at the same resolution (the geometry the issue named), and the planner's time
on the same pick given the true shapes instead of the depth obstacles. ``--sensor d435`` renders
through the D435-like sensor (noise, invalid pixels: their rays go to the obstacles too) and
writes ``depth_obstacles_d435.json`` unless ``--out`` says otherwise.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import statistics
import time
from functools import partial
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin  # coal's Python module is found through pinocchio's path
from results_file import record_path, write_record

from control.depth_obstacles import GraspRegion, OccludedSpace, depth_obstacles
from perception.labels import nearest_rotation
from perception.objects.catalog import clear_of_table
from perception.poses import Pose
from robots.yumi import YUMI
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task
from sim.trials.planner_setup import ObstacleSource
from sim.trials.trial_runner import TrialRunner
from sim.world.grip import grip_of
from sim.world.sensor import SensorConfig, SensorKind, sensor_kind

TASKS = ("single", "multiple", "selected-type", "selected-position")


def median_ms(action, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        action()
        times.append(time.perf_counter() - started)
    return 1000 * statistics.median(times)


def summary(values: list[float]) -> dict[str, float]:
    ordered = sorted(values)
    return {"median": round(statistics.median(ordered), 2),
            "p90": round(ordered[int(0.9 * (len(ordered) - 1))], 2),
            "max": round(ordered[-1], 2)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--sensor", choices=[k.value for k in SensorKind], default="ideal")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    sensor = SensorConfig(sensor_kind(args.sensor))
    out = args.out or record_path("depth_obstacles" if args.sensor == "ideal"
                                   else "depth_obstacles_d435")

    build = {policy: [] for policy in OccludedSpace}
    octree, render, plan_depth, plan_truth, cells = [], [], [], [], []
    for name in TASKS:
        task = dataclasses.replace(load_task(name), camera=sensor)
        with TrialRunner(task, robot=YUMI) as runner:
            occupied = dataclasses.replace(runner.depth, occluded=OccludedSpace.OCCUPIED)
            for index in range(args.scenes):
                scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, index)
                runner.setup(scene)
                render.append(median_ms(runner.sense, args.repeats))
                frame = runner.sense()
                prediction = runner.model.predict(frame.rgb, scene.condition)
                target = prediction.targets[0]
                grip = grip_of(target, runner.world.description.max_opening_m)
                rotation = nearest_rotation("predicted rotation", target.rotation)
                grasp, _ = clear_of_table(Pose(target.position_m, rotation), grip.opening_m,
                                          YUMI.arms[0].gripper.fingers)
                region = GraspRegion(pin.SE3(grasp.matrix), grip.opening_m)
                points, camera = frame.points_world(), np.asarray(frame.camera.position_m)
                unknown = frame.unknown_rays()
                for policy, config in ((OccludedSpace.FREE, runner.depth),
                                       (OccludedSpace.OCCUPIED, occupied)):
                    build[policy].append(median_ms(partial(
                        depth_obstacles, points, camera, config, region, unknown), args.repeats))
                seen = depth_obstacles(points, camera, runner.depth, region, unknown)
                cells.append(seen.obstacle_cells + seen.target_cells)
                kept = points[np.isfinite(points).all(axis=-1) & (points[..., 2] > 0.01)]
                octree.append(median_ms(partial(coal.makeOctree, np.ascontiguousarray(
                    kept, dtype=float), runner.depth.cell_m), args.repeats))
                for source, times in ((ObstacleSource.DEPTH, plan_depth),
                                      (ObstacleSource.TRUTH, plan_truth)):
                    runner.obstacle_source = source
                    started = time.perf_counter()
                    runner.plan_pick(frame, prediction, 0, len(scene.targets))
                    times.append(1000 * (time.perf_counter() - started))
                runner.obstacle_source = ObstacleSource.DEPTH
        print(f"{name}: build {statistics.median(build[OccludedSpace.FREE][-args.scenes:]):.1f}"
              f" ms (median of {args.scenes} scenes)")

    free = summary(build[OccludedSpace.FREE])
    result = {
        "machine": {"cpu_count": os.cpu_count(), "python": platform.python_version(),
                    "processor": platform.processor() or platform.machine()},
        "scenes_per_task": args.scenes, "tasks": list(TASKS), "sensor": sensor.to_json(),
        "build_ms_hidden_free": free,
        "build_ms_hidden_occupied": summary(build[OccludedSpace.OCCUPIED]),
        "peer_coal_octree_build_ms": summary(octree),
        "ratio_build_to_octree": round(free["median"] / statistics.median(octree), 2),
        "render_rgbd_ms": summary(render),
        "occupied_cells": summary([float(c) for c in cells]),
        "plan_ms_depth": summary(plan_depth),
        "plan_ms_true_shapes": summary(plan_truth),
        "ratio_plan_depth_to_true_shapes": round(statistics.median(plan_depth) /
                                                 statistics.median(plan_truth), 2),
    }
    for key in ("build_ms_hidden_free", "build_ms_hidden_occupied", "peer_coal_octree_build_ms",
                "plan_ms_depth", "plan_ms_true_shapes"):
        print(f"{key}: {result[key]}")
    write_record(out, result)


if __name__ == "__main__":
    main()
