"""``gva compare``: two run folders paired trial by trial; refusals; Table III's comparisons.

The run folders are written here as ``gva trials`` writes them (``run.json`` from
:meth:`TrialSettings.identity`, ``trials.jsonl``, ``summary.json``), with outcomes chosen by
the test: running 30 real trials per folder would take minutes.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import pytest
from gva_cli import gva

from experiments.table3.report import (
    baseline_comparisons,
    table3_json,
    table3_markdown,
    variant_comparisons,
)
from experiments.table3.trial_sets import TrialSetResult
from harness.inputs.trial_settings import TrialSettings
from harness.trial_summary import TrialSummary
from sim.trials.records import TrialOutcome, TrialRecord

OK, FAILED = TrialOutcome.SUCCESS, TrialOutcome.PERCEPTION_FAILED
TYPES = ("mug", "sponge", "spray_bottle")


def trials(outcomes: Sequence[TrialOutcome], model: str = "oracle", seed: int = 0,
           task: str = "single") -> list[TrialRecord]:
    """Trial ``i`` with ``outcomes[i]``, its one pick aimed at object ``TYPES[i % 3]``."""
    records = []
    for index, outcome in enumerate(outcomes):
        target = TYPES[index % len(TYPES)]
        records.append(TrialRecord(
            index=index, seed=seed, task=task, model=model, outcome=outcome, reason="test",
            target=target, objects=[{"type": target, "distractor": False,
                                     "position_xy_m": [0.45, 0.01 * index], "yaw_rad": 0.0}],
            picks=[{"target": target, "outcome": outcome.value}]))
    return records


def write_run(folder: Path, records: Sequence[TrialRecord], n: int | None = None,
              task: str = "single", seed: int = 0) -> Path:
    """A run folder of ``records`` as ``gva trials`` writes one (n: the number it was asked)."""
    n = len(records) if n is None else n
    settings = TrialSettings(model="oracle", task=task, n=n, seed=seed)
    identity = settings.identity() | {"model": records[0].model if records else "oracle"}
    folder.mkdir(parents=True)
    (folder / "run.json").write_text(json.dumps({"format_version": 1, **identity}))
    (folder / "trials.jsonl").write_text("".join(r.to_json() + "\n" for r in records))
    summary = {"settings": identity | {"n": n}} | TrialSummary.of(list(records)).to_dict()
    (folder / "summary.json").write_text(json.dumps(summary))
    return folder


def compared(tmp_path: Path, *argv: object) -> tuple[int, str, str, dict]:
    """``gva compare ARGV --out FILE``: status, stdout, stderr and the JSON written."""
    out = tmp_path / "comparison.json"
    status, stdout, stderr = gva("compare", *argv, "--out", out)
    return status, stdout, stderr, json.loads(out.read_text()) if out.exists() else {}


def test_a_run_against_itself_has_p_1_and_no_difference(tmp_path):
    run = write_run(tmp_path / "a", trials([OK] * 20 + [TrialOutcome.MISSED] * 10))
    status, stdout, stderr, data = compared(tmp_path, run, run)
    assert status == 0, stderr
    assert (data["mcnemar_exact_p"], data["difference_b_minus_a"]) == (1.0, 0.0)
    assert data["pairs"] == {"both": 20, "only_a": 0, "only_b": 0, "neither": 10}
    low, high = data["difference_interval95"]
    assert low == pytest.approx(-high) and low < 0
    assert data["outcomes"] == {"success": {"success": 20, "missed": 0},
                                "missed": {"success": 0, "missed": 10}}
    assert data["verdict"] == "no_significant_difference" and data["exit_status"] == 0
    assert "exact McNemar p = 1" in stdout and "B - A: +0.0 %" in stdout
    assert f"A: 20/30 successes  {run} (model oracle)" in stdout


def test_the_oracle_against_a_model_that_always_fails(tmp_path):
    oracle = write_run(tmp_path / "oracle", trials([OK] * 30))
    broken = write_run(tmp_path / "broken", trials([FAILED] * 30, model="user_models:Raises"))
    status, stdout, stderr, data = compared(tmp_path, oracle, broken)
    assert status == 1, stderr  # B significantly worse: a CI job fails
    assert data["mcnemar_exact_p"] == pytest.approx(2 * 0.5 ** 30)
    assert data["mcnemar_exact_p"] < 0.001
    assert data["difference_b_minus_a"] == -1.0 and data["difference_interval95"][1] < -0.8
    assert data["outcomes"] == {"success": {"perception_failed": 30}}
    assert data["model_a"] == "oracle" and data["model_b"] == "user_models:Raises"
    assert data["per_object"]["mug"]["pairs"] == {"both": 0, "only_a": 10, "only_b": 0,
                                                  "neither": 0}
    assert "B is significantly worse than A (p < 0.05)" in stdout
    status, stdout, _, data = compared(tmp_path, broken, oracle)  # the other way round
    assert status == 0 and data["verdict"] == "b_better"
    assert "B is significantly better than A" in stdout


def test_a_lower_rate_without_significance_exits_0(tmp_path):
    a = write_run(tmp_path / "a", trials([OK] * 28 + [FAILED] * 2))
    b = write_run(tmp_path / "b", trials([OK] * 25 + [FAILED] * 5, model="other"))
    status, _, stderr, data = compared(tmp_path, a, b)
    assert status == 0, stderr
    assert data["pairs"] == {"both": 25, "only_a": 3, "only_b": 0, "neither": 2}
    assert data["mcnemar_exact_p"] == pytest.approx(0.25)  # 2 (1/2)^3
    assert data["difference_b_minus_a"] == pytest.approx(-0.1)


@pytest.mark.parametrize(("change", "named"), [
    ({"seed": 1}, "seed of B ({b}) = 1 is not allowed: 0, as in A ({a})"),
    ({"n": 12}, "n of B ({b}) = 12 is not allowed: 30, as in A ({a})"),
    ({"task": "selected-type"},
     "task.name of B ({b}) = 'selected-type' is not allowed: 'single', as in A ({a})"),
])
def test_runs_of_other_trials_are_refused_naming_the_field_and_both_values(tmp_path, change,
                                                                           named):
    a = write_run(tmp_path / "a", trials([OK] * 30))
    seed, task = change.get("seed", 0), change.get("task", "single")
    records = trials([OK] * change.get("n", 30), seed=seed, task=task)
    b = write_run(tmp_path / "b", records, seed=seed, task=task)
    status, stdout, stderr, data = compared(tmp_path, a, b)
    assert status == 2 and stdout == "" and data == {}
    assert stderr == f"gva compare: error: {named.format(a=a, b=b)}: pairs need runs of the " \
                     "same trials (the same task, scene, seed and n)\n"


def test_folders_that_are_not_finished_runs_are_refused_in_one_line(tmp_path):
    a = write_run(tmp_path / "a", trials([OK] * 12))
    unfinished = write_run(tmp_path / "unfinished", trials([OK] * 5), n=12)
    damaged = write_run(tmp_path / "damaged", trials([OK] * 12))
    (damaged / "trials.jsonl").write_text("{not json\n" + (damaged / "trials.jsonl").read_text())
    table3 = tmp_path / "table3"
    (table3 / "s0").mkdir(parents=True)
    (table3 / "table3.json").write_text("{}")
    other_scenes = write_run(tmp_path / "other", [
        TrialRecord(**{**vars(r), "objects": [{"type": "block"}]}) if r.index == 3 else r
        for r in trials([OK] * 12)])
    cases = {
        unfinished: f"{unfinished} is an unfinished run: 5 of its 12 trials are done; run the "
                    "same gva trials command again to finish it",
        damaged: f"{damaged / 'trials.jsonl'} line 1 is damaged",
        tmp_path / "missing": f"{tmp_path / 'missing'} is not a folder",
        table3: f"{table3} is not a finished run of gva trials: it has no run.json or "
                "trials.jsonl or summary.json; a gva reproduce real folder holds its runs in "
                "s<seed>/trials/<model>/<task>",
        other_scenes: "trial 3 objects of B = [{'type': 'block'}] is not allowed: "
                      "[{'distractor': False, 'position_xy_m': [0.45, 0.03], 'type': 'mug'",
    }
    for folder, message in cases.items():
        status, stdout, stderr, _ = compared(tmp_path, a, folder)
        assert status == 2 and stdout == "", folder
        assert stderr.startswith(f"gva compare: error: {message}"), stderr
        assert stderr.count("\n") == 1 and "Traceback" not in stderr
    status, _, stderr = gva("compare", a, a, "--out", tmp_path)
    assert status == 2 and f"--out = '{tmp_path}' is not allowed: a file" in stderr


def test_a_trials_file_or_run_file_not_utf8_is_one_line_naming_the_file(tmp_path):
    # issue 63: "'utf-8' codec can't decode byte 0xff in position 0: invalid start byte"
    a = write_run(tmp_path / "a", trials([OK] * 3))
    b = write_run(tmp_path / "b", trials([OK] * 3))
    log = b / "trials.jsonl"
    log.write_bytes(b"\xff" + log.read_bytes())
    status, stdout, stderr = gva("compare", a, b)
    assert status == 2 and stdout == ""
    assert stderr == (f"gva compare: error: {log} line 1 is damaged (not UTF-8 text (byte 0 is "
                      "0xff), not a line gva trials wrote); run the same gva trials command "
                      "again to repair and finish it\n")
    summary = a / "summary.json"
    summary.write_bytes(b"\xfe" + summary.read_bytes())
    status, stdout, stderr = gva("compare", a, a)
    assert status == 2 and stderr == (f"gva compare: error: {summary} is damaged (not UTF-8 "
                                      "text: byte 0 is 0xfe)\n")


def _set(model: str, task: str, per_seed: dict[int, list[TrialRecord]],
         expected: int = 30) -> TrialSetResult:
    return TrialSetResult(model, task, "plain",
                          tuple((seed, tuple(records)) for seed, records in per_seed.items()),
                          expected)


def test_table3_pairs_each_baseline_with_kqv_per_task_and_seed():
    kqv = _set("kqv", "single", {0: trials([OK] * 29 + [FAILED], "kqv"),
                                 1: trials([OK] * 30, "kqv", seed=1)})
    keypoint = _set("keypoint-16", "single", {0: trials([OK] * 15 + [FAILED] * 15, "kp"),
                                              1: trials([OK] * 12, "kp", seed=1)})  # 12 of 30
    fcn = _set("fcn", "multiple", {0: trials([FAILED] * 30, "fcn", task="multiple")})
    dark = TrialSetResult("kqv", "single", "dark", kqv.per_seed, 30)
    sets = [kqv, dark, keypoint, fcn]  # fcn has no kqv trials of its task: nothing to pair
    found = baseline_comparisons(sets)
    assert [(c.model, c.task, c.seed, c.unfinished) for c in found] == [
        ("keypoint-16", "single", 0, False), ("keypoint-16", "single", 1, True)]
    seed0, seed1 = (c.comparison for c in found)
    assert (seed0.model_a, seed0.model_b) == ("kqv", "kp")  # A: kqv, B: the baseline
    assert seed0.overall.counts.only_a == 14 and seed0.overall.p_value < 0.001
    assert seed1.n == 12 and seed1.overall.p_value == 1.0  # the 12 trials both have
    text = table3_markdown(sets, "Made by x.", robot="yumi")
    section = text[text.index("## Baselines against Ours (kqv, q=min)"):]
    assert "| Key Point (q=16), seed 0 | -47 % (-64 to -25), p = 0.00012 | — | — | — |" \
        in section
    assert "| Key Point (q=16), seed 1 | +0 % (-24 to +24), p = 1* | — | — | — |" in section
    assert text.index("## Baselines against") < text.index("## Failure reasons")
    against = table3_json(sets)["against_kqv"]
    assert against["reference"] == "kqv" and list(against["models"]) == ["keypoint-16"]
    entries = against["models"]["keypoint-16"]["single"]
    assert [(e["seed"], e["n"], e["unfinished"]) for e in entries] == [(0, 30, False),
                                                                       (1, 12, True)]
    assert entries[0]["mcnemar_exact_p"] == seed0.overall.p_value
    only_kqv = table3_markdown([kqv], "Made by x.", robot="yumi")
    assert "## Baselines against" not in only_kqv
    assert table3_json([kqv])["against_kqv"]["models"] == {}


def test_pairs_of_runs_of_several_seeds_pool_their_trials(tmp_path):
    """``gva compare A0 B0 A1 B1``: one pair per seed, the counts pooled over the seeds."""
    runs = []
    for seed, (a, b) in enumerate([([OK] * 30, [OK] * 25 + [FAILED] * 5),
                                   ([OK] * 30, [OK] * 24 + [FAILED] * 6)]):
        runs += [write_run(tmp_path / f"a{seed}", trials(a, seed=seed), seed=seed),
                 write_run(tmp_path / f"b{seed}", trials(b, model="b", seed=seed), seed=seed)]
    status, stdout, stderr, data = compared(tmp_path, *runs)
    assert status == 1, stderr  # 11 of 60 pairs only A: significantly worse pooled
    assert data["pairs"] == {"both": 49, "only_a": 11, "only_b": 0, "neither": 0}
    assert data["seed"] == [0, 1] and data["n"] == 60
    assert data["runs"] == [[str(runs[0]), str(runs[1])], [str(runs[2]), str(runs[3])]]
    assert "60 trials of task single, seeds 0, 1 pooled" in stdout
    single = compared(tmp_path / "one", runs[0], runs[1])[3]
    assert single["seed"] == 0 and single["pairs"]["only_a"] == 5  # one pair: as before
    status, _, stderr, _ = compared(tmp_path, *runs[:3])
    assert status == 2 and "runs = '3 folders' is not allowed: pairs: RUN_A RUN_B" in stderr
    other = write_run(tmp_path / "other", trials([OK] * 30, seed=1, task="multiple"),
                      task="multiple", seed=1)
    status, _, stderr, _ = compared(tmp_path, runs[0], runs[1], other, other)
    assert status == 2 and "task of a later pair = 'multiple' is not allowed" in stderr


def test_table3_pairs_each_variant_with_its_own_clean_trials():
    kqv = _set("kqv", "single", {0: trials([OK] * 28 + [FAILED] * 2, "kqv")})
    dark = TrialSetResult("kqv", "single", "dark",
                          ((0, tuple(trials([OK] * 20 + [FAILED] * 10, "kqv-dark"))),), 30)
    fcn_palette = TrialSetResult("fcn", "single", "palette", kqv.per_seed, 30)  # no fcn plain
    found = variant_comparisons([kqv, dark, fcn_palette])
    assert [(c.model, c.variant, c.task, c.seed) for c in found] == [
        ("kqv", "dark", "single", 0)]
    assert found[0].comparison.n == 30
    assert found[0].comparison.overall.difference == pytest.approx(-8 / 30)  # variant - clean
    assert found[0].cell().startswith("-27 %")
