"""One run per folder: a second run on a folder in use is refused, and no trial is written twice."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from harness.inputs.trial_settings import TrialSettings
from harness.run_folder import run_folder_lock
from harness.run_loop import run_trials
from sim.errors import RunFolderError

ROOT = Path(__file__).resolve().parents[3]


def test_a_folder_in_use_is_refused_with_who_holds_it(tmp_path):
    with run_folder_lock(tmp_path):
        with pytest.raises(RunFolderError, match=rf"{tmp_path} is in use by another run \(process "
                           rf"{os.getpid()} on .*, started .*\); wait until it ends"):
            run_trials(TrialSettings("oracle", "single", n=1), tmp_path, progress=False)
    assert not (tmp_path / "trials.jsonl").exists()
    summary = run_trials(TrialSettings("oracle", "single", n=1), tmp_path, progress=False)
    assert summary.n == 1  # released: the next run goes ahead


def test_two_runs_started_at_once_on_one_folder_write_each_trial_once(tmp_path):
    command = [sys.executable, "-m", "experiments.cli", "trials", "--model", "oracle", "--n",
               "3", "--out", str(tmp_path), "--no-progress"]
    env = os.environ | {"PYTHONPATH": os.pathsep.join([str(ROOT),
                                                       os.environ.get("PYTHONPATH", "")])}
    runs = [subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=env, cwd=ROOT) for _ in range(2)]
    results = [(run.wait(timeout=600), run.stderr.read()) for run in runs]
    for status, err in results:
        assert status == 0 or (status == 2 and "is in use by another run" in err), err
    indices = [json.loads(line)["index"]
               for line in (tmp_path / "trials.jsonl").read_text().splitlines()]
    assert sorted(indices) == [0, 1, 2]
    assert json.loads((tmp_path / "summary.json").read_text())["n"] == 3
