"""studies/check_arm_mask_offline.py reads the robot's pixels and counts the heeded images."""

from __future__ import annotations

import json

import numpy as np
from benchmark_scripts import load_study

from harness.inputs.collector import CollectSettings, collect
from perception.learning.dataset_file import load_dataset
from perception.learning.train import TrainConfig
from perception.models.kqv import KqvConfig, KqvModel
from sim.world.sensor import SensorKind


def test_the_masks_are_the_arm_and_the_heeded_images_are_counted(tmp_path):
    check = load_study("check_arm_mask_offline")
    data = tmp_path / "approach.gva"
    dataset = collect(CollectSettings("yumi", "single", 1, approach_hz=5.0,
                                      sensor=SensorKind.IDEAL), data, progress=False)
    masks = check.robot_masks(load_dataset(data))
    approach = [i for i, r in enumerate(dataset.scenes) if r.get("stage") == "approach"]
    assert not masks[0].any() and masks[approach[-1]].sum() > 100  # the arm, coming in
    assert dataset.depths_m is not None
    np.testing.assert_array_equal(masks[approach], dataset.depths_m[approach] == 0.0)  # ideal
    model = KqvModel.for_dataset(dataset, KqvConfig(starts=1, type_steps=2))
    model.fit(dataset, TrainConfig(steps=2, batch_size=2), progress=False)
    model.save(tmp_path / "kqv")
    out = tmp_path / "hold.json"
    assert check.main(["--case", "tiny", str(tmp_path / "kqv"), str(data), "--masks", str(data),
                       "--json", str(out)]) == 0
    [result] = json.loads(out.read_text())["results"]
    assert result["approach_images"] == len(approach) and result["scenes"] == 1
    assert 0 <= result["heeded_images"] <= result["approach_images"]
