"""``gva reproduce real --models kqv,colour_detector:ColourDetector``: a plug-in beside kqv.

The plug-in (examples/plugins) is tried untrained on kqv's scenes: its rows, records and paired
differences, no training job, a resumed run, a changed identity and bad specs refused.
"""

from __future__ import annotations

import json
import shutil
import textwrap
from pathlib import Path

import pytest
from gva_cli import gva

from experiments.table3.layout import task_file
from experiments.table3.settings import ReproduceRealSettings, TrialSet, Unit
from harness.inputs.trial_settings import TrialSettings

PLUGINS = Path(__file__).resolve().parents[2] / "examples" / "plugins"
SPEC = "colour_detector:ColourDetector"
TINY = ["--models", f"kqv,{SPEC}", "--tasks", "single", "--demos", "2", "--n", "2", "--steps",
        "3", "--workers", "1", "--variants", "dark", "--gif-trials", "1", "--no-progress"]


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """A tiny run of kqv and the detector, then the same command again (it resumes)."""
    out = tmp_path_factory.mktemp("reproduce-real-plugin") / "run"
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(PLUGINS))
        status, stdout, stderr = gva("reproduce", "real", "--out", out, *TINY)
        assert status == 0, stderr
        # kqv: collect, train, trials plain and dark, GIF; the detector: trials, trials, GIF
        assert "8 job(s) run (0 failed), 0 finished earlier" in stdout
        assert f"| {SPEC} | " in stdout
        status, stdout, stderr = gva("reproduce", "real", "--out", out, *TINY)
        assert status == 0, stderr
        assert "0 job(s) run (0 failed), 8 finished earlier" in stdout
    return out


def _records(out: Path, model: str, name: str) -> list[dict]:
    log = out / "s0" / "trials" / model / name / "trials.jsonl"
    return sorted(map(json.loads, log.read_text().splitlines()), key=lambda r: r["index"])


@pytest.mark.slow
def test_the_plugin_is_tried_without_demonstrations_or_training(run):
    computed = [json.loads(line)["computed"] for line in
                (run / "history.jsonl").read_text().splitlines()]
    assert computed[1] == []  # the second run resumed everything
    assert sorted(computed[0]) == sorted([
        "collect-single-s0", "train-kqv-single-s0", "trials-kqv-single-s0",
        "trials-kqv-single-dark-s0", "gif-kqv-single-s0", f"trials-{SPEC}-single-s0",
        f"trials-{SPEC}-single-dark-s0", f"gif-{SPEC}-single-s0"])
    assert [p.name for p in (run / "s0" / "checkpoints").iterdir()] == ["kqv"]
    assert (run / "s0" / "gifs" / f"{SPEC}-single.gif").read_bytes()[:6] == b"GIF89a"


def test_its_records_are_those_gva_trials_makes_on_kqvs_scenes(run):
    for name in ("single", "single-dark"):
        ours, kqv = _records(run, SPEC, name), _records(run, "kqv", name)
        assert [r["index"] for r in ours] == [0, 1] == [r["index"] for r in kqv]
        assert [r["objects"] for r in ours] == [r["objects"] for r in kqv]  # the same scenes
        assert {r["model"] for r in ours} == {SPEC} and {r["seed"] for r in ours} == {0}
    folder = run / "s0" / "trials" / SPEC / "single"
    stored = json.loads((folder / "run.json").read_text())
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(PLUGINS))
        settings = ReproduceRealSettings(models=("kqv", SPEC), tasks=("single",), n=2, demos=2,
                                         steps=3, variants=("dark",), workers=1)
        assert settings.plugins() == (SPEC,)
        trials = settings.trial_settings(run / "s0", TrialSet(Unit(SPEC, "single")))
    # what gva trials --model SPEC --task <the run's task file> records
    assert trials == TrialSettings(model=SPEC, task=str(task_file(run / "s0", "single")), n=2)
    assert stored["model"] == SPEC and "weights_sha256" not in stored
    assert {k: v for k, v in stored.items() if k not in ("provenance", "format_version")} == (
        json.loads(json.dumps(trials.identity())))
    assert len(stored["provenance"]) == 1  # the session that ran it; the resume ran nothing


def test_its_rows_counts_and_paired_differences_are_a_trained_models(run):
    table = json.loads((run / "table3.json").read_text())
    single = table["models"][SPEC]["single"]
    assert single["n"] == 2 and single["per_seed"] == [
        {"seed": 0, "successes": single["successes"], "n": 2, "unfinished": False}]
    assert single["mean"] == single["successes"] and single["std"] == 0.0
    dark = table["variants"]["models"][SPEC]["dark"]["single"]
    assert dark["n"] == 2 and [(e["seed"], e["n"]) for e in dark["against_clean"]] == [(0, 2)]
    against = table["against_kqv"]["models"][SPEC]["single"]
    assert [(e["seed"], e["n"]) for e in against] == [(0, 2)]
    assert table["settings"]["models"] == ["kqv", SPEC] and table["settings"]["plugins"] == [SPEC]
    assert f"--models kqv,{SPEC}" in table["settings"]["command"]
    markdown = (run / "table3.md").read_text()
    for row in (f"| {SPEC} | {single['successes']}/2 |",
                f"| {SPEC}, darker light (brightness 0.5) | {dark['successes']}/2 |",
                f"| {SPEC}, seed 0 | ", f"| {SPEC}, darker light (brightness 0.5), seed 0 | "):
        assert row in markdown
    assert f"Plug-ins, untrained, on the same test scenes: `{SPEC}`." in markdown


def test_a_plugin_set_made_with_other_settings_is_refused_before_any_job(run, tmp_path):
    copied = tmp_path / "run"
    shutil.copytree(run, copied)
    path = copied / "s0" / "trials" / SPEC / "single-dark" / "run.json"
    stored = json.loads(path.read_text())
    path.write_text(json.dumps(stored | {"settle_s": 0.5}))
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(PLUGINS))
        status, _, stderr = gva("reproduce", "real", "--out", copied, *TINY)
    assert status == 2
    assert "1 plug-in trial set(s) made with other settings" in stderr
    assert "'settle_s': (0.5, 0.25)" in stderr and "single-dark" in stderr
    history = (copied / "history.jsonl").read_text().splitlines()
    assert len(history) == 2  # refused before running anything


BAD_PLUGIN = '''
from perception.interface import LabelKind, PerceptionModel


class Positions(PerceptionModel):
    name = "positions"
    label_kind = LabelKind.POSITION

    def predict(self, image, condition):
        raise NotImplementedError
'''


@pytest.mark.parametrize(("spec", "refusal"), [
    ("no_such_module:Detector", "models = 'no_such_module:Detector' is not allowed: one of "
     "kqv, keypoint, dsae, conv-ae, fcn, keypoint-16"),
    ("bad_plugin:Missing", "models = 'bad_plugin:Missing' is not allowed: one of kqv"),
    ("bad_plugin:Positions", "model bad_plugin:Positions: label_kind = 'position' is not "
     "allowed: 'grasp_pose': pick trials need a grasp pose"),
])
def test_a_plugin_that_cannot_be_imported_or_serve_is_refused_before_writing(
        tmp_path, monkeypatch, spec, refusal):
    (tmp_path / "bad_plugin.py").write_text(textwrap.dedent(BAD_PLUGIN))
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "run"
    status, _, stderr = gva("reproduce", "real", "--out", out, "--models", f"kqv,{spec}",
                            "--tasks", "single")
    assert status == 2 and refusal in stderr
    assert len(stderr.strip().splitlines()) == 1
    assert not out.exists()
