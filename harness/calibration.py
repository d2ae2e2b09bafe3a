"""How well a pick's judged probability of success means what it says (issue 63).

The grasp judge gives each pick a probability of holding (its tolerance map's success rate).
Scored as a probability, not as a yes or no: how well it ranks picks (AUC), how close it is
(Brier score, and its skill over always saying the base rate), whether it expects as many misses
as happened, read both ways: the expected count inside the observed count's 95 % interval (the
sampling noise of the misses that happened; issue 63's bar), and the observed count inside the
expected count's 95 % range under the judge's own probabilities (their spread); and a
reliability table (the rate observed in each bin of the probability).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from harness.trial_summary import wilson_interval
from sim.errors import InvalidInputError

BINS = 5
"""Reliability bins of equal width over [0, 1]: about 180 picks of a Table III run each."""
Z_95 = 1.959964
"""The normal quantile of a two-sided 95 % range."""


@dataclass(frozen=True)
class ReliabilityBin:
    """The picks whose probability fell in ``[low, high)`` (the last bin closed)."""

    low: float
    high: float
    picks: int
    mean_probability: float | None  # None for an empty bin
    observed_rate: float | None

    def to_json(self) -> dict[str, Any]:
        """The bin as ``gva judge --json`` writes it."""
        return {"low": self.low, "high": self.high, "picks": self.picks,
                "mean_probability": self.mean_probability, "observed_rate": self.observed_rate}


@dataclass(frozen=True)
class Calibration:
    """The judge's probabilities scored against what the physics did, over some picks.

    Attributes:
        picks: Picks scored.
        misses: Picks the physics says failed.
        auc: The chance a pick that held got a higher probability than one that did not (ties
            count half); None without both.
        brier: Mean squared difference between probability and outcome (1 held, 0 not).
        base_brier: The Brier score of always saying the observed success rate.
        skill: ``1 - brier / base_brier``: 0 no better than the base rate, 1 perfect; None
            where every pick ended alike.
        expected_misses: The misses the probabilities expect, the sum of ``1 - p``.
        expected_low, expected_high: Its 95 % range: ``expected ± 1.96 sqrt(sum p (1 - p))``
            (the misses' count is a sum of independent Bernoulli trials).
        observed_low, observed_high: The observed misses' 95 % interval (Wilson's, of the
            miss rate, times the picks).
        reliability: The observed success rate per bin of probability.

    """

    picks: int
    misses: int
    auc: float | None
    brier: float
    base_brier: float
    skill: float | None
    expected_misses: float
    expected_low: float
    expected_high: float
    observed_low: float
    observed_high: float
    reliability: tuple[ReliabilityBin, ...]

    @classmethod
    def of(cls, pairs: Sequence[tuple[float, bool]]) -> Calibration:
        """The score of ``(probability, held)`` pairs, one per pick.

        Raises:
            InvalidInputError: No pairs, or a probability outside [0, 1].

        """
        if not pairs:
            raise InvalidInputError("picks", 0, "at least one judged pick")
        for p, _ in pairs:
            if not (isinstance(p, int | float) and 0.0 <= p <= 1.0):
                raise InvalidInputError("probability", p, "a number in [0, 1]")
        n = len(pairs)
        held = [bool(y) for _, y in pairs]
        rate = sum(held) / n
        brier = sum((p - y) ** 2 for p, y in pairs) / n
        base = rate * (1.0 - rate)
        expected = sum(1.0 - p for p, _ in pairs)
        spread = Z_95 * math.sqrt(sum(p * (1.0 - p) for p, _ in pairs))
        low, high = wilson_interval(n - sum(held), n, Z_95)
        return cls(picks=n, misses=n - sum(held), auc=_auc(pairs), brier=brier,
                   base_brier=base, skill=None if base == 0.0 else 1.0 - brier / base,
                   expected_misses=expected, expected_low=max(0.0, expected - spread),
                   expected_high=expected + spread, observed_low=low * n,
                   observed_high=high * n, reliability=_bins(pairs))

    @property
    def expected_as_observed(self) -> bool:
        """Whether the expected misses lie within the observed count's 95 % interval."""
        return self.observed_low <= self.expected_misses <= self.observed_high

    @property
    def misses_as_expected(self) -> bool:
        """Whether the observed misses lie within the probabilities' 95 % range."""
        return self.expected_low <= self.misses <= self.expected_high

    def line(self) -> str:
        """One line for the report."""
        auc = "-" if self.auc is None else f"{self.auc:.3f}"
        skill = "-" if self.skill is None else f"{100 * self.skill:.0f} %"
        return (f"AUC {auc}, Brier {self.brier:.4f} (base rate {self.base_brier:.4f}, skill "
                f"{skill}); expected misses {self.expected_misses:.1f} (95 % range "
                f"{self.expected_low:.1f}-{self.expected_high:.1f}), observed {self.misses} "
                f"(95 % interval {self.observed_low:.1f}-{self.observed_high:.1f}): observed "
                f"{_inside(self.misses_as_expected)} the expected range, expected "
                f"{_inside(self.expected_as_observed)} the observed interval")

    def to_json(self) -> dict[str, Any]:
        """The score as ``gva judge --json`` writes it."""
        return {"picks": self.picks, "misses": self.misses, "auc": self.auc,
                "brier": self.brier, "base_brier": self.base_brier, "skill": self.skill,
                "expected_misses": self.expected_misses,
                "expected_misses_95": [self.expected_low, self.expected_high],
                "misses_as_expected": self.misses_as_expected,
                "observed_misses_95": [self.observed_low, self.observed_high],
                "expected_as_observed": self.expected_as_observed,
                "reliability": [b.to_json() for b in self.reliability]}


def _inside(inside: bool) -> str:
    return "within" if inside else "outside"


def _auc(pairs: Sequence[tuple[float, bool]]) -> float | None:
    """Mann-Whitney's estimate of P(p of a held pick > p of a missed one), ties half."""
    held = sorted(p for p, y in pairs if y)
    missed = sorted(p for p, y in pairs if not y)
    if not held or not missed:
        return None
    wins = 0.0
    for p in held:
        below = sum(1 for q in missed if q < p)
        ties = sum(1 for q in missed if q == p)
        wins += below + 0.5 * ties
    return wins / (len(held) * len(missed))


def _bins(pairs: Sequence[tuple[float, bool]]) -> tuple[ReliabilityBin, ...]:
    bins = []
    for k in range(BINS):
        low, high = k / BINS, (k + 1) / BINS
        inside = [(p, y) for p, y in pairs if low <= p < high or (k == BINS - 1 and p == 1.0)]
        bins.append(ReliabilityBin(
            low, high, len(inside),
            sum(p for p, _ in inside) / len(inside) if inside else None,
            sum(y for _, y in inside) / len(inside) if inside else None))
    return tuple(bins)
