"""A misbehaving plug-in costs its trial, never the run: each misbehaviour is a recorded outcome.

Every case runs ``gva trials`` as a user would, on the models of ``tests/user_models.py``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import user_models

from experiments.cli import main


def _trials(tmp_path, model, capsys, n=1):
    """Runs ``gva trials --model user_models:MODEL``; (exit status, records, out, err)."""
    status = main(["trials", "--model", f"user_models:{model}", "--n", str(n), "--out",
                   str(tmp_path), "--no-progress"])
    out, err = capsys.readouterr()
    log = tmp_path / "trials.jsonl"
    records = [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []
    return status, records, out, err


@pytest.mark.parametrize(("model", "reason"), [
    ("Raises", "misbehaving's predict raised RuntimeError: the detector lost its calibration"),
    ("ReturnsNone", "misbehaving returned NoneType, not a perception.interface.Prediction"),
    ("NanPosition", "misbehaving's predict raised InvalidInputError: position_m = "
                    "[0.47, nan, 0.03] is not allowed: finite numbers"),
    ("InfAfterwards", "misbehaving's target 1 of 1: position_m = [0.47, 0.0, inf] is not three "
                      "finite numbers"),
    ("TwoTargets", "misbehaving predicted 2 targets; this pick needs 1"),
    ("NotARotation", "misbehaving's target 1 of 1: rotation = 'matrix 0 = "),
])
def test_a_misbehaving_prediction_is_a_recorded_perception_failure(tmp_path, capsys, model,
                                                                    reason):
    status, (record,), out, err = _trials(tmp_path, model, capsys)
    assert status == 0
    assert record["outcome"] == "perception_failed"
    assert record["reason"].startswith(reason)
    assert ("traceback" in record["picks"][0]) == (model in ("Raises", "NanPosition"))
    assert "Traceback" not in out + err and "0/1 successes" in out


def test_the_traceback_of_a_raising_model_is_kept_in_its_record(tmp_path, capsys):
    _, (record,), _, _ = _trials(tmp_path, "Raises", capsys)
    traceback = record["picks"][0]["traceback"]
    assert traceback.startswith("Traceback (most recent call last)")
    assert "user_models.py" in traceback and "the detector lost its calibration" in traceback


@pytest.mark.parametrize(("model", "message"), [
    ("Nameless", "user_models:Nameless' is not allowed: a class with a name"),
    ("BrokenConstructor", "a class that builds with no arguments; BrokenConstructor() raised "
                          "FileNotFoundError: weights.bin"),
    ("NotAModel", "a subclass of perception.interface.PerceptionModel"),
    ("DepthWithoutFrame", "{ModelInput.RGB} for a model that implements only predict(image, "
                          "condition)"),
    ("StringInputs", "a non-empty frozenset of ModelInput.RGB, ModelInput.DEPTH, "
                     "ModelInput.CAMERA"),
])
def test_a_model_that_cannot_be_used_is_one_line_and_exit_2(tmp_path, capsys, model, message):
    status, records, _, err = _trials(tmp_path / "run", model, capsys)
    assert status == 2 and records == [] and not (tmp_path / "run").exists()
    assert err.count("\n") == 1 and err.startswith("gva trials: error: model")
    assert message in err and "Traceback" not in err


@pytest.mark.parametrize(("model", "status", "why"), [
    ("ExitsOnSecondCall", 1, "stopped: the model raised SystemExit(3) after 1 finished trials"),
    ("InterruptedOnSecondCall", 130, "stopped: interrupted after 1 finished trials"),
])
def test_system_exit_and_ctrl_c_stop_the_run_with_the_summary_of_what_finished(
        tmp_path, capsys, model, status, why):
    getattr(user_models, model).calls = 0
    code, records, out, err = _trials(tmp_path, model, capsys, n=3)
    assert code == status
    assert [r["index"] for r in records] == [0]
    assert "1/1 successes" in out or "0/1 successes" in out
    assert why in err and f"resume with: gva trials --model user_models:{model} --n 3" in err
    assert json.loads((tmp_path / "summary.json").read_text())["n"] == 1


def test_a_model_reads_the_depth_and_calibration_it_declares(tmp_path, capsys):
    """The trial hands a frame model the depth and the camera that took it: the only test that does.

    ``DepthReader`` grasps the highest point its frame's depth puts in the world; the scene's
    one object is a spray bottle, whose top is its trigger head's (catalog: a 26 mm box centred
    160 mm up and 10 mm forward of the axis). Without depth the model falls back on
    ``FixedGrasp``'s (0.47, 0, 0.03); with a wrong calibration the point lands elsewhere.
    """
    status, (record,), _, err = _trials(tmp_path, "DepthReader", capsys)
    assert status == 0, err
    assert record["predicted"] is not None, record["reason"]
    (bottle,) = record["objects"]
    assert bottle["type"] == "spray_bottle"
    yaw = bottle["yaw_rad"]
    head_xy = np.array(bottle["position_xy_m"]) + 0.010 * np.array([np.cos(yaw), np.sin(yaw)])
    seen = np.array(record["predicted"]["position_m"])
    assert seen[2] == pytest.approx(0.160 + 0.013, abs=0.004)  # the head's top, 0.173 m
    assert np.linalg.norm(seen[:2] - head_xy) < 0.028  # on the head's 50 x 26 mm top
