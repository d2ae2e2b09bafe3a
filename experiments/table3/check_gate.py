"""A checkpoint that failed its held-out check: its trials left out by default, its cells marked.

A training that fails its check at every start (:func:`~perception.learning.validation.fit_checked`)
keeps its checkpoint and ``trained.json``, so a resumed run trains nothing again; by default the
run does not use it (issue 66): its trial sets and GIF are not run, and
``s<seed>/errors/check-<model>-<task>-s<seed>.json`` records the cell as failed with the check's
reason, as a job that raised is (the run's exit status 1). ``use_failed_checkpoints``
(``--use-failed-checkpoints``) runs its trials anyway with a warning, as runs did before. Trials a
failed checkpoint already has (a folder run with the option, or before it existed) are kept and
reported, marked; nothing is deleted. A checkpoint trained again has its record dropped first,
and its new check decides anew.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from collections.abc import Set as AbstractSet
from enum import Enum
from pathlib import Path
from typing import Any

from experiments.table3.layout import error_file, trained_file, trials_folder
from experiments.table3.settings import ReproduceRealSettings, Unit
from harness.run_files import read_json, write_json


class CheckUse(Enum):
    """What a run makes of a unit's checkpoint, by its held-out check (``checks[].cells``)."""

    PASSED = "passed"
    """The check passed (or nothing was held out): the trials run."""
    LEFT_OUT = "check failed"
    """It failed at every start: no trials, the cells recorded failed with the reason."""
    USED = "used a checkpoint that failed its check"
    """It failed, and its trials run anyway (the option) or were run before."""


def check_job(unit: Unit, seed: int) -> str:
    """The name a failed check is recorded under: ``check-kqv-single-s0``."""
    return f"check-{unit.name}-s{seed}"


def stored_check(folder: Path, unit: Unit) -> dict[str, Any] | None:
    """The check a unit's ``trained.json`` keeps; None: not trained, or nothing held out."""
    path = trained_file(folder, unit)
    check = read_json(path).get("check") if path.exists() else None
    return check if isinstance(check, dict) else None


def has_trials(settings: ReproduceRealSettings, folder: Path, unit: Unit) -> bool:
    """Whether some trial set of ``unit`` in one seed's ``folder`` has a trial log."""
    return any((trials_folder(folder, s) / "trials.jsonl").exists()
               for s in settings.trial_sets() if s.unit == unit)


def check_use(settings: ReproduceRealSettings, folder: Path, unit: Unit) -> CheckUse:
    """How a unit's trained checkpoint in one seed's ``folder`` is used (for the reports)."""
    check = stored_check(folder, unit)
    if check is None or check["passed"]:
        return CheckUse.PASSED
    if settings.use_failed_checkpoints or has_trials(settings, folder, unit):
        return CheckUse.USED
    return CheckUse.LEFT_OUT


def admit(settings: ReproduceRealSettings, folder: Path, unit: Unit) -> bool:
    """Whether a trained unit's trials may run: its check passed, or the run uses failed ones.

    A checkpoint kept out is recorded as a failed cell (its error file, with the check's reason);
    one let in has that file removed, as a job that succeeds has its earlier error file removed.
    """
    check = stored_check(folder, unit)
    path = error_file(folder, check_job(unit, settings.seed))
    if check is None or check["passed"] or settings.use_failed_checkpoints:
        path.unlink(missing_ok=True)
        return True
    kept = ("; those an earlier run made are kept, marked †"
            if has_trials(settings, folder, unit) else "")
    attempts = read_json(trained_file(folder, unit)).get("attempts", 1)
    write_json(path, {"job": check_job(unit, settings.seed), "model": unit.model,
                      "task": unit.task, "seed": settings.seed,
                      "error": f"held-out check failed at every start ({attempts}): "
                               f"{check['reason']}; its trials are not run "
                               f"(--use-failed-checkpoints runs them){kept}",
                      "check": check})
    return False


CHECK_FAILED = CheckUse.LEFT_OUT.value
"""A cell with no trials because its checkpoint failed its held-out check (issue 66)."""
USED_MARK = "†"
"""A cell with trials of a checkpoint that failed its held-out check."""


FailedChecks = Mapping[tuple[str, str], AbstractSet[int]]
"""(model, task): the seeds whose checkpoint failed its held-out check."""


def failed_checks(checks: Sequence[Mapping[str, Any]]) -> dict[tuple[str, str], set[int]]:
    """(model, task): the seeds whose checkpoint failed its held-out check."""
    failed: dict[tuple[str, str], set[int]] = {}
    for check in checks:
        if not check["passed"]:
            failed.setdefault((check["model"], check["task"]), set()).add(check["seed"])
    return failed


def marks_note(failed: FailedChecks) -> list[str]:
    """What ``check failed`` and ``†`` say, where some checkpoint failed its check."""
    if not failed:
        return []
    return [f"`{CHECK_FAILED}`: the checkpoint failed its held-out check at every start, so "
            f"the run did not try it (`--use-failed-checkpoints` does); `{USED_MARK}`: trials of "
            "a checkpoint that failed its check, tried anyway. Which and why: Held-out checks, "
            "below.", ""]


def checks_markdown(checks: Sequence[Mapping[str, Any]]) -> list[str]:
    """The held-out checks section: how many passed, and every failed one by name."""
    if not checks:
        return []
    failed = [c for c in checks if not c["passed"]]
    retried = sum(c["attempts"] > 1 for c in checks if c["passed"])
    lines = ["## Held-out checks", "",
             f"Each training held out part of its own demonstrations and scored the trained "
             f"model on them (`perception.learning.validation`): {len(checks) - len(failed)} of "
             f"{len(checks)} passed" + (f", {retried} of them at a later start" if retried
                                        else "") + "."]
    lines += [f"- **FAILED**: {c['model']} {c['task']} seed {c['seed']} after {c['attempts']} "
              f"attempt(s): {c['reason']}{_use(c.get('cells'))}" for c in failed]
    shown = [c for c in checks if c.get("parts")]
    if shown:  # what each check saw of each head or condition: a weak one before the trials
        lines += ["", "What each check saw of each head or condition on its held-out scenes: "
                  "mean error, share the grasp judge predicts picked, expected share picked "
                  "(the mean of its calibrated probabilities, which the check reads).", "",
                  "| model | task | seed | check | per head or condition |",
                  "|---|---|---:|---|---|"]
        lines += [f"| {c['model']} | {c['task']} | {c['seed']} | "
                  f"{'passed' if c['passed'] else '**FAILED**'} | "
                  + "; ".join(f"{name} {_part(values)}" for name, values in c["parts"].items())
                  + " |" for c in shown]
    return [*lines, ""]


def _part(values: Mapping[str, float]) -> str:
    """One head's or condition's check: ``0.71 cm, 100 %, 0.98``."""
    shown = [f"{values['error_cm']:.2f} cm"]
    if "judged" in values:
        shown.append(f"{100 * values['judged']:.0f} %")
    if "expected" in values:
        shown.append(f"{values['expected']:.2f}")
    return ", ".join(shown)


def _use(cells: str | None) -> str:
    """What became of a failed checkpoint's cells, as its line in Held-out checks ends."""
    if cells == CheckUse.LEFT_OUT.value:
        return f"; not tried (its cells read `{CHECK_FAILED}`)"
    if cells == CheckUse.USED.value:
        return f"; tried anyway (its cells marked {USED_MARK})"
    return ""
