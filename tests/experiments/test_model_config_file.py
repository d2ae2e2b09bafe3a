"""Model config files: ``gva train --model-config`` and ``gva reproduce sim|real --model-config``.

Tiny synthetic datasets and a few optimiser steps; the reproduce commands are checked through
their settings and a job's call of ``new_model``, never by running the simulator.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import re
from pathlib import Path
from types import SimpleNamespace

import pytest
from user_models import synthetic_dataset

from experiments.cli import main
from experiments.table2.settings import Cell, ReproduceSimSettings
from experiments.table3 import jobs
from experiments.table3.settings import ReproduceRealSettings, Unit
from experiments.tables import model_config
from harness.run_files import refuse_other_settings
from harness.run_folder import json_form
from perception.interface import InvalidInputError
from perception.learning.checkpoint import read_config
from perception.learning.dataset_file import save_dataset
from perception.model_config_file import ModelConfigFile, read_model_config
from perception.registry import trainable
from sim.errors import InvalidInputError as SimInvalidInputError
from sim.errors import RunFolderError

FAST = ["--steps", "3", "--batch-size", "4", "--threads", "1", "--holdout", "0", "--no-progress"]
KQV_FILE = 'similarity = "dot"\nstarts = 1\nchannels = [8, 8]\n'
UNIT = Unit("kqv", "single")


def gva(*args: object) -> tuple[int, str, str]:
    """Runs ``gva`` in this process: (exit status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main([str(a) for a in args])
    return status, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Four scenes of one coloured square, 32 x 32 px."""
    root = tmp_path_factory.mktemp("model-config")
    return save_dataset(synthetic_dataset(size=4, image_px=32), root / "tiny.gva")


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_a_file_sets_the_checkpoints_hyperparameters_and_is_recorded(dataset, tmp_path):
    path = write(tmp_path / "kqv.toml", KQV_FILE)
    status, out, err = gva("train", "--model", "kqv", "--data", dataset, "--out",
                           tmp_path / "ckpt", "--model-config", path, *FAST)
    assert status == 0, err
    config = read_config(tmp_path / "ckpt")
    hyper = config["hyperparameters"]
    assert (hyper["similarity"], hyper["starts"], hyper["channels"]) == ("dot", 1, [8, 8])
    assert hyper["temperature"] == 0.1  # a key left out keeps the default
    assert config["training"]["model_config_file"] == {
        "path": str(path), "settings": {"similarity": "dot", "starts": 1, "channels": [8, 8]}}
    assert f"model config {path}: similarity = 'dot', starts = 1, channels = (8, 8)" in out


def test_a_checkpoint_trained_without_a_file_records_none(dataset, tmp_path):
    status, _, err = gva("train", "--model", "kqv", "--data", dataset, "--out", tmp_path / "c",
                         *FAST)
    assert status == 0, err
    assert "model_config_file" not in read_config(tmp_path / "c")["training"]


@pytest.mark.parametrize(("text", "message"), [
    ("simil = 1\n", r"model config {path}: simil = 1 is not allowed: a known key, one of the "
                    r"fields of KqvConfig: channels, key_dim, .*context_layers, depth_input, "
                    r"value_input, repaint$"),
    ('similarity = "l2"\n', r"model config {path}: similarity = 'l2' is not allowed: one of "
                            r"'cosine', 'dot'$"),
    ("seed = 3\n", r"model config {path}: seed = 3 is not allowed: set by --seed, not by the "
                   r"file; its keys are fields of KqvConfig: channels, .*"),
    ("[net]\nstarts = 1\n", r"model config {path}: net = \{'starts': 1\} is not allowed: a "
                            r"value, not a \[table\]: .*fields of KqvConfig: channels, .*"),
    ("head_coords = 1\n", r"model config {path}: head_coords = 1 is not allowed: true or false$"),
    ("starts = \n", r"model config {path} = 'not valid TOML' is not allowed: TOML \(Invalid "
                    r"value \(at line 1, column 10\)\)$"),
    (None, r"model config {path} = 'no such file or directory' is not allowed: an existing, "
           r"readable TOML file$"),
    # issue 63: a torch "can't allocate memory" traceback, and a training that never ended
    ("key_dim = 1000000000000\n", r"model config {path}: key_dim = 1000000000000 is not "
                                  r"allowed: an integer >= 1 and <= 4096$"),
    ("starts = 99999999999999999999\n", r"model config {path}: starts = 99999999999999999999 "
                                        r"is not allowed: an integer >= 1 and <= 100$"),
], ids=["unknown-key", "bad-value", "seed", "nested-table", "wrong-type", "bad-toml", "missing",
        "key-dim-too-wide", "starts-beyond-64-bits"])
def test_a_bad_file_is_one_line_naming_file_key_value_and_allowed(dataset, tmp_path, text,
                                                                   message):
    path = tmp_path / "bad.toml"
    if text is not None:
        write(path, text)
    status, _, err = gva("train", "--model", "kqv", "--data", dataset, "--out",
                         tmp_path / "ckpt", "--model-config", path, *FAST)
    assert status == 2
    lines = err.splitlines()
    assert len(lines) == 1
    expected = re.escape("gva train: error: ") + message.replace("{path}", re.escape(str(path)))
    assert re.match(expected, lines[0]), lines[0]
    assert not (tmp_path / "ckpt").exists()


def test_points_given_twice_names_both_options(dataset, tmp_path):
    path = write(tmp_path / "kp.toml", "points = 4\n")
    status, _, err = gva("train", "--model", "keypoint", "--data", dataset, "--out",
                         tmp_path / "ckpt", "--model-config", path, "--points", 3, *FAST)
    assert status == 2
    assert err.strip() == (f"gva train: error: --points = 3 is not allowed: left out: "
                           f"--model-config {path} sets points too (4); give it one way")
    assert not (tmp_path / "ckpt").exists()


def test_a_file_changes_a_presets_settings_and_keeps_the_rest(tmp_path):
    path = write(tmp_path / "paper.toml", "starts = 2\n")
    assert read_model_config(path, "kqv-paper") == {"starts": 2}
    # a value the preset's config refuses names the file
    with pytest.raises(InvalidInputError, match=r"^model config .*paper.toml: points"):
        read_model_config(write(tmp_path / "paper.toml", "points = 0\n"), "keypoint-16")


# gva reproduce real and sim


def kqv_file(tmp_path: Path, text: str = KQV_FILE) -> ModelConfigFile:
    return ModelConfigFile.read(write(tmp_path / "kqv.toml", text), "kqv")


def test_a_model_config_changes_the_checkpoint_identity_and_the_command(tmp_path):
    plain = ReproduceRealSettings(tasks=("single",))
    tuned = ReproduceRealSettings(tasks=("single",), model_configs=(kqv_file(tmp_path),))
    # without a file, the identity is the one folders made before files existed hold
    assert plain.train_identity(UNIT)["model_config"] == json_form(model_config("kqv", 0))
    assert tuned.train_identity(UNIT)["model_config"] == {
        **json_form(model_config("kqv", 0)), "similarity": "dot", "starts": 1, "channels": [8, 8]}
    assert tuned.command(Path("runs/x")) == (plain.command(Path("runs/x")) +
                                             f" --model-config kqv={tmp_path / 'kqv.toml'}")
    with pytest.raises(RunFolderError, match=r"model_config.similarity': \('cosine', 'dot'\)"):
        refuse_other_settings([("checkpoints/kqv/single", plain.train_identity(UNIT),
                                tuned.train_identity(UNIT))], "checkpoint(s)")
    hash(tuned)  # frozen settings stay hashable


def test_the_training_job_passes_the_files_settings_to_new_model(tmp_path, monkeypatch):
    settings = ReproduceRealSettings(tasks=("single",), demos=2,
                                     model_configs=(kqv_file(tmp_path),))
    seen: dict[str, object] = {}

    class Demonstrations(list):
        """Stands for the task's two demonstrations: ``_train`` counts them, then builds."""

        metadata = SimpleNamespace(extra={"scenes": 2})

    class Built(Exception):
        """Stops the job once the model is asked for."""

    def fake_new_model(name, data, *, seed, **hyperparameters):
        seen.update(hyperparameters, name=name)
        raise Built

    monkeypatch.setattr(jobs, "new_model", fake_new_model)
    monkeypatch.setattr(jobs, "load_dataset", lambda path, expect: Demonstrations())
    monkeypatch.setattr(jobs, "fit_checked", lambda build, *args, **kwargs: build(0))
    with pytest.raises(Built):
        jobs._train(jobs.TrainJob("train", UNIT, settings, {}, tmp_path))
    assert seen == {"name": "kqv", "similarity": "dot", "starts": 1, "channels": (8, 8)}


def test_a_model_config_for_a_model_not_run_is_refused(tmp_path):
    path = write(tmp_path / "fcn.toml", "head_width = 8\n")
    status, _, err = gva("reproduce", "real", "--out", tmp_path / "run", "--models", "kqv",
                         "--model-config", f"fcn={path}", "--no-progress")
    assert status == 2
    assert err.strip() == (f"gva reproduce real: error: --model-config = 'fcn={path}' is not "
                           "allowed: MODEL=FILE.toml, at most one per MODEL, MODEL one of "
                           "--models: kqv")
    assert not (tmp_path / "run").exists()
    with pytest.raises(SystemExit):  # no MODEL=: argparse's own error
        gva("reproduce", "real", "--out", tmp_path / "run", "--model-config", str(path))


def test_a_model_config_changes_a_table2_cells_identity_and_command(tmp_path):
    plain = ReproduceSimSettings(models=("kqv",))
    tuned = ReproduceSimSettings(models=("kqv",), model_configs=(kqv_file(tmp_path),))
    cell = Cell("kqv", "single", 4, 0)
    assert plain.cell_identity(cell)["model_config"] == json_form(model_config("kqv", 0))
    assert tuned.cell_identity(cell)["model_config"]["similarity"] == "dot"
    assert tuned.command(Path("o")).endswith(f" --model-config kqv={tmp_path / 'kqv.toml'}")
    with pytest.raises(SimInvalidInputError, match="MODEL one of --models: kqv"):
        ReproduceSimSettings(models=("kqv",), model_configs=(
            ModelConfigFile.read(write(tmp_path / "f.toml", ""), "fcn"),))


def test_fields_added_later_stay_out_of_identities_at_their_old_behaviour():
    before = {"channels", "head_width", "points", "rotation_loss_weight", "seed", "temperature"}
    assert set(model_config("keypoint-16", 0)) == before  # folders made before them resume
    helped = model_config("keypoint-16-helped", 0)
    assert helped["readout"] == "ray" and helped["input_norm"] == "per-image"
    assert "mirror" in helped and "point_loss_weight" in helped


def _too_big(value: object) -> str:
    """TOML for a value far past any bound, of the kind of ``value`` (a field's default)."""
    if isinstance(value, tuple):
        return "[" + ", ".join(_too_big(item) for item in value) + "]"
    return "1e300" if isinstance(value, float) else "1000000000000"


@pytest.mark.parametrize("model", ["kqv", "keypoint", "dsae", "fcn", "conv-ae"])
def test_every_number_of_a_models_config_has_an_upper_bound(tmp_path, model):
    # issue 63: model-config integers had no upper bound (and the floats none either)
    config_class = trainable(model)[0].config_class
    numbers = [f for f in dataclasses.fields(config_class) if f.name != "seed" and (
        (isinstance(f.default, int | float | tuple) and not isinstance(f.default, bool))
        or (f.default is None and f.type in ("int | None", "float | None")))]
    assert len(numbers) >= 3  # fcn: head_width, rotation_loss_weight, channels
    for field in numbers:
        default = 1 if field.default is None else field.default
        path = write(tmp_path / f"{field.name}.toml", f"{field.name} = {_too_big(default)}\n")
        with pytest.raises(InvalidInputError) as refused:
            read_model_config(path, model)
        message = str(refused.value)
        assert message.startswith(f"model config {path}: {field.name} = "), message
        assert "\n" not in message
        assert re.search(r"<= [0-9.e+]+$|one of .*|a fraction in \[0, 1\)$", message), message


def test_hue_jitter_is_a_kqv_setting_left_out_of_identities_at_its_default():
    from experiments.tables import model_config
    from perception.models.kqv_config import KqvConfig

    assert "hue_jitter" not in model_config("kqv", 0)  # folders made before it resume
    assert model_config("kqv", 0, {"hue_jitter": 0.25})["hue_jitter"] == 0.25
    with pytest.raises(InvalidInputError, match=r"hue_jitter = 0\.6 is not allowed: a finite "
                       r"value >= 0 and <= 0\.5"):
        KqvConfig(hue_jitter=0.6)


EXAMPLE_CONFIGS = Path(__file__).parents[2] / "examples" / "model-configs"


@pytest.mark.parametrize("path", sorted(EXAMPLE_CONFIGS.glob("*.toml")), ids=lambda p: p.stem)
def test_every_shipped_example_config_is_one_kqv_takes(path):
    """The docs' example configs (kqv for a varied world, for closed-loop picks) read as kqv's
    settings, each key a field it has."""
    settings = read_model_config(path, "kqv")
    assert settings and all(isinstance(key, str) for key in settings)
