"""``gva serve`` and ``gva trials --model ws://HOST:PORT``: the command lines, end to end."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from gva_cli import gva
from served_detector import DETECTOR, PLUGINS, serve

from perception.plugins import build_plugin
from perception.remote.client import RemoteModelError, _open

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def served():
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(PLUGINS))
        model = build_plugin(DETECTOR)
    server = serve(model)
    yield server
    server.shutdown()


def test_trials_pick_with_a_served_model_and_record_what_it_announced(served, tmp_path):
    url = f"ws://127.0.0.1:{served.port}"
    status, out, err = gva("trials", "--model", url, "--task", "single", "--n", 2,
                           "--out", tmp_path / "run", "--no-progress")
    assert status == 0, err
    assert "2/2 successes" in out
    records = [json.loads(line) for line in (tmp_path / "run" / "trials.jsonl").read_text()
               .splitlines()]
    assert [r["model"] for r in records] == [url, url]
    settings = json.loads((tmp_path / "run" / "summary.json").read_text())["settings"]
    assert settings["model"] == url
    assert settings["announced"]["name"] == "colour-detector"
    assert len(settings["announced"]["source_sha256"]) == 64


def test_a_server_that_is_not_there_stops_trials_before_any_in_one_line(tmp_path):
    status, _, err = gva("trials", "--model", "ws://127.0.0.1:9", "--task", "single", "--n", 1,
                         "--out", tmp_path / "run", "--no-progress")
    assert status == 2 and "unreachable" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("oracle", ["oracle", "oracle-view"])
def test_serve_refuses_the_oracle(tmp_path, oracle):
    status, _, err = gva("serve", oracle, "--port", 0)
    assert status == 2 and oracle in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(("flags", "server_env"), [(["--api-key", "k"], {}),
                                                   ([], {"GVA_API_KEY": "k"})],
                         ids=["--api-key", "GVA_API_KEY"])
def test_gva_serve_announces_its_address_and_serves_only_its_key(monkeypatch, flags,
                                                                 server_env):
    # the key reaches the server whichever way it is given (issue 79: the start-up lines
    # were read and nothing ever connected, so a key that never arrived passed)
    env = {k: v for k, v in os.environ.items() if k != "GVA_API_KEY"} | server_env | {
        "PYTHONPATH": os.pathsep.join([str(ROOT), str(PLUGINS)])}
    process = subprocess.Popen([sys.executable, "-m", "experiments.cli", "serve", DETECTOR,
                                "--port", "0", *flags], cwd=ROOT, env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        assert process.stdout is not None
        line = process.stdout.readline()
        assert line.startswith("serving colour-detector on ws://127.0.0.1:"), line
        announced = json.loads(process.stdout.readline())
        assert announced["name"] == "colour-detector" and announced["protocol"] == "gva-pick/1"
        address = line.split()[-1]
        for key, admitted in ((None, False), ("wrong", False), ("k", True)):
            if key is None:
                monkeypatch.delenv("GVA_API_KEY", raising=False)
            else:
                monkeypatch.setenv("GVA_API_KEY", key)
            if admitted:
                connection, said = _open(address, 10.0)
                connection.close()
                assert said == announced
            else:
                with pytest.raises(RemoteModelError, match="HTTP 401"):
                    _open(address, 10.0)
    finally:
        process.terminate()
        process.wait(timeout=20)


@pytest.mark.parametrize(("flags", "environment", "field"), [
    (["--api-key", ""], {}, "api_key"),
    (["--api-key", "  "], {}, "api_key"),
    ([], {"GVA_API_KEY": ""}, "GVA_API_KEY"),
])
def test_an_empty_api_key_is_refused_not_read_as_none(monkeypatch, flags, environment, field):
    # issue 77: `gva serve --api-key ''` served anyone who connected, and said nothing
    for name, value in environment.items():
        monkeypatch.setenv(name, value)
    status, stdout, stderr = gva("serve", DETECTOR, "--port", "0", *flags)
    assert status == 2 and f"{field} = " in stderr and "non-empty key" in stderr, stderr
    assert "serving" not in stdout
