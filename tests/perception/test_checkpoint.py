import json
import os
import pickle

import numpy as np
import pytest
import torch
from safetensors.torch import load_file, save_file
from user_models import synthetic_dataset, typed_dataset

from perception.files import file_sha256
from perception.interface import LabelKind
from perception.learning.checkpoint import (
    CONFIG_FILE,
    FORMAT_VERSION,
    WEIGHTS_FILE,
    CheckpointError,
    config_sha256,
    config_verified,
    load_checkpoint,
    read_config,
)
from perception.learning.train import TrainConfig
from perception.models.kqv import KqvConfig, KqvModel


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """A briefly trained grasp model with 3 heads, saved once for every test."""
    dataset = synthetic_dataset(size=4, targets=3, kind=LabelKind.GRASP_POSE, seed=5)
    model = KqvModel.for_dataset(dataset, KqvConfig(seed=1))
    model.fit(dataset, TrainConfig(steps=3, batch_size=2, threads=1), progress=False)
    folder = model.save(tmp_path_factory.mktemp("ckpt") / "kqv")
    return model, dataset, folder


def copy_of(folder, tmp_path):
    target = tmp_path / "copy"
    target.mkdir()
    for name in (WEIGHTS_FILE, CONFIG_FILE):
        (target / name).write_bytes((folder / name).read_bytes())
    return target


def edit_config(folder, change, reseal=True):
    """Changes config.json; ``reseal``: its checksum too, as only a deliberate editor would."""
    config = json.loads((folder / CONFIG_FILE).read_text())
    change(config)
    if reseal and "config_sha256" in config:
        config["config_sha256"] = config_sha256(config)
    (folder / CONFIG_FILE).write_text(json.dumps(config))


def test_save_then_load_gives_identical_predictions(saved):
    model, dataset, folder = saved
    loaded = KqvModel.load(folder)
    before = model.predict_batch(dataset.images, dataset.conditions)
    after = loaded.predict_batch(dataset.images, dataset.conditions)
    for a, b in zip(before, after, strict=True):
        np.testing.assert_array_equal(a.attention_px, b.attention_px)
        np.testing.assert_array_equal(a.heatmaps, b.heatmaps)
        for x, y in zip(a.targets, b.targets, strict=True):
            np.testing.assert_array_equal(x.position_m, y.position_m)
            np.testing.assert_array_equal(x.rotation, y.rotation)
    assert loaded.spec == model.spec and loaded.config == model.config
    assert loaded.scaler == model.scaler


def test_config_json_describes_the_model(saved):
    _, _, folder = saved
    config = json.loads((folder / CONFIG_FILE).read_text())
    assert config["model"] == "kqv" and config["format_version"] == FORMAT_VERSION
    assert config["spec"]["label_kind"] == "grasp_pose" and config["spec"]["targets"] == 3
    assert config["spec"]["label_dim"] == 12 and config["spec"]["image_height_px"] == 64
    assert set(config["label_scaler"]) == {"centre_m", "scale_m"}
    assert config["hyperparameters"]["channels"] == [16, 16]
    assert config["training"]["steps"] == 3
    assert config["weights_sha256"] == file_sha256(folder / WEIGHTS_FILE)


@pytest.mark.parametrize("name", [WEIGHTS_FILE, CONFIG_FILE])
def test_missing_file(saved, tmp_path, name):
    folder = copy_of(saved[2], tmp_path)
    (folder / name).unlink()
    with pytest.raises(CheckpointError, match=rf"{name}: missing: a checkpoint folder holds"):
        KqvModel.load(folder)


def test_missing_folder(tmp_path):
    with pytest.raises(CheckpointError, match=r"nowhere: no such folder"):
        KqvModel.load(tmp_path / "nowhere")


def test_other_format_version(saved, tmp_path):
    folder = copy_of(saved[2], tmp_path)
    edit_config(folder, lambda c: c.update(format_version=99))
    with pytest.raises(CheckpointError, match=r"config.json: format version 99; this gva "
                                              r"reads versions 1, 2"):
        KqvModel.load(folder)


