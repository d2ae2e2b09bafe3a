"""benchmarks/check_arm_mask_offline.py reads the robot's pixels and counts the heeded images."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np

from perception.learning.dataset_file import load_dataset
from perception.learning.train import TrainConfig
from perception.models.kqv import KqvConfig, KqvModel
from sim.trials.collector import CollectSettings, collect

ROOT = Path(__file__).resolve().parents[2]


def test_the_masks_are_the_arm_and_the_heeded_images_are_counted(tmp_path):
    sys.path.insert(0, str(ROOT / "benchmarks"))
    spec = importlib.util.spec_from_file_location(
        "check_arm_mask_offline", ROOT / "benchmarks" / "check_arm_mask_offline.py")
    assert spec is not None and spec.loader is not None
    check = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = check  # its dataclasses look their module up
    spec.loader.exec_module(check)
    data = tmp_path / "approach.gva"
    dataset = collect(CollectSettings("yumi", "single", 1, approach_hz=5.0), data, progress=False)
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
