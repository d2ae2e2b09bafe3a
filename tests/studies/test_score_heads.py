"""studies/score_heads.py and check_held_out_power.py: each head, focused and whole, held out."""

from __future__ import annotations

import json
import re

from benchmark_scripts import load_study

from harness.inputs.collector import CollectSettings, LabelSource, collect
from perception.learning.train import TrainConfig
from perception.learning.validation import CheckConfig, fit_checked, split_scenes, write_check
from perception.models.kqv import KqvConfig, KqvModel
from sim.world.sensor import SensorKind


def test_each_head_gets_a_line_per_reading_and_the_check_its_held_out_scenes(tmp_path):
    data = tmp_path / "multiple.gva"
    # Labelled by the catalog, never picked: the scoring reads a dataset, not how it was made
    # (the same scenes as demonstrations, seconds instead of five physics picks of three).
    dataset = collect(CollectSettings("yumi", "multiple", 5, sensor=SensorKind.IDEAL,
                                      labels=LabelSource.CATALOG), data, progress=False)
    fit = fit_checked(lambda seed: KqvModel.for_dataset(dataset, KqvConfig(starts=1, seed=seed,
                                                                            type_steps=2)),
                      dataset, TrainConfig(steps=2, batch_size=2), CheckConfig(attempts=1),
                      progress=False)
    checkpoint = tmp_path / "s0" / "checkpoints" / "kqv" / "multiple"
    fit.model.save(checkpoint)
    write_check(checkpoint, fit)
    lines = load_study("score_heads").score(checkpoint, data)
    heads = [line.split()[:3] for line in lines[1:]]
    assert heads == [[reading, "head", str(k)] for reading in ("focus", "whole")
                     for k in range(3)]
    assert re.fullmatch(r"  focus head 1 \(\d+\): judged \d+\.\d %, chance \d+\.\d %; "
                        r"position \d+\.\d\d/\d+\.\d\d cm, approach .* yaw \d+\.\d deg",
                        lines[2])
    # the held-out split is found again as the training drew it
    (tmp_path / "s0" / "datasets").mkdir()
    (tmp_path / "s0" / "datasets" / "multiple-train-5-s0.gva").write_bytes(data.read_bytes())
    held = split_scenes(dataset, CheckConfig().holdout, 0)[1]
    recorded = json.loads((checkpoint / "check.json").read_text())["held_out_scenes"]
    assert held is not None and sorted(set(held.scene_keys())) == recorded
    power = load_study("check_held_out_power")
    seen = power.per_head(fit.model, held)
    assert set(seen) == {"head 0", "head 1", "head 2"}  # a multi-head task: by head
    assert all(0.0 <= share <= 1.0 and 0.0 <= p <= 1.0 and n > 0 for share, p, n in seen.values())