def test_config_of_another_model(saved, tmp_path):
    folder = copy_of(saved[2], tmp_path)
    edit_config(folder, lambda c: c.update(model="keypoint"))
    with pytest.raises(CheckpointError, match=r"config.json: a checkpoint of model 'keypoint', "
                                              r"not 'kqv'"):
        KqvModel.load(folder)


def test_truncated_weights(saved, tmp_path):
    folder = copy_of(saved[2], tmp_path)
    data = (folder / WEIGHTS_FILE).read_bytes()
    (folder / WEIGHTS_FILE).write_bytes(data[:-100])
    with pytest.raises(CheckpointError, match=rf"{WEIGHTS_FILE}: truncated: \d+ bytes, the "
                                              r"header describes \d+"):
        KqvModel.load(folder)


def test_tampered_weights(saved, tmp_path):
    folder = copy_of(saved[2], tmp_path)
    data = bytearray((folder / WEIGHTS_FILE).read_bytes())
    data[-5] ^= 0x40  # one bit of one weight
    (folder / WEIGHTS_FILE).write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match=rf"{WEIGHTS_FILE}: its SHA-256 does not match "
                                              r"config.json: the weights were changed"):
        KqvModel.load(folder)


def test_not_json_config(saved, tmp_path):
    folder = copy_of(saved[2], tmp_path)
    (folder / CONFIG_FILE).write_text("{not json")
    with pytest.raises(CheckpointError, match=r"config.json: not valid JSON"):
        KqvModel.load(folder)


@pytest.mark.parametrize(("change", "message"), [
    ({"key_dim": 8}, rf"{WEIGHTS_FILE}: tensor \S+ is torch.float32 \(.*\); the network "
                     r"config.json describes needs torch.float32 \(.*\)"),
    ({"stride": 3}, r"config.json: cannot rebuild the model \(InvalidInputError: stride = 3"),
])
def test_hyperparameters_that_do_not_fit_the_weights(saved, tmp_path, change, message):
    folder = copy_of(saved[2], tmp_path)
    edit_config(folder, lambda c: c["hyperparameters"].update(change))
    with pytest.raises(CheckpointError, match=message):
        KqvModel.load(folder)


def test_missing_tensor(saved, tmp_path):
    folder = copy_of(saved[2], tmp_path)
    tensors = load_file(str(folder / WEIGHTS_FILE))
    tensors.pop("head.0.bias")
    save_file(tensors, str(folder / WEIGHTS_FILE))  # a consistent file, with its checksum
    edit_config(folder, lambda c: c.update(weights_sha256=file_sha256(folder / WEIGHTS_FILE)))
    with pytest.raises(CheckpointError, match=r"lacks tensors head.0.bias that the network"):
        KqvModel.load(folder)


class _RunsOnUnpickling:
    """Pickled, it calls ``os.mkdir(path)`` when unpickled: the proof that a loader used pickle."""

    def __init__(self, path):
        self.path = str(path)

    def __reduce__(self):
        return os.mkdir, (self.path,)


def test_load_checkpoint_reads_tensors_without_pickle(saved, tmp_path, monkeypatch):
    """Weights load with every unpickler refused, and a pickle in their place never runs.

    A checkpoint is shared like a dataset: loading one must run no code it holds.
    """
    model, _, folder = saved

    def refused(*args, **kwargs):
        raise AssertionError("loading a checkpoint used pickle")

    with monkeypatch.context() as patch:
        for module, name in ((pickle, "load"), (pickle, "loads"), (pickle, "Unpickler"),
                             (torch, "load")):
            patch.setattr(module, name, refused)
        checkpoint = load_checkpoint(folder, "kqv")
    state = model.network.state_dict()
    assert checkpoint.config["model"] == "kqv" and set(checkpoint.tensors) == set(state)
    assert all(torch.equal(checkpoint.tensors[name], state[name]) for name in state)

    ran = tmp_path / "pickle-ran"
    planted = copy_of(folder, tmp_path)
    torch.save({name: _RunsOnUnpickling(ran) for name in state}, planted / WEIGHTS_FILE)
    edit_config(planted, lambda c: c.update(weights_sha256=file_sha256(planted / WEIGHTS_FILE)))
    with pytest.raises(CheckpointError, match=WEIGHTS_FILE):
        load_checkpoint(planted, "kqv")
    assert not ran.exists()


