"""The colour detector of examples/plugins: it grasps every task's targets, importing perception."""

import dataclasses

import pytest
from plugin_detectors import assert_grasps_every_target, imports_beyond_the_rule

from perception.errors import InvalidPredictionError
from perception.interface import Condition, ConditionKind
from perception.objects.catalog import OBJECT_TYPES
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task

TASKS = ("single", "multiple", "selected-type", "selected-position")
PLUGIN = "colour_detector:ColourDetector"


def test_the_detector_imports_only_perception_numpy_and_the_standard_library():
    assert imports_beyond_the_rule("colour_detector.py") == set()


@pytest.mark.parametrize("task_name", TASKS)
def test_the_detector_grasps_every_target_within_a_centimetre(runner, detector, task_name):
    assert_grasps_every_target(runner, detector, task_name, (0, 1), 0.01, 0.1)


def test_the_detector_says_which_object_it_did_not_find(runner, detector):
    empty = dataclasses.replace(sample_scene(load_task("single"), YUMI_SCENE, 0, SeedStream.TEST,
                                             0), objects=(), targets=())
    runner.setup(empty)
    mug = Condition(ConditionKind.OBJECT_TYPE, "mug", OBJECT_TYPES)
    with pytest.raises(InvalidPredictionError, match="colour-detector found no mug on the table"):
        detector.predict_frame(runner.sense(), mug)
