"""Offline errors judged as a trial judges a pick: per object type, with the tail."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from user_models import synthetic_dataset

from perception.interface import LabelKind, Prediction, Target
from perception.labels import split_label
from perception.learning.judged_errors import judge_predictions
from perception.poses import rot_z


@pytest.fixture
def dataset():
    """Six grasp-labelled images whose scene records name a sponge or a mug as the target."""
    data = synthetic_dataset(size=6, targets=1, kind=LabelKind.GRASP_POSE)
    scenes = tuple({"index": n, "targets": [0], "objects": [
        {"type": "sponge" if n % 2 else "mug", "position_xy_m": [0.45, 0.0], "yaw_rad": 0.0,
         "distractor": False}]} for n in range(len(data)))
    return dataclasses.replace(data, scenes=scenes)


def _predictions(dataset, turn_sponges_deg: float = 0.0) -> list[Prediction]:
    truth = split_label(dataset.labels.astype(np.float64))
    predictions = []
    for n, record in enumerate(dataset.scenes):
        turn = turn_sponges_deg if record["objects"][0]["type"] == "sponge" else 0.0
        rotation = truth.rotation[n, 0] @ rot_z(math.radians(turn))
        predictions.append(Prediction((Target(truth.position_m[n, 0], rotation),)))
    return predictions


def test_exact_predictions_are_judged_picked_with_no_error(dataset):
    judged = judge_predictions(_predictions(dataset), dataset)
    assert judged is not None and judged.all.targets == 6
    assert judged.all.predicted_success_rate == 1.0
    assert judged.all.errors["position_cm"].worst == pytest.approx(0.0, abs=1e-4)
    assert set(judged.per_object) == {"sponge", "mug"}
    assert judged.per_condition is None and judged.per_head is None


def test_sponges_turned_60_degrees_are_judged_missed_and_the_mugs_are_not(dataset):
    judged = judge_predictions(_predictions(dataset, turn_sponges_deg=60.0), dataset)
    assert judged.per_object["sponge"].predicted_success_rate == 0.0
    assert judged.per_object["mug"].predicted_success_rate == 1.0
    assert judged.all.predicted_success_rate == 0.5
    sponge_yaw = judged.per_object["sponge"].errors["yaw_deg"]
    assert (sponge_yaw.mean, sponge_yaw.p95, sponge_yaw.worst) == pytest.approx((60, 60, 60))
    # a mean position error would see nothing: every grasp is where it should be
    assert judged.all.errors["position_cm"].worst == pytest.approx(0.0, abs=1e-4)


def test_position_labels_are_not_judged():
    data = synthetic_dataset(size=3, targets=1, kind=LabelKind.POSITION)
    truth = split_label(data.labels.astype(np.float64)).position_m
    assert judge_predictions([Prediction((Target(p[0]),)) for p in truth], data) is None
