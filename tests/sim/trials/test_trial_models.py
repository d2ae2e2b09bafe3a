"""Which model a run of trials loads: checkpoints refused or identified, user classes, threads."""

import dataclasses
import json
import re
import shutil
from pathlib import Path

import pytest
import torch
from user_models import synthetic_dataset

from experiments.cli import build_parser, main
from harness.inputs.trial_settings import TrialSettings, load_trial_model
from harness.run_loop import run_trials
from harness.trial_log import TrialLog
from perception.interface import ConditionKind, LabelKind
from perception.learning.checkpoint import read_config
from perception.learning.learnable import ModelSpec
from perception.learning.torch_pieces import LabelScaler
from perception.learning.train import TrainConfig
from perception.learning.validation import CHECK_FILE, HeldOutCheck
from perception.models.kqv import KqvModel
from sim.errors import InvalidInputError, RunFolderError
from sim.tasks.task_toml import load_task, task_to_toml
from sim.world.d435 import D435Config
from sim.world.sensor import SensorConfig, SensorKind


def _checkpoint(folder, dataset=None, spec=None, seed=0):
    """A kqv checkpoint: trained 1 step on ``dataset``, or untrained for ``spec``."""
    if dataset is not None:
        model = KqvModel.for_dataset(dataset)
        model.fit(dataset, TrainConfig(steps=1, threads=1), progress=False)
    else:
        model = KqvModel(spec, KqvModel.config_class(seed=seed),
                         LabelScaler((0.47, 0.0, 0.05), 0.1))
    return model.save(folder)


YUMI_SINGLE = ModelSpec("yumi", "single", LabelKind.GRASP_POSE, 1, ConditionKind.NONE, (), 128,
                        128)


