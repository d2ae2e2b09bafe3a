"""The statistics of paired runs: exact McNemar test, Newcombe's interval, pairing of records."""

from __future__ import annotations

import math

import pytest

from harness.compare import compare_records
from harness.paired_statistics import (
    Interval,
    PairedCounts,
    PairedTest,
    Verdict,
    mcnemar_exact_p,
    newcombe_paired_interval,
)
from harness.trial_summary import wilson_interval
from sim.errors import InvalidInputError
from sim.trials.records import TrialOutcome, TrialRecord

# Complete response before and after consolidation therapy (Cavo et al. 2012), the worked
# example of Fagerland, Lydersen & Laake, "Statistical Analysis of Contingency Tables" (CRC
# 2017), chapter 8 "The paired 2x2 table": 59 responded at both times, 6 only before, 16 only
# after, 80 at neither. Their "Newcombe square-and-add" interval for paired data is Newcombe's
# (1998) method 10; for the difference before - after they give -0.0621 (95 % CI -0.1186 to
# -0.0046), values their R package contingencytables checks in tests/testthat/test-ch8.R.
# Here "before" is B and "after" is A, so B - A is their difference.
CAVO = PairedCounts(both=59, only_a=16, only_b=6, neither=80)


def test_newcombe_interval_matches_the_published_example():
    test = PairedTest.of(CAVO)
    assert test.difference == pytest.approx(-0.0621, abs=5e-5)
    assert test.interval.low == pytest.approx(-0.1186, abs=5e-5)
    assert test.interval.high == pytest.approx(-0.0046, abs=5e-5)


def test_exact_mcnemar_p_is_the_two_sided_binomial_tail_of_the_discordant_pairs():
    # 1 pair only B, 7 only A: p = 2 P(X <= 1), X ~ Bin(8, 1/2) = 2 (1 + 8) / 2^8, by hand.
    assert mcnemar_exact_p(PairedCounts(1, 7, 1, 12)) == pytest.approx(18 / 256, rel=1e-12)
    cavo = 2 * sum(math.comb(22, k) for k in range(7)) / 2 ** 22  # 6 of 22 discordant pairs
    assert mcnemar_exact_p(CAVO) == pytest.approx(cavo, rel=1e-12)
    assert cavo == pytest.approx(0.0525, abs=1e-4)
    assert mcnemar_exact_p(PairedCounts(12, 0, 0, 18)) == 1.0  # nothing tells them apart


def test_a_run_against_itself_differs_by_nothing():
    for counts in (PairedCounts(20, 0, 0, 10), PairedCounts(30, 0, 0, 0),
                   PairedCounts(0, 0, 0, 30)):
        test = PairedTest.of(counts)
        assert (test.p_value, test.difference) == (1.0, 0.0)
        assert test.interval.low == pytest.approx(-test.interval.high)
        assert test.interval.low < 0 < test.interval.high
        assert test.verdict is Verdict.NO_SIGNIFICANT_DIFFERENCE


def test_swapping_the_runs_mirrors_the_interval():
    swapped = PairedCounts(CAVO.both, CAVO.only_b, CAVO.only_a, CAVO.neither)
    interval, mirrored = newcombe_paired_interval(CAVO), newcombe_paired_interval(swapped)
    assert mirrored.low == pytest.approx(-interval.high)
    assert mirrored.high == pytest.approx(-interval.low)
    assert mcnemar_exact_p(swapped) == mcnemar_exact_p(CAVO)


def test_without_correlation_the_interval_squares_and_adds_the_wilson_errors():
    # every run of A succeeded: A's margin of failures is 0, so phi = 0 (Newcombe's rule)
    counts = PairedCounts(both=17, only_a=13, only_b=0, neither=0)
    low_b, high_b = wilson_interval(17, 30)
    low_a, high_a = wilson_interval(30, 30)
    p_b, p_a = 17 / 30, 1.0
    interval = newcombe_paired_interval(counts)
    assert interval.low == pytest.approx(p_b - p_a - math.hypot(p_b - low_b, high_a - p_a))
    assert interval.high == pytest.approx(p_b - p_a + math.hypot(high_b - p_b, p_a - low_a))


