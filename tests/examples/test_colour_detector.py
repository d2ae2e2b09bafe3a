"""The colour detector of examples/plugins: it grasps every task's targets, importing perception."""

import dataclasses

import numpy as np
import pytest
from plugin_detectors import PLUGINS, imports_beyond_the_rule

from perception.errors import InvalidPredictionError
from perception.interface import Condition, ConditionKind
from perception.objects.catalog import OBJECT_TYPES
from perception.plugins import build_plugin
from robots.yumi import YUMI
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task
from sim.trials.pick_results import grasp_angle_rad
from sim.trials.trial_runner import TrialRunner

TASKS = ("single", "multiple", "selected-type", "selected-position")


@pytest.fixture(scope="module")
def detector():
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(PLUGINS))
        yield build_plugin("colour_detector:ColourDetector")  # as --model finds it


@pytest.fixture(scope="module")
def runner(detector):
    with TrialRunner(load_task("single"), lambda world, camera: detector, robot=YUMI) as runner:
        yield runner  # sets up and renders any task's scenes: they share the light


def test_the_detector_imports_only_perception_numpy_and_the_standard_library():
    assert imports_beyond_the_rule("colour_detector.py") == set()


@pytest.mark.parametrize("task_name", TASKS)
def test_the_detector_grasps_every_target_within_a_centimetre(runner, detector, task_name):
    task = load_task(task_name)
    for index in (0, 1):
        scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, index)
        bodies = runner.setup(scene)
        prediction = detector.predict_frame(runner.sense(), scene.condition)
        assert len(prediction.targets) == len(scene.targets)
        assert prediction.attention_px.shape == (len(scene.targets), 2)
        for target, number in zip(prediction.targets, scene.targets, strict=True):
            truth = runner.truth(bodies[number])
            assert target.object_type == scene.objects[number].object_type
            assert np.linalg.norm(target.position_m - truth.position) < 0.01
            assert grasp_angle_rad(truth.rotation, target.rotation) < 0.1


def test_the_detector_says_which_object_it_did_not_find(runner, detector):
    empty = dataclasses.replace(sample_scene(load_task("single"), YUMI_SCENE, 0, SeedStream.TEST,
                                             0), objects=(), targets=())
    runner.setup(empty)
    mug = Condition(ConditionKind.OBJECT_TYPE, "mug", OBJECT_TYPES)
    with pytest.raises(InvalidPredictionError, match="colour-detector found no mug on the table"):
        detector.predict_frame(runner.sense(), mug)
