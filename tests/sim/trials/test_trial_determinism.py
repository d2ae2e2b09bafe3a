"""A trial's record depends only on task, model, seed and index: however the run went."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from harness.inputs.trial_settings import TrialSettings
from harness.run_loop import run_trials
from robots.yumi import YUMI
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task
from sim.trials.trial_runner import TrialRunner
from sim.world.sensor import SensorConfig, SensorKind

D435_SINGLE = dataclasses.replace(load_task("single"), camera=SensorConfig(SensorKind.D435))


def second_record_after_another_and_alone(task):
    """Trial 1's record run after trial 0 in one runner, and run alone in a fresh one."""
    scenes = [sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, i) for i in range(2)]

    def record(runner, index):
        fields = json.loads(runner.run(scenes[index], index, 0, "oracle").to_json())
        fields.pop("wall_time_s")
        return fields

    with TrialRunner(task, robot=YUMI) as runner:
        after_another = [record(runner, i) for i in (0, 1)][1]
    with TrialRunner(task, robot=YUMI) as runner:
        alone = record(runner, 1)  # as a resumed run, or another worker, runs it
    return after_another, alone


@pytest.mark.slow
@pytest.mark.parametrize("task", [load_task("multiple"), D435_SINGLE], ids=["multiple", "d435"])
def test_a_trials_record_does_not_depend_on_the_trials_before_it(task):
    # multiple trial 1 after trial 0 lifted its last object 0.09900 m, alone 0.09901 m, while
    # one PyBullet world carried its state from trial to trial; a D435's noise is seeded per
    # trial and pick, never drawn from a stream the trials before it advanced
    after_another, alone = second_record_after_another_and_alone(task)
    assert alone == after_another


@pytest.mark.slow
def test_trials_side_by_side_write_the_records_of_one_process(tmp_path):
    def records(folder):
        lines = (folder / "trials.jsonl").read_text().splitlines()
        return {r["index"]: r for r in map(json.loads, lines) if r.pop("wall_time_s")}

    settings = TrialSettings("oracle", "single", n=3)
    run_trials(settings, tmp_path / "one", progress=False)
    summary = run_trials(settings, tmp_path / "two", progress=False, workers=2)
    assert records(tmp_path / "two") == records(tmp_path / "one") and summary.n == 3


def test_a_d435_runner_seeds_each_frame_by_scene_and_pick():
    scenes = [sample_scene(D435_SINGLE, YUMI_SCENE, 0, SeedStream.TEST, i) for i in range(2)]
    with TrialRunner(D435_SINGLE, robot=YUMI) as runner:
        def sights(scene):  # the frames of a scene's first two picks
            body = runner.setup(scene)[scene.targets[0]]
            return runner.sight(body).frame, runner.sight(body).frame

        first, second = sights(scenes[1])
        sights(scenes[0])
        again, _ = sights(scenes[1])
    assert np.array_equal(again.rgb, first.rgb) and np.array_equal(again.depth_m, first.depth_m)
    assert not np.array_equal(second.rgb, first.rgb)  # the next pick: fresh noise, same world
    assert first.camera == runner.camera.pinhole  # the calibration, not the true camera
    assert runner.camera.true_camera(0) != first.camera