def test_a_model_that_always_fails_is_significantly_worse_than_one_that_always_succeeds():
    test = PairedTest.of(PairedCounts(0, 30, 0, 0))
    assert test.p_value == pytest.approx(2 * 0.5 ** 30) and test.p_value < 0.001
    assert test.difference == -1.0 and test.interval.low == -1.0 and test.interval.high < -0.5
    assert test.verdict is Verdict.B_WORSE and test.verdict.exit_status == 1
    better = PairedTest.of(PairedCounts(0, 0, 30, 0))
    assert better.verdict is Verdict.B_BETTER and better.verdict.exit_status == 0


@pytest.mark.parametrize("counts", [PairedCounts(3, 2, 9, 16), PairedCounts(1, 0, 1, 0),
                                    PairedCounts(0, 5, 1, 0), PairedCounts(28, 1, 0, 1)])
def test_the_interval_holds_the_difference_and_stays_within_minus_one_and_one(counts):
    test = PairedTest.of(counts)
    assert -1.0 <= test.interval.low <= test.difference <= test.interval.high <= 1.0


def test_a_lower_rate_is_not_called_worse_without_significance():
    test = PairedTest.of(PairedCounts(25, 3, 1, 1))  # 28 vs 26 of 30
    assert test.difference < 0 and test.p_value > 0.05
    assert test.verdict is Verdict.NO_SIGNIFICANT_DIFFERENCE and test.verdict.exit_status == 0


def test_bad_counts_are_refused():
    with pytest.raises(InvalidInputError, match="only_b = -1 is not allowed"):
        PairedCounts(1, 2, -1, 0)
    with pytest.raises(InvalidInputError, match="pairs"):
        PairedCounts.of([True, False], [True])
    with pytest.raises(InvalidInputError, match=r"confidence = 1\.5"):
        newcombe_paired_interval(CAVO, confidence=1.5)
    assert Interval(-0.2, 0.1).contains(0.0) and not Interval(-0.2, -0.1).contains(0.0)


def _trial(index: int, picks: list[tuple[str, TrialOutcome]], seed: int = 0) -> TrialRecord:
    """A trial of the multiple task: its picks (target, outcome), the last deciding it."""
    return TrialRecord(index=index, seed=seed, task="multiple", model="m",
                       outcome=picks[-1][1], reason="test", target=picks[-1][0],
                       objects=[{"type": t} for t in ("sponge", "mug", "cup")],
                       picks=[{"target": t, "outcome": o.value} for t, o in picks])


OK, MISSED = TrialOutcome.SUCCESS, TrialOutcome.MISSED


def test_picks_pair_by_trial_and_target_and_a_target_never_reached_is_not_picked():
    a = [_trial(0, [("sponge", OK), ("mug", OK), ("cup", OK)]),
         _trial(1, [("sponge", MISSED)])]
    b = [_trial(0, [("sponge", OK), ("mug", MISSED)]),  # B never reached the cup
         _trial(1, [("sponge", MISSED)])]  # neither reached mug or cup: not counted
    comparison = compare_records(a, b)
    assert comparison.overall.counts == PairedCounts(0, 1, 0, 1)
    assert comparison.outcomes == {"success": {"missed": 1}, "missed": {"missed": 1}}
    per_object = {name: test.counts for name, test in comparison.per_object.items()}
    assert per_object == {"cup": PairedCounts(0, 1, 0, 0), "mug": PairedCounts(0, 1, 0, 0),
                          "sponge": PairedCounts(1, 0, 0, 1)}


def test_records_of_other_trials_are_refused():
    a = [_trial(0, [("sponge", OK)]), _trial(1, [("sponge", OK)])]
    with pytest.raises(InvalidInputError,
                       match="trial indices of B = '0, 1, 5' is not allowed: 0-1, as in A"):
        compare_records(a, [*a, _trial(5, [("sponge", OK)])])
    with pytest.raises(InvalidInputError, match="trial 1 seed of B = 3 is not allowed: 0, as"):
        compare_records(a, [a[0], _trial(1, [("sponge", OK)], seed=3)])
    other_scene = TrialRecord(**{**vars(a[1]), "objects": [{"type": "block"}]})
    with pytest.raises(InvalidInputError, match="trial 1 objects of B"):
        compare_records(a, [a[0], other_scene])
