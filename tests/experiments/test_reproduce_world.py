"""gva reproduce real --world: every task of a run under one variant, demonstrations and trials."""

from __future__ import annotations

import pytest

from experiments.table3.settings import ReproduceRealSettings, TrialSet, Unit
from harness.inputs.collector import CollectSettings, collect
from sim.errors import InvalidInputError
from sim.tasks.variants import read_variant


def test_the_world_lays_its_variant_over_every_task_and_enters_the_identity():
    plain = ReproduceRealSettings()
    world = ReproduceRealSettings(world="varied-held-out")
    for task in ("single", "multiple", "selected-type", "selected-position"):
        unit = Unit("kqv", task)
        run_task = world.run_task(TrialSet(unit))
        assert run_task.name == f"{task}+varied-held-out"
        assert run_task.appearance.held_out
        assert plain.run_task(TrialSet(unit)).appearance.is_default
        assert world.train_identity(unit)["task"] != plain.train_identity(unit)["task"]
        dark = world.run_task(TrialSet(unit, "dark"))
        assert dark.brightness == 0.5 and dark.appearance == run_task.appearance
    assert world.shared_identity()["world"] == read_variant("varied-held-out")[1]
    assert "world" not in plain.shared_identity()  # folders from before keep their identity
    assert "--world varied-held-out" in world.command("runs/x")


def test_an_unknown_world_is_refused_naming_the_built_in_variants():
    with pytest.raises(InvalidInputError, match="variant = 'moon' is not allowed: one of block"):
        ReproduceRealSettings(world="moon")


def test_a_dataset_under_a_moved_mount_records_the_camera_as_mounted(tmp_path):
    settings = CollectSettings("yumi", "single", 1, seed=0, variant="mount")
    dataset = collect(settings, tmp_path / "d.gva", progress=False)
    assert dataset.metadata.task == "single+mount"
    assert tuple(dataset.metadata.camera["position_m"]) == (0.09, 0.0, 0.52)
    assert "mount" in dataset.scenes[0]["look"]