def test_a_checkpoint_from_before_object_types_loads_and_predicts_as_before(saved, tmp_path):
    model, dataset, folder = saved
    old = copy_of(folder, tmp_path)

    def forget(config):  # what gva wrote before the vocabulary and the type head
        del config["spec"]["object_types"]
        del config["hyperparameters"]["type_head"], config["hyperparameters"]["type_steps"]
        del config["training"]["phases"]

    edit_config(old, forget)
    loaded = KqvModel.load(old)
    assert loaded.spec.object_types == () and loaded.network.type_head is None
    before = model.predict_batch(dataset.images, dataset.conditions)
    after = loaded.predict_batch(dataset.images, dataset.conditions)
    for a, b in zip(before, after, strict=True):
        for x, y in zip(a.targets, b.targets, strict=True):
            np.testing.assert_array_equal(x.position_m, y.position_m)
            np.testing.assert_array_equal(x.rotation, y.rotation)
            assert x.object_type is None and y.object_type is None


def test_a_type_head_is_saved_and_states_the_same_types_after_loading(tmp_path):
    dataset = typed_dataset(4, seed=9, targets=2)
    model = KqvModel.for_dataset(dataset, KqvConfig(type_steps=3))
    model.fit(dataset, TrainConfig(steps=2, batch_size=2, threads=1), progress=False)
    loaded = KqvModel.load(model.save(tmp_path / "typed"))
    config = json.loads((tmp_path / "typed" / CONFIG_FILE).read_text())
    assert config["spec"]["object_types"] == ["red", "green", "blue"]
    assert [p["name"] for p in config["training"]["phases"]] == ["targets", "object types"]
    assert loaded.spec == model.spec and loaded.network.type_head is not None
    before = model.predict_batch(dataset.images, dataset.conditions)
    after = loaded.predict_batch(dataset.images, dataset.conditions)
    stated = [[t.object_type for t in p.targets] for p in before]
    assert all(name in ("red", "green", "blue") for row in stated for name in row)
    assert stated == [[t.object_type for t in p.targets] for p in after]


def _shift_centre(config):
    config["label_scaler"]["centre_m"][0] += 1.0


def _move_camera(config):
    config["spec"]["camera"] = {"position_m": [0.1, 0.0, 0.6], "target_m": [0.5, 0.0, 0.0],
                                "up": [0.0, 0.0, 1.0], "vertical_fov_deg": 40.0,
                                "horizontal_fov_deg": None, "width_px": 64, "height_px": 64}


def _warmer(config):
    config["hyperparameters"]["temperature"] = 2.0 * config["hyperparameters"]["temperature"]


@pytest.mark.parametrize("change", [_shift_centre, _move_camera, _warmer],
                         ids=["label scaler", "camera record", "hyper-parameter"])
def test_a_changed_value_is_refused_like_a_changed_weight(saved, tmp_path, change):
    folder = copy_of(saved[2], tmp_path)
    edit_config(folder, change, reseal=False)
    with pytest.raises(CheckpointError, match=r"config.json: its values do not match its "
                                              r"config_sha256: they were changed after saving"):
        KqvModel.load(folder)


def test_the_config_checksum_survives_a_reformatted_file(saved, tmp_path):
    folder = copy_of(saved[2], tmp_path)
    config = json.loads((folder / CONFIG_FILE).read_text())
    (folder / CONFIG_FILE).write_text(json.dumps(config, indent=8))  # same values, other text
    assert config_verified(read_config(folder))
    KqvModel.load(folder)


def test_a_version_1_checkpoint_loads_unverified_and_predicts_as_before(saved, tmp_path):
    model, dataset, folder = saved
    old = copy_of(folder, tmp_path)

    def version_1(config):  # what gva wrote before the config had a checksum
        config["format_version"] = 1
        del config["config_sha256"]

    edit_config(old, version_1)
    assert not config_verified(read_config(old))
    loaded = KqvModel.load(old)
    for a, b in zip(model.predict_batch(dataset.images, dataset.conditions),
                    loaded.predict_batch(dataset.images, dataset.conditions), strict=True):
        np.testing.assert_array_equal(a.targets[0].position_m, b.targets[0].position_m)