def test_a_position_checkpoint_is_refused_for_trials(tmp_path, capsys):
    folder = _checkpoint(tmp_path / "ckpt", synthetic_dataset(size=2))
    assert main(["trials", "--model", str(folder), "--n", "1", "--out",
                 str(tmp_path / "run"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert f"error: model {folder}: label_kind = 'position' is not allowed: 'grasp_pose': pick " \
           "trials need a grasp pose (TCP position and rotation) per target" in err
    assert not (tmp_path / "run").exists()  # refused before the run folder is made


def test_a_checkpoint_for_another_task_is_refused_naming_both(tmp_path):
    dataset = synthetic_dataset(size=2, conditioned=True, kind=LabelKind.GRASP_POSE)
    folder = _checkpoint(tmp_path / "ckpt", dataset)
    with pytest.raises(InvalidInputError, match=(
            f"model {re.escape(str(folder))} = 'trained for task selected-type on scene synthetic "
            r"\(object_type condition over red, green, blue; 1 target; 64x64 px images\)' is "
            r"not allowed: a checkpoint for trial task single on scene yumi \(no condition; 1 "
            r"target; 128x128 px images\)")):
        load_trial_model(TrialSettings(str(folder), "single"))
    wrong_task = _checkpoint(tmp_path / "yumi-single", spec=YUMI_SINGLE)
    with pytest.raises(InvalidInputError, match=r"trained for task single on scene yumi \(no "
                       r"condition; .* a checkpoint for trial task multiple on scene yumi \(no "
                       r"condition; 3 targets;"):
        load_trial_model(TrialSettings(str(wrong_task), "multiple"))


def test_a_checkpoint_run_is_identified_by_its_weights(tmp_path):
    folder = _checkpoint(tmp_path / "ckpt", spec=YUMI_SINGLE)
    identity = TrialSettings(str(folder), "single").identity()
    assert identity["model"] == "checkpoint"
    assert identity["weights_sha256"] == read_config(folder)["weights_sha256"]
    TrialLog(tmp_path / "run", identity)
    moved = Path(shutil.copytree(folder, tmp_path / "elsewhere"))  # the same weights, moved
    TrialLog(tmp_path / "run", TrialSettings(str(moved), "single").identity())
    _checkpoint(folder, spec=YUMI_SINGLE, seed=1)  # other weights in the same folder
    with pytest.raises(RunFolderError, match="holds a different run"):
        TrialLog(tmp_path / "run", TrialSettings(str(folder), "single").identity())
    with pytest.raises(InvalidInputError, match="model_class = 'user_models:MyKqv' is not "
                       "allowed: None unless model is a checkpoint folder"):
        TrialSettings("oracle", "single", model_class="user_models:MyKqv")
    with pytest.raises(InvalidInputError, match="model = 'user_models:MyKqv' is not allowed: "
                       "a model without weights; a learnable one loads from its checkpoint "
                       "folder: --model FOLDER --model-class user_models:MyKqv"):
        load_trial_model(TrialSettings("user_models:MyKqv", "single"))


def test_trials_run_a_checkpoint_on_one_torch_thread(tmp_path, monkeypatch):
    folder = _checkpoint(tmp_path / "ckpt", spec=YUMI_SINGLE)
    threads, seen = torch.get_num_threads(), []
    original = KqvModel.predict_batch

    def spy(self, images, conditions, *more):
        seen.append(torch.get_num_threads())
        return original(self, images, conditions, *more)

    monkeypatch.setattr(KqvModel, "predict_batch", spy)
    summary = run_trials(TrialSettings(str(folder), "single", n=1), tmp_path / "run",
                         progress=False)
    assert seen == [1] and torch.get_num_threads() == threads
    (line,) = (tmp_path / "run" / "trials.jsonl").read_text().splitlines()
    record = json.loads(line)
    assert summary.n == 1 and record["model"] == str(folder)
    assert record["predicted"]["rotation"] is not None


def test_a_users_model_class_without_weights_runs_trials(tmp_path):
    assert main(["trials", "--model", "user_models:FixedGrasp", "--n", "1", "--out",
                 str(tmp_path), "--no-progress"]) == 0
    (line,) = (tmp_path / "trials.jsonl").read_text().splitlines()
    record = json.loads(line)
    assert record["model"] == "user_models:FixedGrasp"
    assert record["predicted"]["position_m"] == [0.47, 0.0, 0.03]


def test_trials_of_a_checkpoint_that_failed_its_held_out_check_say_so(tmp_path, capsys):
    folder = _checkpoint(tmp_path / "ckpt", spec=YUMI_SINGLE)
    failed = HeldOutCheck(passed=False, reason="held-out mean: 3.07 cm > 2.00 cm",
                          held_out_scenes=(3,), samples=1, mean_position_error_cm=3.07,
                          per_condition_mean_position_error_cm=None,
                          per_target_mean_position_error_cm=(3.07,), limit_cm=2.0, attempt=2,
                          model_seed=7)
    (folder / CHECK_FILE).write_text(json.dumps(failed.to_json()))
    assert main(["trials", "--model", str(folder), "--n", "1", "--out", str(tmp_path / "run"),
                 "--no-progress"]) == 0
    assert "WARNING: checkpoint " in capsys.readouterr().err
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert HeldOutCheck.from_json(summary["held_out_check"]) == failed



def _d435_task_file(tmp_path):
    path = tmp_path / "single-d435.toml"
    path.write_text(task_to_toml(dataclasses.replace(
        load_task("single"), name="single-d435", camera=SensorConfig(SensorKind.D435))))
    return path


def test_a_checkpoint_refuses_trials_under_another_sensor_naming_its_own_flag_first(
        tmp_path, capsys):
    folder = _checkpoint(tmp_path / "ckpt", spec=YUMI_SINGLE)  # its spec: no sensor, so ideal
    task = _d435_task_file(tmp_path)
    with pytest.raises(InvalidInputError, match=(
            f"model {re.escape(str(folder))} = 'trained on images of sensor ideal' is not "
            r"allowed: trials under that sensor \(--sensor ideal; trial task single-d435 is "
            r"seen through d435\), or --allow-sensor-change to try it under d435$")):
        load_trial_model(TrialSettings(str(folder), str(task)))
    with pytest.raises(InvalidInputError, match=r"\(--sensor ideal; trial task single is seen "
                       r"through d435\)"):  # --sensor, the user's choice, differs too
        load_trial_model(TrialSettings(str(folder), "single", sensor=SensorKind.D435))
    load_trial_model(TrialSettings(str(folder), str(task), allow_sensor_change=True))
    load_trial_model(TrialSettings(str(folder), str(task), sensor=SensorKind.IDEAL))
    assert main(["trials", "--model", str(folder), "--task", str(task), "--n", "1", "--out",
                 str(tmp_path / "run"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.index("--sensor ideal") < err.index("or --allow-sensor-change")
    assert not (tmp_path / "run").exists()
    assert build_parser().parse_args(["trials", "--out", "x", "--allow-sensor-change"]
                                     ).allow_sensor_change
    assert build_parser().parse_args(["trials", "--out", "x", "--sensor", "ideal"]
                                     ).sensor == "ideal"


def test_a_task_without_a_sensor_is_tried_under_the_checkpoints_own(tmp_path):
    ideal = _checkpoint(tmp_path / "ideal", spec=YUMI_SINGLE)  # from before sensors: ideal
    d435 = _checkpoint(tmp_path / "d435", spec=dataclasses.replace(
        YUMI_SINGLE, sensor=SensorConfig(SensorKind.D435).to_json()))
    for folder, sensor in ((ideal, SensorConfig()), (d435, SensorConfig(SensorKind.D435))):
        settings = TrialSettings(str(folder), "single")  # single.toml names no sensor
        assert settings.task_spec.camera == sensor
        load_trial_model(settings)
    assert TrialSettings("oracle", "single").task_spec.camera == SensorConfig(SensorKind.D435)


def test_a_checkpoint_trained_under_the_d435_refuses_ideal_trials(tmp_path):
    sensor = SensorConfig(SensorKind.D435).to_json()
    spec = dataclasses.replace(YUMI_SINGLE, sensor=sensor)
    assert ModelSpec.from_json(spec.to_json()) == spec  # the record survives a checkpoint
    assert "sensor" not in YUMI_SINGLE.to_json()  # an ideal spec's JSON as before sensors
    folder = _checkpoint(tmp_path / "ckpt", spec=spec)
    ideal = tmp_path / "single-ideal.toml"
    ideal.write_text(task_to_toml(dataclasses.replace(
        load_task("single"), name="single-ideal", camera=SensorConfig())))
    with pytest.raises(InvalidInputError, match=r"trained on images of sensor d435.* "
                       r"\(--sensor d435; trial task single-ideal is seen through ideal\)"):
        load_trial_model(TrialSettings(str(folder), str(ideal)))
    load_trial_model(TrialSettings(str(folder), str(ideal), sensor=SensorKind.D435))
    load_trial_model(TrialSettings(str(folder), str(_d435_task_file(tmp_path))))


def test_run_json_names_a_d435_sensor_and_ideal_runs_keep_their_identity(tmp_path):
    ideal = TrialSettings("oracle", "single", sensor=SensorKind.IDEAL)
    assert "camera" not in ideal.identity()["task"]  # as before sensors
    d435 = {"sensor": "d435"} | {k: list(v) if isinstance(v, tuple) else v
                                 for k, v in dataclasses.asdict(D435Config()).items()}
    identity = TrialSettings("oracle", str(_d435_task_file(tmp_path))).identity()
    assert identity["task"]["camera"] == d435
    # A task file naming no sensor is the D435's, recorded as a file naming it is (issue 64).
    assert TrialSettings("oracle", "single").identity()["task"] == {
        **identity["task"], "name": "single"}
