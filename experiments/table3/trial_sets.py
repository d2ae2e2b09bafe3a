"""The trial folders of a ``gva reproduce real`` run, read back per model, task and variant.

Every seed's ``trials/<model>/<task>[-variant]/trials.jsonl``, as the reports
(:mod:`experiments.table3.report`) tabulate and compare them.
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from experiments.table3.layout import seed_folder
from experiments.table3.settings import OPEN_LOOP, PLAIN
from experiments.tables import ALL_TASKS, model_order
from harness.trial_summary import TrialSummary
from sim.trials.records import TrialRecord


@dataclass(frozen=True)
class TrialSetResult:
    """The trials of one model, task and variant found in a run folder, over its seeds.

    ``per_seed`` holds each seed's trials (seed, records), in seed order; the summary pools
    them.
    """

    model: str
    task: str
    variant: str  # plain, open-loop, or a variant's name
    per_seed: tuple[tuple[int, tuple[TrialRecord, ...]], ...]
    expected: int  # the n each seed's set was started with

    @property
    def records(self) -> tuple[TrialRecord, ...]:
        """Every seed's trials, seed by seed."""
        return tuple(record for _, records in self.per_seed for record in records)

    @property
    def summary(self) -> TrialSummary:
        """Successes, interval and outcome counts of every trial present, pooled."""
        return TrialSummary.of(list(self.records))

    @property
    def counts(self) -> list[int]:
        """Each seed's successes."""
        return [sum(r.success for r in records) for _, records in self.per_seed]

    @property
    def mean(self) -> float:
        """The mean of the seeds' successes."""
        return statistics.fmean(self.counts)

    @property
    def std(self) -> float:
        """The sample standard deviation of the seeds' successes (0 for one seed)."""
        return statistics.stdev(self.counts) if len(self.counts) > 1 else 0.0

    @property
    def unfinished(self) -> bool:
        """Whether a seed has fewer trials than asked."""
        return any(len(records) < self.expected for _, records in self.per_seed)

    def entry(self) -> dict[str, Any]:
        """The set as ``table3.json`` holds it: per seed, mean and spread, then pooled."""
        summary = self.summary
        errors = first_pick_errors_cm(self.records)
        return {"per_seed": [{"seed": seed, "successes": count, "n": len(records),
                              "unfinished": len(records) < self.expected}
                             for (seed, records), count in zip(self.per_seed, self.counts,
                                                               strict=True)],
                "mean": self.mean, "std": self.std,
                "successes": summary.successes, "n": summary.n,
                "wilson95": list(summary.wilson95), "outcomes": summary.outcomes,
                "per_object": summary.per_object, "unfinished": self.unfinished,
                "median_position_error_cm": statistics.median(errors) if errors else None,
                "median_wall_time_s": summary.median_wall_time_s,
                "judge": None if summary.judge is None else asdict(summary.judge)}


def first_pick_errors_cm(records: Sequence[TrialRecord]) -> list[float]:
    """Each trial's first-pick grasp position error [cm], where the model predicted one."""
    errors = []
    for record in records:
        first = record.picks[0] if record.picks else {}
        error = first.get("position_error_m", record.position_error_m)
        if error is not None:
            errors.append(100.0 * error)
    return errors


def split_task(name: str) -> tuple[str, str]:
    """``single-dark`` -> (``single``, ``dark``); ``single`` -> (``single``, ``plain``).

    The longest task name that starts it wins (``selected-type-text`` is a task, not
    ``selected-type`` under a variant ``text``); a name of no task comes back whole, plain.
    """
    for task in sorted(ALL_TASKS, key=len, reverse=True):
        if name == task:
            return task, PLAIN
        if name.startswith(f"{task}-"):
            return task, name[len(task) + 1:]
    return name, PLAIN


def variant_order(variant: str) -> tuple[int, str]:
    """Rows in order: plain, open-loop, then the variants by name."""
    return (0 if variant == PLAIN else 1 if variant == OPEN_LOOP else 2, variant)


def read_trial_sets(out: Path, seeds: Sequence[int], n: int) -> list[TrialSetResult]:
    """Every trial folder of each seed's ``trials/`` (``<model>/<task>[-variant]``), in table order.

    ``n`` is the trials each set is meant to have (the folder's ``run.json`` pins it). A row
    holds the seeds that have its trial folder.
    """
    rows: dict[tuple[str, str, str], list[tuple[int, tuple[TrialRecord, ...]]]] = {}
    for seed in seeds:
        for log in sorted((seed_folder(out, seed) / "trials").glob("*/*/trials.jsonl")):
            task, variant = split_task(log.parent.name)
            if task not in ALL_TASKS:
                continue
            records = sorted((TrialRecord.from_json(line) for line in
                              log.read_text().splitlines() if line.strip()),
                             key=lambda r: r.index)
            rows.setdefault((log.parent.parent.name, task, variant), []).append(
                (seed, tuple(r for r in records if r.index < n)))
    found = [TrialSetResult(model, task, variant, tuple(per_seed), n)
             for (model, task, variant), per_seed in rows.items()]
    found.sort(key=lambda s: (model_order(s.model), variant_order(s.variant),
                              ALL_TASKS.index(s.task)))
    return found


