"""The statistics of paired outcomes: is B worse than A on the same trials.

On the same scenes two models' outcomes are paired, and only the discordant pairs (one
succeeded, the other failed) tell them apart:

- the **exact McNemar test**: under "A and B are equally good" each discordant pair is equally
  likely to favour either, so the count of pairs only B won is Binomial(discordant, 1/2); its
  two-sided exact test gives p (McNemar 1947; the exact form, e.g. Fagerland, Lydersen & Laake
  2013, BMC Med Res Methodol 13:91);
- the **difference in success rate** B - A with its 95 % interval: Newcombe's hybrid score
  interval for paired proportions, method 10 of Newcombe (1998), "Improved confidence intervals
  for the difference between binomial proportions based on paired data", Stat Med 17:2635-2650:
  each run's Wilson interval, squared and added with a correction for the pairs' correlation.

:mod:`harness.compare` pairs two runs' trials and applies them.
"""

from __future__ import annotations

import enum
import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from scipy.stats import binomtest, norm

from harness.trial_summary import wilson_interval
from sim.errors import InvalidInputError

CONFIDENCE = 0.95
"""Level of the interval of the difference (Newcombe's, from 95 % Wilson intervals)."""
SIGNIFICANCE = 0.05
"""B is called significantly better or worse than A when McNemar's p is below this."""


class Verdict(enum.Enum):
    """What a comparison says of B against A (at :data:`SIGNIFICANCE`)."""

    B_WORSE = "b_worse"  # p < 0.05 and B's success rate lower
    B_BETTER = "b_better"  # p < 0.05 and B's success rate higher
    NO_SIGNIFICANT_DIFFERENCE = "no_significant_difference"

    @property
    def exit_status(self) -> int:
        """``gva compare``'s exit status: 1 when B is significantly worse, else 0."""
        return 1 if self is Verdict.B_WORSE else 0


@dataclass(frozen=True)
class Interval:
    """A confidence interval (of a difference of success rates: fractions in [-1, 1])."""

    low: float
    high: float

    def contains(self, value: float) -> bool:
        """Whether ``value`` lies in the interval, ends included."""
        return self.low <= value <= self.high


@dataclass(frozen=True)
class PairedCounts:
    """Pairs of outcomes (success or not) of A and B: both succeeded, only A, only B, neither."""

    both: int
    only_a: int
    only_b: int
    neither: int

    def __post_init__(self) -> None:
        for name in ("both", "only_a", "only_b", "neither"):
            value = getattr(self, name)
            if not isinstance(value, int) or value < 0:
                raise InvalidInputError(name, value, "a count: an integer >= 0")

    @classmethod
    def of(cls, a: Sequence[bool], b: Sequence[bool]) -> PairedCounts:
        """The counts of the pairs ``(a[i], b[i])`` (A's and B's success in pair ``i``)."""
        if len(a) != len(b):
            raise InvalidInputError("pairs", f"{len(a)} outcomes of A, {len(b)} of B",
                                    "as many outcomes of A as of B")
        pairs = Counter(zip(a, b, strict=True))
        return cls(pairs[True, True], pairs[True, False], pairs[False, True],
                   pairs[False, False])

    @property
    def n(self) -> int:
        """Number of pairs."""
        return self.both + self.only_a + self.only_b + self.neither

    @property
    def successes_a(self) -> int:
        """A's successes."""
        return self.both + self.only_a

    @property
    def successes_b(self) -> int:
        """B's successes."""
        return self.both + self.only_b

    @property
    def discordant(self) -> int:
        """Pairs where exactly one of A and B succeeded: all a paired test looks at."""
        return self.only_a + self.only_b

    def to_dict(self) -> dict[str, int]:
        """JSON-ready form."""
        return {"both": self.both, "only_a": self.only_a, "only_b": self.only_b,
                "neither": self.neither}


def mcnemar_exact_p(counts: PairedCounts) -> float:
    """Two-sided p of the exact McNemar test: ``only_b`` of the discordant pairs ~ Bin(., 1/2).

    With no discordant pair nothing tells A from B: p = 1.
    """
    if counts.discordant == 0:
        return 1.0
    return float(binomtest(counts.only_b, counts.discordant, 0.5,
                           alternative="two-sided").pvalue)


