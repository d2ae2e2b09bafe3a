"""``gva reproduce real --models ws://HOST:PORT``: a served model tried untrained, as a plug-in.

The colour detector (examples/plugins, no weights) is served in a thread; its row is named by
what the server announced and its address, its trial sets record the announcement (a rerun
against a server announcing another model is refused), and a server gone after the run began
costs the trials, not the job.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from gva_cli import gva
from served_detector import DETECTOR, PLUGINS, serve

from experiments.table3.jobs import TrialsJob, run_job
from experiments.table3.layout import seed_folder
from experiments.table3.run import run_task_files, write_run_tasks
from experiments.table3.settings import ReproduceRealSettings, TrialSet, Unit
from perception.plugins import build_plugin
from perception.remote import client
from perception.remote.server import ModelServer


def _serve() -> ModelServer:
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(PLUGINS))
        model = build_plugin(DETECTOR)
    return serve(model)


@pytest.fixture(scope="module")
def served() -> Iterator[str]:
    server = _serve()
    yield f"ws://127.0.0.1:{server.port}"
    server.shutdown()


@pytest.fixture(scope="module")
def run(served, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("reproduce-served") / "run"
    status, stdout, stderr = gva("reproduce", "real", "--out", out, *_options(served))
    assert status == 0, stderr
    assert "2 job(s) run (0 failed), 0 finished earlier" in stdout  # trials and GIF, no training
    return out


def _options(url: str) -> list[object]:
    return ["--models", url, "--tasks", "single", "--n", 1, "--no-robustness", "--workers", 1,
            "--no-progress"]


def test_its_row_is_what_the_server_announced_at_its_address(run, served):
    row = f"colour-detector@{served.removeprefix('ws://')}"
    folder = run / "s0" / "trials" / row / "single"
    records = [json.loads(line) for line in (folder / "trials.jsonl").read_text().splitlines()]
    assert [r["model"] for r in records] == [served]
    stored = json.loads((folder / "run.json").read_text())
    assert stored["model"] == served and stored["announced"]["name"] == "colour-detector"
    assert len(stored["announced"]["source_sha256"]) == 64
    table = json.loads((run / "table3.json").read_text())
    assert table["models"][row]["single"]["n"] == 1
    assert table["settings"]["plugins"] == [row] and table["settings"]["models"] == [served]
    assert table["settings"]["served"][row]["url"] == served
    assert table["settings"]["served"][row]["announced"] == stored["announced"]
    markdown = (run / "table3.md").read_text()
    assert f"| {row} | " in markdown and f"`{row}` (served at {served})" in markdown


def test_a_rerun_resumes_and_another_announcement_is_refused(run, served, tmp_path):
    copied = tmp_path / "run"
    shutil.copytree(run, copied)
    status, stdout, stderr = gva("reproduce", "real", "--out", copied, *_options(served))
    assert status == 0, stderr
    assert "0 job(s) run (0 failed), 2 finished earlier" in stdout
    row = f"colour-detector@{served.removeprefix('ws://')}"
    path = copied / "s0" / "trials" / row / "single" / "run.json"
    stored = json.loads(path.read_text())
    stored["announced"]["source_sha256"] = "0" * 64  # the trials were answered by other code
    path.write_text(json.dumps(stored))
    status, _, stderr = gva("reproduce", "real", "--out", copied, *_options(served))
    assert status == 2 and "1 plug-in trial set(s) made with other settings" in stderr


def test_a_server_that_is_not_there_at_the_start_is_refused_in_one_line(tmp_path):
    status, _, stderr = gva("reproduce", "real", "--out", tmp_path / "run",
                            *_options("ws://127.0.0.1:9"))
    assert status == 2 and "unreachable" in stderr and len(stderr.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists()


def test_a_server_gone_after_the_start_costs_trials_not_the_job(tmp_path):
    server = _serve()
    url = f"ws://127.0.0.1:{server.port}"
    settings = ReproduceRealSettings(models=(url,), tasks=("single",), n=2, variants=(),
                                     workers=1)
    folder = seed_folder(tmp_path, 0)
    write_run_tasks(run_task_files(settings), folder)
    trial_set = TrialSet(Unit(settings.plugins()[0], "single"))
    job = TrialsJob("trials-served", trial_set, settings.trial_settings(folder, trial_set),
                    folder)
    server.shutdown()
    client.announced_metadata.cache_clear()  # as a spawned worker: nothing asked before
    outcome = run_job(job)
    assert outcome.failure is None and outcome.result == "0/2"
    log = folder / "trials" / trial_set.unit.model / "single" / "trials.jsonl"
    records = [json.loads(line) for line in log.read_text().splitlines()]
    assert [r["outcome"] for r in records] == ["perception_failed"] * 2
    assert all(f"server {url} unreachable" in r["reason"] for r in records)
