"""A ``gva serve`` process killed mid-run: its trials fail with why, the run finishes, a rerun
against the server brought back resumes.

What a rerun does today (:mod:`harness.trial_log`): every trial in ``trials.jsonl`` is finished,
``perception_failed`` ones included, so the same command runs only the trials that have no
record; the failures the dead server caused stay in the run as outcomes. A run that stopped
before its last trial (Ctrl-C), or the same folder asked for more trials (``--n``: not part of a
run's identity), goes on against the restarted server, which announces the same model.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from gva_cli import gva

from perception.remote import client
from perception.remote.client import RemoteModel

ROOT = Path(__file__).resolve().parents[2]
PLUGINS = ROOT / "examples" / "plugins"
DETECTOR = "colour_detector:ColourDetector"


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def _serve(port: int) -> subprocess.Popen[str]:
    """``gva serve`` of the colour detector on ``port``, in its own process, once it listens."""
    env = os.environ | {"PYTHONPATH": os.pathsep.join([str(ROOT), str(PLUGINS)])}
    process = subprocess.Popen([sys.executable, "-m", "experiments.cli", "serve", DETECTOR,
                                "--port", str(port)], cwd=ROOT, env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    assert process.stdout is not None
    line = process.stdout.readline()
    assert line.startswith(f"serving colour-detector on ws://127.0.0.1:{port}"), line
    return process


@pytest.fixture
def port() -> Iterator[int]:
    yield _free_port()
    client.announced_metadata.cache_clear()  # each gva trials is a process of its own


def _records(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "trials.jsonl").read_text().splitlines()]


def test_a_server_killed_mid_run_fails_its_trials_and_a_rerun_resumes(port, tmp_path,
                                                                      monkeypatch):
    server = _serve(port)
    predict = RemoteModel.predict_frame
    calls: list[int] = []

    def kill_after_two(self, frame, condition):
        if len(calls) == 2 and server.poll() is None:
            server.kill()  # SIGKILL: no close frame, the socket just goes
            server.wait(timeout=20)
        calls.append(1)
        return predict(self, frame, condition)

    monkeypatch.setattr(RemoteModel, "predict_frame", kill_after_two)
    url, out = f"ws://127.0.0.1:{port}", tmp_path / "run"
    command = ("trials", "--model", url, "--task", "single", "--seed", 0, "--out", out,
               "--no-progress")
    try:
        status, stdout, err = gva(*command, "--n", 4)
        assert status == 0, err
        records = _records(out)
        assert [r["index"] for r in records] == [0, 1, 2, 3]
        assert all(r["outcome"] != "perception_failed" for r in records[:2])
        assert [r["outcome"] for r in records[2:]] == ["perception_failed"] * 2
        assert f"server {url} closed the connection" in records[2]["reason"]
        assert f"server {url} unreachable" in records[3]["reason"]
        assert "perception_failed  2" in stdout

        monkeypatch.setattr(RemoteModel, "predict_frame", predict)
        client.announced_metadata.cache_clear()
        server = _serve(port)  # back, the same model
        status, _, err = gva(*command, "--n", 4)  # the same command: nothing left to run
        assert status == 0, err
        assert _records(out) == records  # the dead server's failures stay outcomes
        status, _, err = gva(*command, "--n", 6)  # more trials: resumed against it
        assert status == 0, err
        resumed = _records(out)
        assert resumed[:4] == records and [r["index"] for r in resumed[4:]] == [4, 5]
        assert all(r["outcome"] != "perception_failed" for r in resumed[4:])
        summary = json.loads((out / "summary.json").read_text())
        assert summary["settings"]["announced"]["name"] == "colour-detector"
    finally:
        server.kill()
        server.wait(timeout=20)
