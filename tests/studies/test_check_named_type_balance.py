"""studies/check_named_type_balance.py scores a checkpoint per stage and named type."""

from __future__ import annotations

import re

from benchmark_scripts import load_study

from harness.inputs.collector import CollectSettings, collect
from perception.learning.train import TrainConfig
from perception.models.kqv import KqvConfig, KqvModel
from sim.world.sensor import SensorKind


def test_each_stage_and_named_type_gets_its_own_line(tmp_path):
    study = load_study("check_named_type_balance")
    data = tmp_path / "approach.gva"
    dataset = collect(CollectSettings("yumi", "selected-type", 1, approach_hz=5.0,
                                      sensor=SensorKind.IDEAL), data, progress=False)
    model = KqvModel.for_dataset(dataset, KqvConfig(starts=1, type_steps=2))
    model.fit(dataset, TrainConfig(steps=2, batch_size=2), progress=False)
    model.save(tmp_path / "kqv")
    lines = study.score(tmp_path / "kqv", data)
    along = [r for r in dataset.scenes if r.get("stage") == "approach"]
    named, approach = along[0]["condition"]["value"], len(along)  # the demonstrated target
    pick = {r["condition"]["value"] for r in dataset.scenes if r.get("stage") != "approach"}
    assert approach > 0 and len(pick) == 3  # an image under every named type before the pick
    assert [line.split()[1:3] for line in lines] == (
        [["pick", t] for t in dataset.metadata.condition_choices if t in pick]
        + [["approach", named]])
    assert re.fullmatch(rf".* approach {named} \({approach} images\): \d+\.\d\d cm, "
                        r"\d+\.\d deg, judged picked \d+ %", lines[-1])
    whole = study.score(tmp_path / "kqv", data, whole_heatmap=True)  # the same lines, unfocused
    assert [line.split()[1:3] for line in whole] == [line.split()[1:3] for line in lines]
