"""The summary of a run's trial records: successes, their Wilson interval, every outcome.

:class:`TrialSummary` is what ``summary.json`` holds; :class:`PickCounts` the grasp judge's
verdicts against the physics over a run's picks (:mod:`harness.judging`).
"""

from __future__ import annotations

import math
import statistics
from collections import Counter
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from typing import Any

from sim.trials.records import TrialOutcome, TrialRecord


@dataclass(frozen=True)
class PickCounts:
    """The grasp judge against the physics over some picks (:mod:`harness.judging`).

    Attributes:
        picks: Picks judged.
        misses: Picks the physics says failed.
        flagged_misses: Of those, the ones the judge predicted to fail.
        unflagged_misses: The ones it predicted to hold.
        false_alarms: Picks that held which the judge predicted to fail.

    """

    picks: int = 0
    misses: int = 0
    flagged_misses: int = 0
    unflagged_misses: int = 0
    false_alarms: int = 0

    @classmethod
    def of(cls, picks: Iterable[tuple[bool, bool]]) -> PickCounts:
        """The counts of ``(picked, predicted_success)`` pairs, one per pick."""
        counts: Counter[str] = Counter()
        for picked, predicted in picks:
            counts["picks"] += 1
            if not picked:
                counts["misses"] += 1
                counts["unflagged_misses" if predicted else "flagged_misses"] += 1
            elif not predicted:
                counts["false_alarms"] += 1
        return cls(**counts)

    @property
    def flagged_fraction(self) -> float:
        """The fraction of the misses the judge flagged (1 where there were none)."""
        return self.flagged_misses / self.misses if self.misses else 1.0

    def line(self) -> str:
        """``12 misses: 10 flagged (83 %), 2 not; 3 false alarms (of 150 picks)``."""
        misses = (f"{self.misses} misses: {self.flagged_misses} flagged "
                  f"({100 * self.flagged_fraction:.0f} %), {self.unflagged_misses} not"
                  if self.misses else "no misses")
        return f"{misses}; {self.false_alarms} false alarms (of {self.picks} picks)"


def judged_pairs(records: Iterable[TrialRecord]) -> list[tuple[bool, bool]]:
    """``(picked, predicted_success)`` of every pick whose record holds the judge's verdict.

    A pick without a grasp (the model gave none) is one the judge predicts to fail.
    """
    pairs = []
    for record in records:
        for pick in record.picks:
            picked = pick.get("outcome") == TrialOutcome.SUCCESS.value
            if "judge" in pick:
                pairs.append((picked, bool(pick["judge"]["predicted_success"])))
            elif "predicted" not in pick and pick.get("target") is not None:
                pairs.append((picked, False))
    return pairs


def wilson_interval(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval of a success rate (95 % for the default ``z``)."""
    if n <= 0:
        return (0.0, 1.0)
    p = successes / n
    denominator = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denominator
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denominator
    return (max(0.0, centre - half), min(1.0, centre + half))


@dataclass(frozen=True)
class TrialSummary:
    """Successes out of n, their 95 % Wilson interval, and the count of every outcome.

    ``judge``: the grasp judge's verdicts against the physics, over the picks whose records
    hold one (None for records made before the judge: ``gva judge`` replays those).
    """

    successes: int
    n: int
    wilson95: tuple[float, float]
    outcomes: dict[str, int]
    median_wall_time_s: float
    per_object: dict[str, dict[str, int]]
    judge: PickCounts | None = None

    @classmethod
    def of(cls, records: list[TrialRecord]) -> TrialSummary:
        """The summary of some records."""
        successes = sum(r.success for r in records)
        counts = Counter(r.outcome.value for r in records)
        per_object: dict[str, dict[str, int]] = {}
        for record in records:
            for pick in record.target_picks():
                counts_of = per_object.setdefault(pick.target, {"attempted": 0, "picked": 0})
                counts_of["attempted"] += 1
                counts_of["picked"] += pick.picked
        times = [r.wall_time_s for r in records]
        median = statistics.median(times) if times else 0.0
        judged = judged_pairs(records)
        return cls(successes, len(records), wilson_interval(successes, len(records)),
                   {o.value: counts.get(o.value, 0) for o in TrialOutcome}, median,
                   dict(sorted(per_object.items())), PickCounts.of(judged) if judged else None)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form, as written to ``summary.json``."""
        return asdict(self) | {"wilson95": list(self.wilson95)}

    def headline(self) -> str:
        """``29/30 successes (95 % Wilson interval 83.3-99.4 %)``."""
        low, high = self.wilson95
        return (f"{self.successes}/{self.n} successes "
                f"(95 % Wilson interval {100 * low:.1f}-{100 * high:.1f} %)")


