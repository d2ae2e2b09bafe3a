"""Trial sets of a ``gva reproduce real`` folder paired trial for trial.

Each baseline's plain trials against kqv's, and each model's trials under a variant against its
own clean ones (:mod:`harness.compare`), per task and seed; :mod:`experiments.table3.report`
tabulates them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from experiments.table3.settings import OPEN_LOOP, PLAIN, REFERENCE_MODEL
from experiments.table3.trial_sets import TrialSetResult
from harness.compare import Comparison, compare_records
from harness.paired_statistics import format_p


@dataclass(frozen=True)
class PairedSets:
    """Two trial sets of one task and seed paired trial for trial (:mod:`harness.compare`).

    A baseline against kqv (``variant`` plain; ``comparison`` has kqv as A, its difference
    baseline - kqv), or a model under a variant against its own plain trials (the plain set as
    A: variant - clean). ``unfinished``: a set lacks some trials, and only the trials both
    have are paired.
    """

    model: str
    task: str
    seed: int
    comparison: Comparison
    unfinished: bool
    variant: str = PLAIN

    def entry(self) -> dict[str, Any]:
        """The comparison as ``table3.json`` holds it."""
        return {"seed": self.seed, "unfinished": self.unfinished} | self.comparison.to_dict()

    def cell(self) -> str:
        """``-43 % (-61 to -20), p = 0.00098``: the difference, its interval and p."""
        test = self.comparison.overall
        return (f"{100 * test.difference:+.0f} % ({100 * test.interval.low:+.0f} to "
                f"{100 * test.interval.high:+.0f}), p = {format_p(test.p_value)}"
                + ("*" if self.unfinished else ""))


def _paired(reference: TrialSetResult | None, result: TrialSetResult) -> list[PairedSets]:
    """``result``'s trials against ``reference``'s, per seed, on the trials both have.

    Trial ``i`` of a seed is the same scene for every model and variant (the seed's test
    stream; a variant's looks and distractors have streams of their own).
    """
    if reference is None:
        return []
    theirs_by_seed = dict(reference.per_seed)
    found = []
    for seed, records in result.per_seed:
        theirs = {r.index: r for r in theirs_by_seed.get(seed, ())}
        ours = {r.index: r for r in records}
        common = sorted(set(theirs) & set(ours))
        if common:
            found.append(PairedSets(
                result.model, result.task, seed,
                compare_records([theirs[i] for i in common], [ours[i] for i in common]),
                len(common) < result.expected, result.variant))
    return found


def baseline_comparisons(sets: Sequence[TrialSetResult]) -> list[PairedSets]:
    """Each baseline's plain trials against kqv's, per task and seed, on the trials both have."""
    reference = {s.task: s for s in sets if s.model == REFERENCE_MODEL and s.variant == PLAIN}
    return [paired for result in sets
            if result.model != REFERENCE_MODEL and result.variant == PLAIN
            for paired in _paired(reference.get(result.task), result)]


def variant_comparisons(sets: Sequence[TrialSetResult]) -> list[PairedSets]:
    """Each model's trials under each variant against its own plain trials, per task and seed."""
    plain = {(s.model, s.task): s for s in sets if s.variant == PLAIN}
    return [paired for result in sets if result.variant not in (PLAIN, OPEN_LOOP)
            for paired in _paired(plain.get((result.model, result.task)), result)]
