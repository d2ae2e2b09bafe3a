"""Two runs of trials on the same trial list, compared pair by pair: is B worse than A.

Each run's own Wilson interval (:class:`~sim.trials.records.TrialSummary`) says how well it did,
not whether two models differ: on the same scenes their outcomes are paired. This module pairs
them (used by ``gva compare`` and by ``gva reproduce real``'s report); the statistics are
:mod:`harness.paired_statistics`'.

A run is a folder ``gva trials`` wrote (``run.json``, ``trials.jsonl``, ``summary.json``);
runs compare only when they ran the same trials: the same task, scene, seed and n (and, trial
by trial, the same objects). Per object type the picks are paired too, by trial and target.
"""
from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from harness.paired_statistics import (
    SIGNIFICANCE,
    PairedCounts,
    PairedTest,
    Verdict,
)
from harness.run_folder import differences, read_json_file
from sim.errors import InvalidInputError, RunFolderError
from sim.trials.records import TrialOutcome, TrialRecord, record_lines, record_of_line

RUN_FILES = ("run.json", "trials.jsonl", "summary.json")
"""What a finished ``gva trials`` run folder holds."""


@dataclass(frozen=True)
class Comparison:
    """Two runs' trials paired by index: overall, by outcome, per object type.

    ``outcomes`` counts the pairs by A's outcome (rows) and B's (columns), by outcome name, for
    the outcomes that occurred; ``per_object`` pairs the picks of each target type by trial
    and target (a target one run never got to counts as not picked by it).
    """

    model_a: str
    model_b: str
    task: str
    seed: int | tuple[int, ...]  # several: runs of several seeds, their pairs pooled
    overall: PairedTest
    outcomes: dict[str, dict[str, int]]
    per_object: dict[str, PairedTest] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of paired trials."""
        return self.overall.counts.n

    @property
    def exit_status(self) -> int:
        """1 when B is significantly worse than A, else 0 (see :class:`Verdict`)."""
        return self.overall.verdict.exit_status

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {"model_a": self.model_a, "model_b": self.model_b, "task": self.task,
                "seed": self.seed, "n": self.n, **self.overall.to_dict(),
                "significance": SIGNIFICANCE,
                "outcomes": self.outcomes,
                "per_object": {name: test.to_dict() for name, test in self.per_object.items()}}

    def _seeds(self) -> str:
        if isinstance(self.seed, int):
            return f"seed {self.seed}"
        return f"seeds {', '.join(map(str, self.seed))} pooled"

    def lines(self, label_a: str | None = None, label_b: str | None = None) -> list[str]:
        """What ``gva compare`` prints: pairs, outcome table, test, interval, per object.

        ``label_a`` and ``label_b`` name the runs (default: their models).
        """
        counts = self.overall.counts
        lines = [f"A: {counts.successes_a}/{self.n} successes  {label_a or self.model_a}",
                 f"B: {counts.successes_b}/{self.n} successes  {label_b or self.model_b}",
                 f"{self.n} trials of task {self.task}, {self._seeds()}, paired by index: "
                 f"both succeeded {counts.both}, only A {counts.only_a}, only B "
                 f"{counts.only_b}, neither {counts.neither}",
                 "outcomes (rows: A, columns: B):"]
        columns = list(next(iter(self.outcomes.values()), {}))
        first = max(len(row) for row in self.outcomes)
        lines.append("  " + " " * first + "".join(f"  {name}" for name in columns))
        lines += ["  " + f"{row:<{first}}" + "".join(f"  {cells[name]:>{len(name)}}"
                                                     for name in columns)
                  for row, cells in self.outcomes.items()]
        lines.append(self.overall.headline())
        if self.per_object:
            lines.append("per object (picks paired by trial and target):")
            lines += [f"  {name}: {test.counts.successes_a}/{test.counts.n} vs "
                      f"{test.counts.successes_b}/{test.counts.n}; {test.headline()}"
                      for name, test in self.per_object.items()]
        verdict = self.overall.verdict
        lines.append({
            Verdict.B_WORSE: f"B is significantly worse than A (p < {SIGNIFICANCE:g})",
            Verdict.B_BETTER: f"B is significantly better than A (p < {SIGNIFICANCE:g})",
            Verdict.NO_SIGNIFICANT_DIFFERENCE: "no significant difference between A and B "
                                               f"(p >= {SIGNIFICANCE:g} or equal rates)",
        }[verdict])
        return lines


def compare_records(a: Sequence[TrialRecord], b: Sequence[TrialRecord]) -> Comparison:
    """A's and B's trials compared pair by pair; both must hold the same trials.

    Raises:
        InvalidInputError: No trials, trials of other indices, seeds or tasks, or a trial
            whose objects differ (not the same scene): one line naming the trial and field.

    """
    return pooled_records([(a, b)])


def pooled_records(pairs: Sequence[tuple[Sequence[TrialRecord], Sequence[TrialRecord]]]
                   ) -> Comparison:
    """Several (A, B) runs' trials, each pair compared as :func:`compare_records` does, pooled.

    Runs of one task at several seeds (a seed's A and B on the same scenes): the counts of
    every seed's pairs add up, the McNemar test and interval are over them all (the pairs are
    independent trials), and the comparison's ``seed`` lists the seeds.

    Raises:
        InvalidInputError: As :func:`compare_records`, for any pair; or pairs of other tasks.

    """
    all_a: list[TrialRecord] = []
    all_b: list[TrialRecord] = []
    for a, b in pairs:
        a, b = sorted(a, key=lambda r: r.index), sorted(b, key=lambda r: r.index)
        if not a or not b:
            raise InvalidInputError("trials", f"{len(a)} of A, {len(b)} of B",
                                    "at least one trial in each run")
        _check_same_trials(a, b)
        if all_a and a[0].task != all_a[0].task:
            raise InvalidInputError("task of a later pair", a[0].task,
                                    f"{all_a[0].task!r}, as in the first: pooled pairs are "
                                    "runs of one task")
        all_a += a
        all_b += b
    seeds = tuple(dict.fromkeys(r.seed for r in all_a))
    overall = PairedTest.of(PairedCounts.of([r.success for r in all_a],
                                            [r.success for r in all_b]))
    return Comparison(all_a[0].model, all_b[0].model, all_a[0].task,
                      seeds[0] if len(pairs) == 1 else seeds, overall,
                      _outcome_table(all_a, all_b), _per_object(all_a, all_b))


def _check_same_trials(a: Sequence[TrialRecord], b: Sequence[TrialRecord]) -> None:
    """Raises unless ``a`` and ``b`` hold the same trials: indices, seed, task, objects.

    B may run A's task under a variant (``single+dark``, :mod:`sim.tasks.variants`): the same
    scenes, looked at otherwise, and where the variant adds distractors, B's objects are A's
    followed by them. So a model's trials under a variant pair with its clean ones.
    """
    first, second = [r.index for r in a], [r.index for r in b]
    if first != second:
        raise InvalidInputError("trial indices of B", _ranges(second),
                                f"{_ranges(first)}, as in A: pairs need the same trials")
    fields: dict[str, Callable[[TrialRecord, TrialRecord], bool]] = {
        "seed": lambda ra, rb: ra.seed == rb.seed,
        "task": lambda ra, rb: rb.task == ra.task or rb.task.startswith(f"{ra.task}+"),
        "objects": lambda ra, rb: rb.objects[:len(ra.objects)] == ra.objects and all(
            o.get("distractor") for o in rb.objects[len(ra.objects):])}
    for record_a, record_b in zip(a, b, strict=True):
        for name, same in fields.items():
            if not same(record_a, record_b):
                raise InvalidInputError(
                    f"trial {record_b.index} {name} of B", getattr(record_b, name),
                    f"{getattr(record_a, name)!r}, as in A (or A's under a variant, with its "
                    "distractors after A's objects): pairs need the same trials (the same "
                    "scenes)")


def _ranges(indices: Sequence[int]) -> str:
    """``0-11`` for consecutive indices, else them all (cut to the first 10)."""
    if indices and list(indices) == list(range(indices[0], indices[-1] + 1)):
        return f"{indices[0]}-{indices[-1]}"
    shown = ", ".join(str(i) for i in indices[:10])
    return shown + (f", ... ({len(indices)} trials)" if len(indices) > 10 else "")


def _outcome_table(a: Sequence[TrialRecord], b: Sequence[TrialRecord]) -> dict[str, dict[str, int]]:
    """Pairs by A's outcome and B's, for the outcomes that occurred (in TrialOutcome order)."""
    pairs = Counter((ra.outcome, rb.outcome) for ra, rb in zip(a, b, strict=True))
    rows = [o for o in TrialOutcome if any(r.outcome is o for r in a)]
    columns = [o for o in TrialOutcome if any(r.outcome is o for r in b)]
    return {row.value: {column.value: pairs[row, column] for column in columns} for row in rows}


def _per_object(a: Sequence[TrialRecord], b: Sequence[TrialRecord]) -> dict[str, PairedTest]:
    """Per target type: A's and B's picks paired by trial, target and occurrence in the trial.

    A target one run tried and the other never reached (it stopped at an earlier failed pick)
    counts as not picked by the other; a target neither tried is not counted.
    """
    picked: dict[str, tuple[list[bool], list[bool]]] = {}
    for record_a, record_b in zip(a, b, strict=True):
        picks_a, picks_b = record_a.target_picks(), record_b.target_picks()
        for target in dict.fromkeys(p.target for p in (*picks_a, *picks_b)):
            of_a = [p.picked for p in picks_a if p.target == target]
            of_b = [p.picked for p in picks_b if p.target == target]
            count = max(len(of_a), len(of_b))
            both = picked.setdefault(target, ([], []))
            both[0].extend(of_a + [False] * (count - len(of_a)))
            both[1].extend(of_b + [False] * (count - len(of_b)))
    return {target: PairedTest.of(PairedCounts.of(*pairs))
            for target, pairs in sorted(picked.items())}


@dataclass(frozen=True)
class FinishedRun:
    """A finished ``gva trials`` run read back: its identity (``run.json``), n and trials."""

    folder: Path
    identity: dict[str, Any]
    n: int
    records: tuple[TrialRecord, ...]  # trials 0 .. n-1, in index order


def read_finished_run(folder: str | Path) -> FinishedRun:
    """The run ``gva trials`` finished in ``folder``; reads only, never repairs or resumes.

    Raises:
        RunFolderError: ``folder`` is not a finished run of trials: a file is missing or
            damaged, or some of its n trials are missing (an unfinished run); one line.

    """
    folder = Path(folder)
    if not folder.is_dir():
        raise RunFolderError(f"{folder} is not a folder; compare two run folders gva trials "
                             "wrote")
    missing = [name for name in RUN_FILES if not (folder / name).is_file()]
    if missing:
        hint = ("; a gva reproduce real folder holds its runs in s<seed>/trials/<model>/<task>"
                if (folder / "table3.json").exists() or (folder / "s0").is_dir() else "")
        raise RunFolderError(f"{folder} is not a finished run of gva trials: it has no "
                             f"{' or '.join(missing)}{hint}")
    identity = _read_json(folder / "run.json")
    n = _read_json(folder / "summary.json").get("settings", {}).get("n")
    if not isinstance(n, int) or n < 1:
        raise RunFolderError(f"{folder / 'summary.json'} names no number of trials "
                             f"(settings.n = {n!r}); it is not a summary gva trials wrote")
    records: dict[int, TrialRecord] = {}
    lines = record_lines(folder / "trials.jsonl")
    for number, line in enumerate(lines, start=1):
        try:
            record = record_of_line(line)
        except (json.JSONDecodeError, TypeError, ValueError, KeyError) as error:
            raise RunFolderError(f"{folder / 'trials.jsonl'} line {number} is damaged "
                                 f"({error}); run the same gva trials command again to "
                                 "repair and finish it") from None
        records[record.index] = record
    have = [i for i in range(n) if i in records]
    if len(have) < n:
        raise RunFolderError(f"{folder} is an unfinished run: {len(have)} of its {n} trials "
                             "are done; run the same gva trials command again to finish it")
    return FinishedRun(folder, identity, n, tuple(records[i] for i in range(n)))


def _read_json(path: Path) -> dict[str, Any]:
    """The JSON object in ``path``; a damaged or non-object file raises RunFolderError."""
    data = read_json_file(path)
    if not isinstance(data, dict):
        raise RunFolderError(f"{path} holds {type(data).__name__}, not the object gva trials "
                             "writes")
    return data


def check_same_trial_list(a: FinishedRun, b: FinishedRun) -> None:
    """Raises unless ``a`` and ``b`` ran the same trial list: task, scene, seed and n.

    Raises:
        InvalidInputError: One line naming the first field that differs and both values.

    """
    def refuse(name: str, value_a: object, value_b: object) -> InvalidInputError:
        return InvalidInputError(f"{name} of B ({b.folder})", value_b,
                                 f"{value_a!r}, as in A ({a.folder}): pairs need runs of the "
                                 "same trials (the same task, scene, seed and n)")

    task_a, task_b = a.identity.get("task"), b.identity.get("task")
    if isinstance(task_a, dict) and isinstance(task_b, dict):
        changed = differences(task_a, task_b)
        if changed:
            key = "name" if "name" in changed else next(iter(changed))
            raise refuse(f"task.{key}", *changed[key])
    checks: list[tuple[str, object, object]] = [
        ("task", task_a, task_b), ("scene", a.identity.get("scene"), b.identity.get("scene")),
        ("seed", a.identity.get("seed"), b.identity.get("seed")), ("n", a.n, b.n)]
    for name, value_a, value_b in checks:
        if value_a != value_b:
            raise refuse(name, value_a, value_b)


def compare_runs(folder_a: str | Path, folder_b: str | Path) -> Comparison:
    """Runs A and B (folders ``gva trials`` finished) compared on their common trial list.

    Raises:
        RunFolderError: A folder is not a finished run of trials.
        InvalidInputError: The runs ran different trials (task, scene, seed, n or a trial's
            objects).

    """
    return compare_pooled([(folder_a, folder_b)])


def compare_pooled(folders: Sequence[tuple[str | Path, str | Path]]) -> Comparison:
    """Pairs of runs (A, B), e.g. one per seed, compared and pooled (:func:`pooled_records`).

    Raises:
        RunFolderError: A folder is not a finished run of trials.
        InvalidInputError: A pair ran different trials, or the pairs other tasks.

    """
    pairs = []
    for folder_a, folder_b in folders:
        run_a, run_b = read_finished_run(folder_a), read_finished_run(folder_b)
        check_same_trial_list(run_a, run_b)
        pairs.append((run_a.records, run_b.records))
    return pooled_records(pairs)

