"""studies/check_retry_start.py: a later start trained again, with what failed drawn twice."""

from __future__ import annotations

import pytest
from benchmark_scripts import load_study

from harness.inputs.collector import CollectSettings, collect
from perception.learning.dataset_file import load_dataset
from perception.registry import load_model
from sim.world.sensor import SensorKind


@pytest.mark.slow
def test_a_later_start_is_trained_checked_and_saved_with_a_type_drawn_twice(tmp_path, capsys):
    data = tmp_path / "single.gva"
    collect(CollectSettings("yumi", "single", 6, sensor=SensorKind.IDEAL), data, progress=False)
    study = load_study("check_retry_start")
    dataset = load_dataset(data)
    kind = dataset.target_types()[0][0]
    twice = study.drawn_twice(dataset, kind)
    shows = sum(kind in types for types in dataset.target_types())
    assert len(twice) == len(dataset) + shows and twice.scenes[-1]["objects"]
    out = tmp_path / "ckpt"
    assert study.main([str(data), "--seed", "0", "--attempt", "3", "--twice", kind,
                       "--steps", "2", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "attempt 3" in printed and "expected picked per object type: " in printed
    assert load_model(out).spec.task == "single"
