"""``gva train``, ``gva evaluate`` and ``gva show attention`` on tiny synthetic datasets."""

from __future__ import annotations

import contextlib
import io
import json
import struct
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.torch import load_file
from user_models import TYPES, given_as, synthetic_dataset

from experiments.cli import main
from perception.drawing import figure_shape, number_size
from perception.interface import ConditionKind, LabelKind
from perception.learning.checkpoint import read_config
from perception.learning.dataset_file import save_dataset
from perception.registry import load_model

FAST = ["--steps", "5", "--batch-size", "4", "--threads", "1", "--holdout", "0", "--no-progress"]


def gva(*args: object) -> tuple[int, str, str]:
    """Runs ``gva`` in this process: (exit status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main([str(a) for a in args])
    return status, out.getvalue(), err.getvalue()


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) of a PNG file, after checking its signature."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    return width, height


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Datasets and checkpoints trained by ``gva train`` (5 steps), shared by the tests."""
    root = tmp_path_factory.mktemp("cli-models")
    paths = {
        "two": save_dataset(synthetic_dataset(size=6, targets=2), root / "two.gva"),
        "cond": save_dataset(synthetic_dataset(size=6, conditioned=True,
                                               kind=LabelKind.GRASP_POSE), root / "cond.gva"),
        "small": save_dataset(synthetic_dataset(size=2, targets=2, image_px=32),
                              root / "small.gva"),
    }
    for name, data in (("two", "two"), ("cond", "cond")):
        status, out, err = gva("train", "--model", "kqv", "--data", paths[data],
                               "--out", root / f"kqv-{name}", *FAST)
        assert status == 0, err
        paths[f"kqv-{name}"] = root / f"kqv-{name}"
        paths[f"train-{name}-stdout"] = Path(root / f"train-{name}.txt")
        paths[f"train-{name}-stdout"].write_text(out)
    return paths


def test_train_writes_a_checkpoint_that_loads(files: dict[str, Path]) -> None:
    out = files["train-two-stdout"].read_text().splitlines()
    assert out[0].startswith("kqv on synthetic / multiple: 6 samples, 5 steps, final loss ")
    assert out[0].endswith(" s on 1 thread(s)")
    assert out[1] == f"checkpoint: {files['kqv-two']}"
    model = load_model(files["kqv-two"])
    assert model.name == "kqv" and model.spec.targets == 2
    # What the training did is stored with the weights: its steps, samples and final loss.
    training = read_config(files["kqv-two"])["training"]
    assert training is not None and (training["steps"], training["samples"]) == (5, 6)
    assert f"final loss {training['final_loss']:.4g}," in out[0]
    # The loaded network holds the file's weights, and those are not a fresh start's.
    stored = load_file(files["kqv-two"] / "weights.safetensors")
    loaded = model.network.state_dict()
    assert set(loaded) == set(stored) and len(stored) > 0
    assert all(torch.equal(loaded[name], stored[name]) for name in stored)
    fresh = type(model)(model.spec, model.config).network.state_dict()
    assert any(not torch.equal(fresh[name], stored[name]) for name in stored)


def test_train_refuses_a_checkpoint_folder_unless_told_to_overwrite(
        files: dict[str, Path], tmp_path: Path) -> None:
    args = ["train", "--model", "kqv", "--data", files["two"], "--out", tmp_path / "k", *FAST]
    assert gva(*args)[0] == 0
    first = read_config(tmp_path / "k")["weights_sha256"]
    status, _, err = gva(*args, "--seed", 1)
    assert status == 2
    assert err.strip() == (f"gva train: error: --out = '{tmp_path / 'k'}' is not allowed: a "
                           "folder without a checkpoint; it holds config.json and "
                           "weights.safetensors (pass --overwrite to replace them)")
    assert read_config(tmp_path / "k")["weights_sha256"] == first
    status, out, _ = gva(*args, "--seed", 1, "--overwrite")
    assert status == 0 and "(replaced)" in out
    assert read_config(tmp_path / "k")["weights_sha256"] != first


def test_train_names_the_allowed_models(files: dict[str, Path], tmp_path: Path) -> None:
    status, _, err = gva("train", "--model", "nosuch", "--data", files["two"],
                         "--out", tmp_path / "k", *FAST)
    assert status == 2
    assert "gva train: error: model = 'nosuch' is not allowed: a registered name (kqv" in err
    assert "'package.module:Class'" in err
    assert not (tmp_path / "k").exists()


