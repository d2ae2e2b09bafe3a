"""``table3.md``: the paper's row beside ours, counts over seeds, failure reasons, checks."""

from __future__ import annotations

from dataclasses import replace

import pytest

from experiments.table3.report import checks_markdown, table3_markdown
from experiments.table3.trial_sets import TrialSetResult
from sim.trials.records import TrialOutcome, TrialRecord


def _record(index: int, outcome: TrialOutcome, reason: str, target: str = "sponge",
            error_m: float | None = 0.01) -> TrialRecord:
    return TrialRecord(index=index, seed=0, task="single", model="kqv", outcome=outcome,
                       reason=reason, target=target, position_error_m=error_m,
                       objects=[{"type": target, "distractor": False},
                                {"type": "sponge", "distractor": True}])


def test_the_markdown_has_the_papers_row_ours_and_the_failure_reasons():
    plain = [_record(i, TrialOutcome.SUCCESS, "lifted 9.9 cm and held 1.0 s") for i in range(28)]
    plain += [_record(28, TrialOutcome.MISSED, "the gripper closed on nothing", "mug", 0.031),
              _record(29, TrialOutcome.IK_UNREACHABLE, "no arm reaches it", "mug", None)]
    sets = [TrialSetResult("kqv", "single", "plain", ((0, tuple(plain)),), 30),
            TrialSetResult("fcn", "single", "plain", ((0, tuple(plain[:20])),), 30),
            TrialSetResult("kqv", "single", "block", ((0, tuple(plain[-5:])),), 5)]
    text = table3_markdown(sets, "Made by `gva reproduce real`.", robot="yumi")
    lines = text.splitlines()
    paper = lines.index("| Paper (real YuMi, 20 demonstrations) | 27/30 | 28/30 | 26/30 | 27/30 |")
    assert lines[paper + 1] == "| Ours (kqv, q=min) | 28/30 | — | — | — |"
    assert lines[paper + 2] == "| FCN | 20/20* | — | — | — |"  # 10 of 30 trials missing
    assert lines[paper + 3] == "| Ours (kqv, q=min), + block distractor | 3/5 | — | — | — |"
    assert "| Ours (kqv, q=min) | 79-98 %; 1.0 cm |" in text
    reasons = text[text.index("## Failure reasons"):]
    assert "- **Ours (kqv, q=min)**: success 28, ik_unreachable 1, missed 1; picks by object: " \
           "mug 0/2, sponge 28/28" in reasons
    assert "  - trial 28 (mug, 3.1 cm off): missed: the gripper closed on nothing" in reasons
    assert "  - trial 29 (mug): ik_unreachable: no arm reaches it" in reasons
    assert "a distractor has a target's type in 3 of 5 trials" in reasons
    assert text.rstrip().endswith("Made by `gva reproduce real`.")


def test_over_seeds_a_cell_is_the_mean_and_spread_with_each_count():
    def seed(number: int, successes: int) -> tuple[int, tuple[TrialRecord, ...]]:
        return number, tuple(
            replace(_record(i, TrialOutcome.SUCCESS if i < successes else TrialOutcome.MISSED,
                            "x"), seed=number) for i in range(30))

    result = TrialSetResult("kqv", "single", "plain",
                            (seed(0, 29), seed(1, 27), seed(2, 30)), 30)
    assert result.counts == [29, 27, 30] and result.mean == pytest.approx(86 / 3)
    entry = result.entry()
    assert (entry["successes"], entry["n"]) == (86, 90)
    assert entry["std"] == pytest.approx(1.5275, abs=1e-4)
    text = table3_markdown([result], "Made by `gva reproduce real`.", robot="yumi")
    assert "| Ours (kqv, q=min) | 28.7 ± 1.5 (29, 27, 30) | — | — | — |" in text
    assert "seed 1 trial 27 (sponge, 1.0 cm off): missed" in text


def test_a_failed_held_out_check_is_named_in_the_table():
    checks = [{"seed": 0, "model": "kqv", "task": "single", "passed": True, "reason": "",
               "attempts": 2, "mean_position_error_cm": 0.5},
              {"seed": 1, "model": "kqv", "task": "selected-type", "passed": False,
               "reason": "condition 'mug': 3.10 cm > 2.00 cm", "attempts": 2,
               "mean_position_error_cm": 1.4}]
    lines = checks_markdown(checks)
    assert lines[0] == "## Held-out checks"
    assert lines[2].endswith("1 of 2 passed, 1 of them at a later start.")
    assert lines[3] == ("- **FAILED**: kqv selected-type seed 1 after 2 attempt(s): condition "
                        "'mug': 3.10 cm > 2.00 cm")
    assert checks_markdown([]) == []
    checks[1]["parts"] = {"sponge": {"error_cm": 0.4, "judged": 1.0, "expected": 0.97},
                          "mug": {"error_cm": 3.1, "judged": 0.5, "expected": 0.55}}
    assert ("| kqv | selected-type | 1 | **FAILED** | sponge 0.40 cm, 100 %, 0.97; mug 3.10 cm, "
            "50 %, 0.55 |") in checks_markdown(checks)  # a weak head seen before the trials
    text = table3_markdown([], "Made by x.", checks=checks, robot="yumi")
    assert text.index("## Held-out checks") < text.index("## Failure reasons")
