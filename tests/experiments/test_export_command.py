"""``gva export --format lerobot`` and ``gva import``: the same file back; bad input named."""

from __future__ import annotations

import json

import numpy as np
import pytest
from gva_cli import gva

from perception.interface import ConditionKind, LabelKind
from perception.labels import label_vector
from perception.learning.data import Dataset, DatasetMetadata
from perception.learning.dataset_file import save_dataset


@pytest.fixture
def dataset_file(tmp_path):
    """A two-scene, two-stage dataset of grasp labels in a .gva file."""
    rng = np.random.default_rng(3)
    metadata = DatasetMetadata(
        scene="yumi", task="multiple", size=4, seed=3, image_height_px=9, image_width_px=7,
        label_kind=LabelKind.GRASP_POSE, targets=2, condition_kind=ConditionKind.NONE,
        condition_choices=(), camera={"vertical_fov_deg": 37.0}, extra={"scenes": 2})
    rotation = np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (4, 2, 3, 3))  # top-down
    scenes = ({"index": 0}, {"index": 0, "taken": [0]}, {"index": 1}, {"index": 1, "taken": [0]})
    dataset = Dataset(metadata, rng.integers(0, 256, (4, 9, 7, 3), dtype=np.uint8),
                      np.zeros((4, 0), np.float32),
                      label_vector(rng.uniform(-0.3, 0.3, (4, 2, 3)), rotation), scenes)
    return save_dataset(dataset, tmp_path / "demos.gva")


def test_export_then_import_gives_the_same_file(tmp_path, dataset_file):
    status, out, err = gva("export", "--format", "lerobot", dataset_file, tmp_path / "lr",
                           "--no-progress")
    assert status == 0, err
    assert "4 samples as 2 LeRobot episodes" in out and f"folder: {tmp_path / 'lr'}" in out
    info = json.loads((tmp_path / "lr/meta/info.json").read_text())
    assert (info["total_episodes"], info["total_frames"]) == (2, 4)
    status, out, err = gva("import", tmp_path / "lr", tmp_path / "back.gva")
    assert status == 0, err
    assert "4 samples of yumi / multiple (seed 3), the same as exported" in out
    assert (tmp_path / "back.gva").read_bytes() == dataset_file.read_bytes()


@pytest.mark.parametrize(("arguments", "message"), [
    (("--format", "zarr", "{data}", "{tmp}/lr"),
     "--format = 'zarr' is not allowed: one of lerobot"),
    (("--format", "lerobot", "{tmp}/demos.safetensors", "{tmp}/lr"),
     "DATASET = '{tmp}/demos.safetensors' is not allowed: a dataset file named *.gva"),
    (("--format", "lerobot", "{tmp}/missing.gva", "{tmp}/lr"),
     "DATASET = '{tmp}/missing.gva' is not allowed: an existing .gva dataset file"),
    (("--format", "lerobot", "{data}", "{tmp}/full"),
     "OUT = '{tmp}/full' is not allowed: a folder that does not exist or is empty"),
])
def test_bad_export_arguments_are_named(tmp_path, dataset_file, arguments, message):
    (tmp_path / "full").mkdir()
    (tmp_path / "full/keep.txt").write_text("mine")
    filled = [a.format(data=dataset_file, tmp=tmp_path) for a in arguments]
    status, _, err = gva("export", *filled, "--no-progress")
    assert status == 2
    assert err.strip() == f"gva export: error: {message.format(tmp=tmp_path)}"
    assert (tmp_path / "full/keep.txt").read_text() == "mine" and not (tmp_path / "lr").exists()


def test_bad_import_arguments_are_named(tmp_path, dataset_file):
    status, _, err = gva("export", "--format", "lerobot", dataset_file, tmp_path / "lr")
    assert status == 0, err
    status, _, err = gva("import", tmp_path / "nowhere", tmp_path / "back.gva")
    assert (status, err.strip()) == (2, f"gva import: error: FOLDER = '{tmp_path / 'nowhere'}' is "
                                     "not allowed: a folder gva export wrote")
    status, _, err = gva("import", tmp_path / "lr", dataset_file)
    assert (status, err.strip()) == (2, f"gva import: error: OUT = '{dataset_file}' is not "
                                     "allowed: a .gva path that does not exist yet")
    status, _, err = gva("import", tmp_path / "lr", tmp_path / "back.npz")
    assert status == 2 and "OUT = " in err and "a dataset file named *.gva" in err
    (tmp_path / "lr/meta/gva.json").unlink()
    status, _, err = gva("import", tmp_path / "lr", tmp_path / "back.gva")
    assert status == 2 and "has no meta/gva.json" in err and not (tmp_path / "back.gva").exists()