def test_train_a_users_class_and_a_hyperparameter_it_lacks(files: dict[str, Path],
                                                          tmp_path: Path) -> None:
    status, out, err = gva("train", "--model", "user_models:MyKqv", "--data", files["two"],
                           "--out", tmp_path / "mine", *FAST)
    assert status == 0, err
    assert out.startswith("my-kqv on synthetic / multiple")
    status, _, err = gva("train", "--model", "kqv", "--points", 4, "--data", files["two"],
                         "--out", tmp_path / "k", *FAST)
    assert status == 2 and "hyper-parameters = ['points'] is not allowed: fields of kqv" in err


def test_evaluate_prints_cm_and_writes_the_json(files: dict[str, Path]) -> None:
    status, out, err = gva("evaluate", "--model", files["kqv-two"], "--data", files["two"])
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("kqv on synthetic / multiple (6 images): position error mean ")
    assert lines[0].endswith(" cm")
    assert lines[1].startswith("per target, mean position error: 0 ")
    path = files["kqv-two"] / "evaluation-two.json"
    assert lines[-1] == f"evaluation: {path}"
    data = json.loads(path.read_text())
    assert data["checkpoint"] == str(files["kqv-two"].resolve())
    assert data["dataset"] == str(files["two"].resolve())
    assert data["weights_sha256"] == read_config(files["kqv-two"])["weights_sha256"]
    assert data["samples"] == 6 and data["targets"] == 2
    assert len(data["position_errors_cm"]) == 6 and len(data["position_errors_cm"][0]) == 2
    assert len(data["per_target_mean_position_error_cm"]) == 2
    assert data["mean_angle_error_deg"] is None
    assert f"{data['mean_position_error_cm']:.2f} cm" in lines[0]


def test_evaluate_grasp_labels_reports_angles_too(files: dict[str, Path], tmp_path: Path) -> None:
    out_file = tmp_path / "sub" / "eval.json"
    status, out, err = gva("evaluate", "--model", files["kqv-cond"], "--data", files["cond"],
                           "--out", out_file)
    assert status == 0, err
    assert "; angle error mean " in out and "per target, mean angle error: 0 " in out
    assert json.loads(out_file.read_text())["mean_angle_error_deg"] > 0


@pytest.mark.parametrize(("data", "differs"), [
    ("cond", "label_kind is 'grasp_pose', the model's is 'position'; targets is 1, the "
             "model's is 2; condition_kind is 'object_type', the model's is 'none'"),
    ("small", "image_height_px is 32, the model's is 64; image_width_px is 32"),
])
def test_a_dataset_of_another_spec_is_refused_naming_what_differs(
        files: dict[str, Path], data: str, differs: str) -> None:
    for command in (["evaluate"], ["show", "attention", "--out", files["two"].parent / "x"]):
        status, out, err = gva(*command, "--model", files["kqv-two"], "--data", files[data])
        assert status == 2 and out == ""
        assert len(err.splitlines()) == 1
        assert (f"error: dataset {files[data]} does not fit the checkpoint {files['kqv-two']} "
                f"(kqv, trained on multiple): {differs}") in err


def test_show_attention_writes_one_png_per_sample(files: dict[str, Path],
                                                  tmp_path: Path) -> None:
    status, out, err = gva("show", "attention", "--model", files["kqv-two"], "--data",
                           files["two"], "--out", tmp_path, "--count", 3, "--scale", 2)
    assert status == 0, err
    pngs = sorted(tmp_path.glob("*.png"))
    assert [p.name for p in pngs] == ["attention-000.png", "attention-001.png",
                                      "attention-002.png"]
    # The image and two heatmaps, each 64 x 64 px enlarged twice, 4 px apart.
    assert figure_shape((64, 64), 2, heads=2, rows=1, labelled=False) == (136, 400)
    assert all(png_size(p) == (400, 136) for p in pngs)
    assert f"sample 0: {pngs[0]}" in out
    assert "  target 1: predicted (" in out and ") m, true (" in out and " cm apart" in out
    assert "  attention points (u, v) px: 0 (" in out


def test_show_attention_draws_a_row_per_condition(files: dict[str, Path],
                                                  tmp_path: Path) -> None:
    status, out, err = gva("show", "attention", "--model", files["kqv-cond"], "--data",
                           files["cond"], "--out", tmp_path, "--count", 1, "--scale", 1)
    assert status == 0, err
    assert out.startswith("rows: 0 = red, 1 = green, 2 = blue")
    label_width = number_size(10, 2)[0] + 4
    width, height = png_size(tmp_path / "attention-000.png")
    assert (height, width) == (4 + 3 * (64 + 4), 4 + label_width + 2 * (64 + 4))


