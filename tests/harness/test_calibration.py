"""The judge's probabilities scored as probabilities: AUC, Brier and skill, expected misses."""

from __future__ import annotations

import math

import pytest

from harness.calibration import Calibration
from harness.trial_summary import wilson_interval
from sim.errors import InvalidInputError


def test_a_perfect_ranking_has_auc_one_and_ties_count_half():
    assert Calibration.of([(0.9, True), (0.8, True), (0.2, False)]).auc == 1.0
    assert Calibration.of([(0.2, True), (0.9, False)]).auc == 0.0
    assert Calibration.of([(0.5, True), (0.5, False)]).auc == 0.5
    assert Calibration.of([(0.5, True), (0.7, True)]).auc is None  # no miss to rank against


def test_brier_skill_and_expected_misses_by_hand():
    pairs = [(0.9, True), (0.9, True), (0.9, False), (0.6, True)]
    score = Calibration.of(pairs)
    assert score.brier == pytest.approx((0.01 + 0.01 + 0.81 + 0.16) / 4)
    assert score.base_brier == pytest.approx(0.75 * 0.25)
    assert score.skill == pytest.approx(1 - score.brier / score.base_brier)
    assert score.expected_misses == pytest.approx(0.1 + 0.1 + 0.1 + 0.4)
    spread = 1.959964 * math.sqrt(3 * 0.09 + 0.24)
    assert score.expected_high == pytest.approx(0.7 + spread)
    assert score.misses == 1 and score.misses_as_expected
    low, high = wilson_interval(1, 4)
    assert (score.observed_low, score.observed_high) == pytest.approx((4 * low, 4 * high))
    assert score.expected_as_observed  # 0.7 expected, inside 1 observed's interval


def test_the_two_readings_of_expected_misses_can_disagree():
    """Certain probabilities leave the expected count no range; the observed count keeps its
    sampling noise (issue 63's bar reads the expected count against the observed)."""
    pairs = [(0.0, False)] * 10 + [(1.0, False)] * 2 + [(1.0, True)] * 988
    score = Calibration.of(pairs)
    assert score.expected_misses == 10 and score.misses == 12
    assert score.expected_low == score.expected_high == 10 and not score.misses_as_expected
    assert score.observed_low < 10 < score.observed_high and score.expected_as_observed
    assert "observed outside the expected range, expected within the observed interval" in (
        score.line())


def test_a_pessimistic_judge_expects_more_misses_than_happen():
    pairs = [(0.5, True)] * 100  # says a coin flip; every pick held
    score = Calibration.of(pairs)
    assert score.expected_misses == 50 and score.misses == 0 and not score.misses_as_expected
    assert not score.expected_as_observed  # 0 observed: the interval stops near 4
    assert score.skill is None  # every pick ended alike: no base rate to beat
    assert "outside" in score.line()


def test_the_reliability_table_bins_the_probabilities():
    pairs = [(0.05, False), (0.15, False), (0.95, True), (1.0, True), (0.85, False)]
    bins = Calibration.of(pairs).reliability
    assert [b.picks for b in bins] == [2, 0, 0, 0, 3]
    assert bins[1].observed_rate is None and bins[4].observed_rate == pytest.approx(2 / 3)
    assert bins[4].mean_probability == pytest.approx((0.95 + 1.0 + 0.85) / 3)


def test_bad_input_names_the_field():
    with pytest.raises(InvalidInputError, match=r"picks = 0 is not allowed"):
        Calibration.of([])
    with pytest.raises(InvalidInputError, match=r"probability = 1\.5 is not allowed"):
        Calibration.of([(1.5, True)])
