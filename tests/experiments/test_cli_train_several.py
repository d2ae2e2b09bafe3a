"""``gva train --data demo.gva --data catalog.gva`` (issue 74): demonstrations and scenes the
catalog labelled in randomised looks trained on together, end to end on a few scenes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from gva_cli import gva
from user_models import synthetic_dataset

from harness.inputs.collector import CollectSettings, LabelSource, LookSource, collect
from perception.files import file_sha256
from perception.learning import combined
from perception.learning.checkpoint import read_config
from perception.learning.dataset_file import load_dataset
from perception.registry import load_model
from sim.world.sensor import SensorKind

TINY = ["--model", "kqv", "--steps", "2", "--batch-size", "2", "--threads", "1", "--no-progress"]


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Three demonstrations of ``single`` and two catalog scenes in randomised looks, ideal."""
    root = tmp_path_factory.mktemp("several")
    paths = {"demo": root / "demo.gva", "shape": root / "shape.gva"}
    collect(CollectSettings("yumi", "single", 3, sensor=SensorKind.IDEAL), paths["demo"],
            progress=False)
    collect(CollectSettings("yumi", "single", 2, seed=5, sensor=SensorKind.IDEAL,
                            labels=LabelSource.CATALOG, looks=LookSource.RANDOMISED),
            paths["shape"], progress=False)
    return paths


def test_demonstrations_and_a_catalog_set_train_together_and_the_checkpoint_says_so(
        files: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "kqv"
    status, stdout, stderr = gva("train", "--data", files["demo"], "--data", files["shape"],
                                 "--out", out, "--holdout", "0.2", "--attempts", "1", *TINY)
    assert status in (0, 1), stderr  # 1: two steps fail the held-out check, as they should
    lines = stdout.splitlines()
    assert lines[0].startswith("held-out check ") and "1 held-out scene(s)" in lines[0]
    assert lines[1].startswith("kqv on yumi / single: 4 samples, ")  # 5, one scene held out
    assert lines[2] == (f"trained on: {files['demo']} (single, 3 scenes, 3 samples, picked "
                        f"labels, task looks) + {files['shape']} (single+randomised, 2 scenes, "
                        "2 samples, catalog labels, randomised looks)")
    recorded = read_config(out)["training"]["datasets"]  # under the config's checksum
    assert [(d["path"], d["sha256"], d["labels"], d["looks"], d["samples"]) for d in recorded] \
        == [(str(files["demo"].resolve()), file_sha256(files["demo"]), "picked", "task", 3),
            (str(files["shape"].resolve()), file_sha256(files["shape"]), "catalog",
             "randomised", 2)]
    # the held-out check held out a demonstration, never a catalog scene (the shape set's
    # scenes are numbered after the demonstrations')
    check = json.loads((out / "check.json").read_text())
    demo_scenes = {record["index"] for record in load_dataset(files["demo"]).scenes}
    assert len(check["held_out_scenes"]) == 1 and set(check["held_out_scenes"]) <= demo_scenes
    assert load_model(out).spec.task == "single"


def test_one_data_file_trains_as_before_and_records_no_files(files: dict[str, Path],
                                                             tmp_path: Path) -> None:
    status, stdout, stderr = gva("train", "--data", files["demo"], "--out", tmp_path / "k",
                                 "--holdout", "0", *TINY)
    assert status == 0, stderr
    assert "trained on:" not in stdout
    assert "datasets" not in read_config(tmp_path / "k")["training"]


def test_files_of_other_tasks_are_refused_in_one_line_naming_the_field(
        files: dict[str, Path], tmp_path: Path) -> None:
    other = tmp_path / "selected.gva"
    collect(CollectSettings("yumi", "selected-type", 1, sensor=SensorKind.IDEAL,
                            labels=LabelSource.CATALOG), other, progress=False)
    status, stdout, stderr = gva("train", "--data", files["demo"], "--data", other,
                                 "--out", tmp_path / "k", *TINY)
    assert status == 2 and stdout == "" and not (tmp_path / "k").exists()
    assert stderr == (f"gva train: error: task family of {other} = 'selected-type' is not "
                      f"allowed: {files['demo']}'s 'single' ({combined.AGREEMENT})\n")


def test_the_record_words_are_the_collectors() -> None:
    assert (combined.PICKED_LABELS, combined.CATALOG_LABELS, combined.TASK_LOOKS) == (
        LabelSource.PICKED.value, LabelSource.CATALOG.value, LookSource.TASK.value)
    # a demonstration's metadata records neither: picked, in its task's looks
    assert combined.labels_and_looks(synthetic_dataset(size=1).metadata) == ("picked", "task")
