"""Trials of a text task: the model hears the sentence, never the name, and the record keeps it."""

from __future__ import annotations

import numpy as np
import pytest

from harness.inputs.trial_settings import TrialSettings
from perception.interface import (
    NO_CONDITION,
    Condition,
    ConditionKind,
    LabelKind,
    PerceptionModel,
)
from robots.yumi import YUMI
from sim.errors import TargetNotFoundError
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.trials.oracle import OraclePerception
from sim.trials.trial_runner import TrialRunner


def test_a_text_task_hands_the_model_the_sentence_and_records_it(tmp_path):
    """The model is given the test phrasing, never the name; the record keeps the sentence."""
    phrases = tmp_path / "p.tsv"
    phrases.write_text("the absorbent scourer\tsponge\nthe atomiser\tspray_bottle\n"
                       "the beaker\tmug\n")
    settings = TrialSettings("oracle", "selected-type-text", phrases=str(phrases))
    task = settings.task_spec
    scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, 0)
    given = []

    class Listens(OraclePerception):  # not the oracle to the runner: a wrapper around one
        def predict(self, image, condition=None):
            given.append(condition)
            return super().predict(image, scene.condition)  # the test, not the model, knows

    class Model(PerceptionModel):
        name, label_kind = "listens", LabelKind.GRASP_POSE

        def __init__(self, inner):
            self.inner = inner

        def predict(self, image, condition=NO_CONDITION):
            return self.inner.predict(image, condition)

    with TrialRunner(task, robot=YUMI) as runner:
        runner.model = Model(Listens(runner.world, runner.camera))
        record = runner.run(scene, 0, 0, "listens")
    wanted = {"sponge": "the absorbent scourer", "spray_bottle": "the atomiser",
              "mug": "the beaker"}[scene.condition.value]
    assert given == [Condition(ConditionKind.TEXT, wanted)]
    assert record.asked == {"kind": "text", "value": wanted}
    assert record.outcome.value == "success", record.reason


def test_the_oracle_is_told_what_the_sentence_stands_for(tmp_path):
    """The referee's demonstrator picks a text task's target from the truth, as it picks poses."""
    task = TrialSettings("oracle", "selected-type-text").task_spec
    scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, 1)
    with TrialRunner(task, robot=YUMI) as runner:
        record = runner.run(scene, 1, 0, "oracle")
        assert runner.model.named == scene.condition
    assert record.outcome.value == "success", record.reason
    assert record.target == scene.condition.value
    assert record.asked == {"kind": "text", "value": scene.given.value}
    untold = OraclePerception(runner.world, runner.camera)
    with pytest.raises(TargetNotFoundError, match="reads a text condition through what its "
                                                   "scene names"):
        untold.predict(np.zeros((8, 8, 3), np.uint8), scene.given)
