"""studies/check_type_head_picks.py replays a run's trials, and only the types change."""

from __future__ import annotations

import json

import numpy as np
import pytest
from benchmark_scripts import load_study
from gva_cli import gva

from perception.interface import Prediction, Target


class _Typed:
    name = "typed"

    def predict_frame(self, frame, condition):
        return Prediction(targets=(Target(np.array([0.4, 0.0, 0.1]), np.eye(3), "mug"),))


def test_untyped_keeps_the_grasp_and_drops_the_type():
    check = load_study("check_type_head_picks")
    model = check.Untyped(_Typed())
    (target,) = model.predict_frame(None, None).targets
    assert target.object_type is None and model.name == "typed"
    np.testing.assert_array_equal(target.position_m, [0.4, 0.0, 0.1])


@pytest.mark.slow
def test_a_replay_with_the_types_is_the_run_and_without_them_is_paired(tmp_path):
    check = load_study("check_type_head_picks")
    run = tmp_path / "run"
    status, _, stderr = gva("reproduce", "real", "--out", run, "--tasks", "single", "--demos",
                            "2", "--n", "2", "--steps", "3", "--workers", "1", "--holdout",
                            "0", "--no-robustness", "--gif-trials", "0", "--no-progress")
    assert status == 0, stderr
    replay = tmp_path / "replay.json"
    assert check.main(["--run", str(run), "--tasks", "single", "--keep-types",
                       "--out", str(replay)]) == 0
    (kept,) = json.loads(replay.read_text())["sets"]
    assert kept["untyped"] == kept["typed"]  # the replay is the run's own trials
    out = tmp_path / "untyped.json"
    assert check.main(["--run", str(run), "--tasks", "single", "--out", str(out)]) == 0
    (pooled,) = json.loads(out.read_text())["pooled"]
    assert pooled["n"] == 2 and pooled["typed"] == sum(kept["typed"])
    assert sum(pooled["pairs"].values()) == 2