def newcombe_paired_interval(counts: PairedCounts, confidence: float = CONFIDENCE) -> Interval:
    """Interval of B's success rate minus A's: Newcombe's (1998) method 10 for paired data.

    With ``p_b, p_a`` the two rates and ``[l_b, u_b], [l_a, u_a]`` their Wilson intervals, the
    difference ``d = p_b - p_a`` has limits

        d - sqrt((p_b - l_b)^2 - 2 phi (p_b - l_b)(u_a - p_a) + (u_a - p_a)^2)
        d + sqrt((u_b - p_b)^2 - 2 phi (u_b - p_b)(p_a - l_a) + (p_a - l_a)^2)

    where ``phi`` is the correlation of the pairs' outcomes, ``(both * neither - only_a *
    only_b) / sqrt(product of the four margins)``, with Newcombe's correction: a positive
    numerator is reduced by n/2 (to no less than 0), and ``phi = 0`` when a margin is 0.
    """
    if not 0.0 < confidence < 1.0:
        raise InvalidInputError("confidence", confidence, "a level in (0, 1), e.g. 0.95")
    n = counts.n
    if n == 0:
        raise InvalidInputError("pairs", 0, "at least one pair of outcomes")
    z = float(norm.ppf(0.5 + confidence / 2))
    p_b, p_a = counts.successes_b / n, counts.successes_a / n
    low_b, high_b = wilson_interval(counts.successes_b, n, z)
    low_a, high_a = wilson_interval(counts.successes_a, n, z)
    phi = _corrected_phi(counts)
    difference = p_b - p_a
    below = _square_and_add(p_b - low_b, high_a - p_a, phi)
    above = _square_and_add(high_b - p_b, p_a - low_a, phi)
    return Interval(max(-1.0, difference - below), min(1.0, difference + above))


def _corrected_phi(counts: PairedCounts) -> float:
    """The pairs' phi coefficient as Newcombe's method 10 uses it (see the caller)."""
    margins = (counts.successes_b * (counts.n - counts.successes_b)
               * counts.successes_a * (counts.n - counts.successes_a))
    if margins == 0:
        return 0.0
    cross = float(counts.both * counts.neither - counts.only_a * counts.only_b)
    if cross > counts.n / 2:
        cross -= counts.n / 2
    elif cross >= 0:
        cross = 0.0
    return cross / math.sqrt(margins)


def _square_and_add(first: float, second: float, phi: float) -> float:
    """sqrt(first^2 - 2 phi first second + second^2): two errors with correlation ``phi``."""
    return math.sqrt(max(0.0, first * first - 2.0 * phi * first * second + second * second))


@dataclass(frozen=True)
class PairedTest:
    """The paired comparison of one set of pairs: counts, McNemar's p, B - A with its interval.

    ``difference`` and ``interval`` are fractions (B's success rate minus A's, in [-1, 1]).
    """

    counts: PairedCounts
    p_value: float
    difference: float
    interval: Interval

    @classmethod
    def of(cls, counts: PairedCounts) -> PairedTest:
        """The test of ``counts``."""
        return cls(counts, mcnemar_exact_p(counts),
                   (counts.successes_b - counts.successes_a) / counts.n,
                   newcombe_paired_interval(counts))

    @property
    def verdict(self) -> Verdict:
        """B significantly worse, better, or neither, at :data:`SIGNIFICANCE`."""
        if self.p_value >= SIGNIFICANCE or self.difference == 0:
            return Verdict.NO_SIGNIFICANT_DIFFERENCE
        return Verdict.B_WORSE if self.difference < 0 else Verdict.B_BETTER

    def headline(self) -> str:
        """``B - A: -40.0 % (95 % interval -58.5 to -17.6 %); exact McNemar p = 0.00049``."""
        return (f"B - A: {100 * self.difference:+.1f} % ({100 * CONFIDENCE:.0f} % interval "
                f"{100 * self.interval.low:+.1f} to {100 * self.interval.high:+.1f} %); "
                f"exact McNemar p = {format_p(self.p_value)}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {"pairs": self.counts.to_dict(), "n": self.counts.n,
                "successes_a": self.counts.successes_a, "successes_b": self.counts.successes_b,
                "mcnemar_exact_p": self.p_value, "difference_b_minus_a": self.difference,
                "difference_interval95": [self.interval.low, self.interval.high],
                "verdict": self.verdict.value}


def format_p(p: float) -> str:
    """A p-value in two significant digits: ``1``, ``0.07``, ``0.00049``, ``1.9e-09``."""
    return f"{p:.2g}"
