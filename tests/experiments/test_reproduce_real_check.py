"""``gva reproduce real``: a checkpoint that failed its held-out check is not tried (issue 66).

By default its trials are left out and the cell is recorded failed with the check's reason;
``--use-failed-checkpoints`` tries it anyway, as runs did before; trials it already has stay.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest
from gva_cli import gva

from experiments.table3.check_gate import CheckUse, admit, check_job, check_use
from experiments.table3.layout import error_file, trained_file
from experiments.table3.report import successes_table
from experiments.table3.settings import ReproduceRealSettings, Unit
from experiments.table3.trial_sets import TrialSetResult
from harness.run_files import write_json
from perception.learning.validation import HeldOutCheck, fit_checked
from sim.errors import InvalidInputError
from sim.trials.records import TrialOutcome, TrialRecord

TINY = ["--tasks", "single", "--demos", "2", "--n", "2", "--steps", "3", "--workers", "1",
        "--no-robustness", "--no-progress"]
SETTINGS = ReproduceRealSettings(tasks=("single",), demos=2, n=2, steps=3, workers=1,
                                 variants=())
UNIT = Unit("kqv", "single")
REASON = "held-out mean: 9.99 cm > 2.00 cm"
ERROR = (f"held-out check failed at every start (2): {REASON}; its trials are not run "
         "(--use-failed-checkpoints runs them)")
RECORDED = f"FAILED check-kqv-single-s0: {ERROR}"


def failed(attempt: int) -> HeldOutCheck:
    return HeldOutCheck(passed=False, reason=REASON, held_out_scenes=(1,), samples=1,
                        mean_position_error_cm=9.99, per_condition_mean_position_error_cm=None,
                        per_target_mean_position_error_cm=(9.99,), limit_cm=2.0,
                        attempt=attempt, model_seed=attempt)


def failing_fit(*args, **kwargs):
    """The real training, its check made to fail at both starts (two demonstrations hold
    out nothing, so nothing would be checked)."""
    return replace(fit_checked(*args, **kwargs), checks=(failed(1), failed(2)))


@pytest.mark.slow
def test_a_failed_check_leaves_its_trials_out_unless_asked_and_keeps_what_it_has(
        tmp_path, monkeypatch):
    import experiments.table3.jobs

    out = tmp_path / "run"
    seed0 = out / "s0"
    monkeypatch.setattr(experiments.table3.jobs, "fit_checked", failing_fit)
    status, stdout, _ = gva("reproduce", "real", "--out", out, *TINY)
    monkeypatch.undo()
    assert status == 1  # a failed cell, as a failed job
    assert "2 job(s) run (0 failed)" in stdout  # collect and train; no trials, no GIF
    assert RECORDED in stdout and "| Ours (kqv, q=min) | check failed |" in stdout
    assert not (seed0 / "trials").exists() and not (seed0 / "gifs").exists()
    record = json.loads(error_file(seed0, "check-kqv-single-s0").read_text())
    assert (record["model"], record["task"], record["seed"]) == ("kqv", "single", 0)
    assert record["check"]["reason"] == REASON
    table = json.loads((out / "table3.json").read_text())
    assert "single" not in table["tasks"]  # no trials: no 0/2
    assert [(c["cells"], c["reason"]) for c in table["checks"]] == [("check failed", REASON)]
    assert table["failed"] == [{"job": "check-kqv-single-s0", "error": ERROR}]
    markdown = (out / "table3.md").read_text()
    assert "| Ours (kqv, q=min) | check failed |" in markdown
    assert (f"- **FAILED**: kqv single seed 0 after 2 attempt(s): {REASON}; not tried (its "
            "cells read `check failed`)") in markdown
    assert f"- check-kqv-single-s0: held-out check failed at every start (2): {REASON}" in markdown

    status, stdout, _ = gva("reproduce", "real", "--out", out, *TINY)  # resumed: the same
    assert status == 1 and "0 job(s) run (0 failed), 2 finished earlier" in stdout
    assert RECORDED in stdout and not (seed0 / "trials").exists()

    status, stdout, _ = gva("reproduce", "real", "--out", out, *TINY, "--use-failed-checkpoints")
    assert status == 0  # warn and go: the trials and the GIF run, nothing recorded failed
    assert "2 job(s) run (0 failed), 2 finished earlier" in stdout
    assert f"note: WARNING: kqv single seed 0 failed its held-out check: {REASON}" in stdout
    assert "FAILED" not in stdout and not error_file(seed0, "check-kqv-single-s0").exists()
    log = seed0 / "trials" / "kqv" / "single" / "trials.jsonl"
    assert len(log.read_text().splitlines()) == 2 and (seed0 / "gifs" / "kqv-single.gif").exists()
    table = json.loads((out / "table3.json").read_text())
    count = table["tasks"]["single"]["successes"]
    assert table["checks"][0]["cells"] == "used a checkpoint that failed its check"
    assert f"| Ours (kqv, q=min) | {count}/2† |" in (out / "table3.md").read_text()
    assert "--use-failed-checkpoints" in json.loads(
        (out / "history.jsonl").read_text().splitlines()[-1])["command"]

    before = log.stat().st_mtime_ns
    status, stdout, _ = gva("reproduce", "real", "--out", out, *TINY)  # the default again
    assert status == 1 and "0 job(s) run (0 failed), 2 finished earlier" in stdout
    assert RECORDED + "; those an earlier run made are kept, marked †" in stdout
    assert log.stat().st_mtime_ns == before  # kept, not run again, not deleted
    assert f"| Ours (kqv, q=min) | {count}/2† |" in stdout

    def broken(*_, **__):
        raise RuntimeError("out of ideas")

    trained_file(seed0, UNIT).unlink()  # trained again: its old check no longer stands
    monkeypatch.setattr(experiments.table3.jobs, "new_model", broken)
    status, stdout, _ = gva("reproduce", "real", "--out", out, *TINY)
    assert status == 1 and "1 job(s) run (1 failed)" in stdout
    assert "FAILED train-kqv-single-s0: RuntimeError: out of ideas" in stdout
    assert "check-kqv" not in stdout and not error_file(seed0, "check-kqv-single-s0").exists()


def test_the_option_joins_no_identity_and_is_in_the_command():
    used = replace(SETTINGS, use_failed_checkpoints=True)
    assert used.shared_identity() == SETTINGS.shared_identity()
    assert used.run_identity() == SETTINGS.run_identity()
    assert used.train_identity(UNIT) == SETTINGS.train_identity(UNIT)
    assert used.command(Path("o")) == SETTINGS.command(Path("o")) + " --use-failed-checkpoints"
    with pytest.raises(InvalidInputError, match="use_failed_checkpoints = 'yes'"):
        replace(SETTINGS, use_failed_checkpoints="yes")  # type: ignore[arg-type]


@pytest.mark.parametrize(("check", "use"), [(None, CheckUse.PASSED),
                                            ({"passed": True, "reason": ""}, CheckUse.PASSED),
                                            ({"passed": False, "reason": REASON},
                                             CheckUse.LEFT_OUT)])
def test_a_passed_or_absent_check_admits_its_trials_and_writes_nothing(tmp_path, check, use):
    write_json(trained_file(tmp_path, UNIT), {"identity": {}, "attempts": 1, "check": check})
    assert admit(SETTINGS, tmp_path, UNIT) is (use is CheckUse.PASSED)
    assert check_use(SETTINGS, tmp_path, UNIT) is use
    assert error_file(tmp_path, check_job(UNIT, 0)).exists() is (use is CheckUse.LEFT_OUT)
    if use is CheckUse.PASSED:
        assert not (tmp_path / "errors").exists()
    assert admit(replace(SETTINGS, use_failed_checkpoints=True), tmp_path, UNIT)
    assert not error_file(tmp_path, check_job(UNIT, 0)).exists()


def test_cells_of_a_failed_check_over_seeds():
    def records(successes: int) -> tuple[TrialRecord, ...]:
        return tuple(TrialRecord(i, 0, "single", "kqv", TrialOutcome.SUCCESS if i < successes
                                 else TrialOutcome.MISSED, "") for i in range(2))

    result = TrialSetResult("kqv", "single", "plain", ((0, records(2)), (1, records(1))), 2)
    checks = [{"seed": s, "model": "kqv", "task": "single", "passed": s == 0, "reason": REASON}
              for s in (0, 1, 2)]
    table = successes_table([result], checks, ("plain", "dark"))
    assert "| Ours (kqv, q=min) | 1.5 ± 0.7† (2, 1); seed 2: check failed | — | — | — |" in table
    assert "| Ours (kqv, q=min), darker light (brightness 0.5) | check failed | — |" in table