def test_show_attention_says_how_kqv_read_each_sentence(tmp_path: Path) -> None:
    base = synthetic_dataset(size=6, conditioned=True)
    names = base.conditions.argmax(axis=1)
    sentences = np.random.default_rng(0).normal(size=(len(TYPES), 384))
    sentences /= np.linalg.norm(sentences, axis=1, keepdims=True)
    data = save_dataset(given_as(base, ConditionKind.TEXT, sentences[names],
                                 [f"the {TYPES[k]} one" for k in names]), tmp_path / "text.gva")
    assert gva("train", "--model", "kqv", "--data", data, "--out", tmp_path / "k", *FAST)[0] == 0
    status, out, err = gva("show", "attention", "--model", tmp_path / "k", "--data", data,
                           "--out", tmp_path / "png", "--count", 1)
    assert status == 0, err
    assert out.startswith('rows: 0 = red ("the red one"), 1 = green ("the green one")')
    # Each type's one sentence is its prototype: read as that type, nearly all of it.
    assert "kqv reads row 0's sentence as red 1.00, green 0.00, blue 0.00\n" in out


def test_show_attention_refuses_a_model_without_attention_points(
        files: dict[str, Path], tmp_path: Path) -> None:
    status, _, err = gva("train", "--model", "user_models:BlindKqv", "--data", files["two"],
                         "--out", tmp_path / "blind", *FAST)
    assert status == 0, err
    status, _, err = gva("show", "attention", "--model", tmp_path / "blind", "--model-class",
                         "user_models:BlindKqv", "--data", files["two"], "--out", tmp_path)
    assert status == 2
    assert err == (f"gva show: error: model blind-kqv ({tmp_path / 'blind'}) predicts no "
                   "attention points, so there is nothing to draw (conv-ae and fcn have none; "
                   "kqv, keypoint and dsae have them)\n")
    assert not list(tmp_path.glob("*.png"))


def test_points_reach_the_model_and_each_point_gets_a_panel(files: dict[str, Path],
                                                            tmp_path: Path) -> None:
    status, _, err = gva("train", "--model", "keypoint", "--points", 5, "--data", files["two"],
                         "--out", tmp_path / "kp", *FAST)
    assert status == 0, err
    assert read_config(tmp_path / "kp")["hyperparameters"]["points"] == 5
    status, out, err = gva("show", "attention", "--model", tmp_path / "kp", "--data",
                           files["two"], "--out", tmp_path, "--count", 1, "--scale", 1)
    assert status == 0, err
    assert "attention points (u, v) px: 0 (" in out and ", 4 (" in out
    # The image, then five heatmaps: four to a line, the fifth on a second line.
    assert png_size(tmp_path / "attention-000.png") == (4 + 5 * 68, 4 + 2 * 68)


@pytest.mark.parametrize(("data", "queries"), [("two", "base"), ("cond", "conditioned")])
def test_kqv_paper_trains_and_its_checkpoint_shows_the_papers_settings(
        files: dict[str, Path], tmp_path: Path, data: str, queries: str) -> None:
    status, _, err = gva("train", "--model", "kqv-paper", "--data", files[data],
                         "--out", tmp_path / "paper", *FAST)
    assert status == 0, err
    config = read_config(tmp_path / "paper")
    assert config["model"] == "kqv"
    settings = config["hyperparameters"]
    assert {k: settings[k] for k in ("similarity", "starts", "readout", "point_loss_weight",
                                     "stride", "input_norm", "mirror", "type_head",
                                     "focus_window_px", "warmup_steps", "query_mode")} == {
        "similarity": "dot", "starts": 1, "readout": "mlp", "point_loss_weight": 0.0,
        "stride": 4, "input_norm": "fixed", "mirror": False, "type_head": False,
        "focus_window_px": 0, "warmup_steps": 0, "query_mode": "paper"}
    network = load_model(tmp_path / "paper").network
    assert network.readout == "mlp" and network.stride == 4 and not network.per_image
    # Base Queries for a task without a condition, Conditioned Queries alone with one
    assert (network.base_queries is not None) == (queries == "base")
    assert (network.query_mlp is not None) == (queries == "conditioned")
