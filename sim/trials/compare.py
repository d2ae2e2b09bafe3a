"""Two runs of trials on the same trial list, compared pair by pair: is B worse than A.

Each run's own Wilson interval (:class:`~sim.trials.records.TrialSummary`) says how well it did,
not whether two models differ: on the same scenes their outcomes are paired, and only the pairs
where one succeeded and the other failed (the discordant pairs) tell them apart. This module
holds the statistics of such pairs, used by ``gva compare`` and by ``gva reproduce real``'s
report:

- the **exact McNemar test**: under "A and B are equally good" each discordant pair is equally
  likely to favour either, so the count of pairs only B won is Binomial(discordant, 1/2); its
  two-sided exact test gives p (McNemar 1947; the exact form, e.g. Fagerland, Lydersen & Laake
  2013, BMC Med Res Methodol 13:91);
- the **difference in success rate** B - A with its 95 % interval: Newcombe's hybrid score
  interval for paired proportions, method 10 of Newcombe (1998), "Improved confidence intervals
  for the difference between binomial proportions based on paired data", Stat Med 17:2635-2650:
  each run's Wilson interval, squared and added with a correction for the pairs' correlation.

A run is a folder ``gva trials`` wrote (``run.json``, ``trials.jsonl``, ``summary.json``);
runs compare only when they ran the same trials: the same task, scene, seed and n (and, trial
by trial, the same objects). Per object type the picks are paired too, by trial and target.
"""

from __future__ import annotations

import enum
import json
import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from scipy.stats import binomtest, norm

from sim.errors import InvalidInputError, RunFolderError
from sim.trials.records import TrialOutcome, TrialRecord, differences, wilson_interval

CONFIDENCE = 0.95
"""Level of the interval of the difference (Newcombe's, from 95 % Wilson intervals)."""
SIGNIFICANCE = 0.05
"""B is called significantly better or worse than A when McNemar's p is below this."""
RUN_FILES = ("run.json", "trials.jsonl", "summary.json")
"""What a finished ``gva trials`` run folder holds."""


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
    seed: int
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

    def lines(self, label_a: str | None = None, label_b: str | None = None) -> list[str]:
        """What ``gva compare`` prints: pairs, outcome table, test, interval, per object.

        ``label_a`` and ``label_b`` name the runs (default: their models).
        """
        counts = self.overall.counts
        lines = [f"A: {counts.successes_a}/{self.n} successes  {label_a or self.model_a}",
                 f"B: {counts.successes_b}/{self.n} successes  {label_b or self.model_b}",
                 f"{self.n} trials of task {self.task}, seed {self.seed}, paired by index: "
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
    a, b = sorted(a, key=lambda r: r.index), sorted(b, key=lambda r: r.index)
    if not a or not b:
        raise InvalidInputError("trials", f"{len(a)} of A, {len(b)} of B",
                                "at least one trial in each run")
    _check_same_trials(a, b)
    overall = PairedTest.of(PairedCounts.of([r.success for r in a], [r.success for r in b]))
    return Comparison(a[0].model, b[0].model, a[0].task, a[0].seed, overall,
                      _outcome_table(a, b), _per_object(a, b))


def _check_same_trials(a: Sequence[TrialRecord], b: Sequence[TrialRecord]) -> None:
    """Raises unless ``a`` and ``b`` hold the same trials: indices, seed, task, objects."""
    first, second = [r.index for r in a], [r.index for r in b]
    if first != second:
        raise InvalidInputError("trial indices of B", _ranges(second),
                                f"{_ranges(first)}, as in A: pairs need the same trials")
    fields: dict[str, Callable[[TrialRecord], object]] = {
        "seed": lambda r: r.seed, "task": lambda r: r.task, "objects": lambda r: r.objects}
    for record_a, record_b in zip(a, b, strict=True):
        for name, value in fields.items():
            if value(record_a) != value(record_b):
                raise InvalidInputError(f"trial {record_b.index} {name} of B", value(record_b),
                                        f"{value(record_a)!r}, as in A: pairs need the same "
                                        "trials (the same scenes)")


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
    lines = (folder / "trials.jsonl").read_text().splitlines()
    for number, line in enumerate(lines, start=1):
        try:
            record = TrialRecord.from_json(line)
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
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as error:
        raise RunFolderError(f"{path} is damaged ({error})") from None
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
    run_a, run_b = read_finished_run(folder_a), read_finished_run(folder_b)
    check_same_trial_list(run_a, run_b)
    return compare_records(run_a.records, run_b.records)

