"""Trial outcomes and records, kept in an append-only JSON-lines file that survives crashes.

Each finished trial is one line of ``trials.jsonl``, flushed and fsynced before the next trial
starts; ``run.json`` beside it holds the run's settings. Opening the same folder again resumes:
finished trials are kept and skipped, a half-written last line (a crash mid-write) is dropped,
and a folder that holds a different run is refused rather than mixed.
"""

from __future__ import annotations

import enum
import json
import math
import os
import statistics
from collections import Counter
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from sim.errors import RunFolderError
from sim.trials.run_folder import claim_run_folder

RECORD_FORMAT_VERSION = 1


class TrialOutcome(enum.Enum):
    """How a pick trial ended."""

    SUCCESS = "success"  # lifted >= 5 cm and held for 1 s
    PERCEPTION_FAILED = "perception_failed"  # the model raised or gave no usable target
    IK_UNREACHABLE = "ik_unreachable"  # no arm reaches the predicted grasp
    PLAN_COLLISION = "plan_collision"  # every path to the grasp collides
    COLLIDED = "collided"  # the robot touched the table or another object before the grasp
    MISSED = "missed"  # the gripper closed on nothing, or the object did not rise
    GRASP_SLIPPED = "grasp_slipped"  # the object was lifted but not held for the hold time
    ERROR = "error"  # an unexpected exception; the record keeps its message


@dataclass(frozen=True)
class TargetPick:
    """One pick of a trial: the type of its target, and whether it was picked."""

    target: str
    picked: bool


@dataclass(frozen=True)
class TrialRecord:
    """Everything a trial did, as it goes into ``trials.jsonl``.

    Positions in [m], angles in [rad], times in [s]. ``predicted`` and ``truth`` hold the TCP
    grasp poses as ``{"position_m": [...], "rotation": [[...], ...]}``; ``raised_m`` is how
    far the predicted grasp was lifted to keep the fingertips off the table
    (:func:`perception.catalog.clear_of_table`). ``grip`` and ``obstacles`` are what the planner was
    given: the grip the model's prediction asked for (:meth:`sim.world.grip.Grip.to_record`) and
    the obstacles' source with their size (points, occupied cells). The top-level pick fields
    describe the last pick tried; ``picks`` lists every pick of a multi-target trial.
    ``judge`` is the grasp judge's verdict on the pick (:mod:`perception.grasp_judge`), absent
    in records made before it. ``asked`` is what the model was given for a condition, where
    it is no one-hot name (the scene record's ``query``): ``{"kind": "text", "value": <the
    sentence>}``, or ``{"kind": "image", "value": "picture <sha256[:12]>"}``. ``look`` is what
    the scene looked like where its task varies it (the scene record's ``look``,
    :class:`sim.world.looks.SceneLook`); absent, and not written, for today's world.
    """

    index: int
    seed: int
    task: str
    model: str
    outcome: TrialOutcome
    reason: str
    objects: list[dict[str, Any]] = field(default_factory=list)
    target: str | None = None
    predicted: dict[str, Any] | None = None
    truth: dict[str, Any] | None = None
    position_error_m: float | None = None
    rotation_error_rad: float | None = None
    raised_m: float | None = None
    grip: dict[str, Any] | None = None
    obstacles: dict[str, Any] | None = None
    plan_status: str | None = None
    arm: str | None = None
    lift_m: float | None = None
    picks: list[dict[str, Any]] = field(default_factory=list)
    sim_time_s: float = 0.0
    wall_time_s: float = 0.0
    asked: dict[str, Any] | None = None
    judge: dict[str, Any] | None = None
    look: dict[str, Any] | None = None

    @property
    def success(self) -> bool:
        """Whether the pick succeeded."""
        return self.outcome is TrialOutcome.SUCCESS

    def target_picks(self) -> tuple[TargetPick, ...]:
        """Each pick of the trial by its target, in the order tried; none without a target.

        A record without ``picks`` (written before they were kept) counts its one pick.
        """
        picks = self.picks or [{"target": self.target, "outcome": self.outcome.value}]
        return tuple(TargetPick(pick["target"], pick["outcome"] == TrialOutcome.SUCCESS.value)
                     for pick in picks if pick.get("target") is not None)

    def to_json(self) -> str:
        """One JSON line (no newline)."""
        data = asdict(self)
        data["outcome"] = self.outcome.value
        if self.look is None:  # today's world: records as they always were
            del data["look"]
        return json.dumps(data, sort_keys=True)

    @classmethod
    def from_json(cls, line: str) -> TrialRecord:
        """Parses a line written by :meth:`to_json`.

        Raises:
            ValueError: (or JSONDecodeError, TypeError, KeyError) the line is no record
                :meth:`to_json` writes: its fields' types are checked as well as its keys
                (:func:`check_record_fields`), so a damaged field is refused here, naming it,
                rather than failing in what reads the record later.

        """
        data = json.loads(line)
        if not isinstance(data, dict):
            raise ValueError(f"a {type(data).__name__}, not a record (a JSON object)")
        check_record_fields(data)
        data["outcome"] = TrialOutcome(data["outcome"])
        return cls(**data)


@dataclass(frozen=True)
class PickCounts:
    """The grasp judge against the physics over some picks (:mod:`sim.trials.judging`).

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


def record_lines(path: Path) -> list[bytes]:
    """The lines of a ``trials.jsonl`` as bytes: each decoded by :func:`record_of_line`.

    Not decoded whole: a file that is not UTF-8 (or a crash mid-character in its last line)
    is then refused, or repaired, a line at a time as any other damage is.
    """
    return Path(path).read_bytes().splitlines()


def _count(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _grasp(value: Any) -> bool:
    """A grasp pose as a record keeps it: position_m (3 numbers), rotation (3 x 3 numbers)."""
    if not isinstance(value, dict):
        return False
    position, rotation = value.get("position_m"), value.get("rotation")
    numbers = (int, float)
    return (isinstance(position, list) and len(position) == 3
            and all(isinstance(v, numbers) and not isinstance(v, bool) for v in position)
            and isinstance(rotation, list) and len(rotation) == 3
            and all(isinstance(row, list) and len(row) == 3 and all(
                isinstance(v, numbers) and not isinstance(v, bool) for v in row)
                for row in rotation))


def check_record_fields(data: dict[str, Any]) -> None:
    """Raises ValueError naming the first field of a record that is not of its kind.

    The fields what reads a run relies on: index, seed, outcome, target, objects, the grasps,
    and each pick's. (Finite values are the judge's to check: it names the trial and pick.)
    """
    outcomes = {o.value for o in TrialOutcome}

    def bad(name: str) -> ValueError:
        return ValueError(f"{name} = {data_at(name)!r:.80} is not what gva trials writes")

    def data_at(name: str) -> Any:
        value: Any = data
        for step in name.replace("]", "").replace("[", ".").split("."):
            value = value[int(step)] if isinstance(value, list) else value.get(step)
        return value

    for name in ("index", "seed"):
        if not _count(data.get(name)):
            raise bad(name)
    if data.get("outcome") not in outcomes:
        raise bad("outcome")
    if not (data.get("target") is None or isinstance(data.get("target"), str)):
        raise bad("target")
    objects = data.get("objects", [])
    if not (isinstance(objects, list) and all(isinstance(o, dict) and isinstance(
            o.get("type"), str) for o in objects)):
        raise bad("objects")
    for name in ("predicted", "truth"):
        if data.get(name) is not None and not _grasp(data[name]):
            raise bad(name)
    picks = data.get("picks", [])
    if not isinstance(picks, list):
        raise bad("picks")
    for k, pick in enumerate(picks):
        if not isinstance(pick, dict):
            raise bad(f"picks[{k}]")
        if pick.get("outcome") not in outcomes:
            raise bad(f"picks[{k}].outcome")
        if not (pick.get("target") is None or isinstance(pick.get("target"), str)):
            raise bad(f"picks[{k}].target")
        for name in ("predicted", "truth"):
            if pick.get(name) is not None and not _grasp(pick[name]):
                raise bad(f"picks[{k}].{name}")


def record_of_line(line: bytes) -> TrialRecord:
    """One line of a ``trials.jsonl`` as its record.

    Raises:
        ValueError: (or JSONDecodeError, TypeError, KeyError) the line is not one
            :meth:`TrialRecord.to_json` wrote; bytes that are not UTF-8 name the first.

    """
    try:
        text = line.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"not UTF-8 text (byte {error.start} is "
                         f"{line[error.start]:#04x}), not a line gva trials wrote") from None
    return TrialRecord.from_json(text)


def read_trial_records(path: Path) -> list[TrialRecord]:
    """The records of a ``trials.jsonl``, read only: a half-written last line is left out.

    A damaged line before the last is no crash's doing: it is refused, naming the line.
    """
    lines = record_lines(path)
    records = []
    for number, line in enumerate(lines, start=1):
        try:
            records.append(record_of_line(line))
        except (json.JSONDecodeError, TypeError, ValueError, KeyError) as error:
            if number == len(lines):  # a crash mid-write; a resumed run drops it too
                break
            raise RunFolderError(f"{path} line {number} is damaged: {error}") from None
    return records


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


class TrialLog:
    """The ``trials.jsonl`` + ``run.json`` pair of a run folder; see the module docstring.

    Args:
        folder: The run folder (created if missing).
        settings: What identifies the run (task, model, seed, ...). Resuming a folder whose
            ``run.json`` holds other settings raises :class:`RunFolderError`.
        provenance: This session's provenance, appended to ``run.json``'s list.

    """

    def __init__(self, folder: str | Path, settings: Mapping[str, Any],
                 provenance: Mapping[str, Any] | None = None) -> None:
        self.folder = Path(folder)
        self.path = self.folder / "trials.jsonl"
        self.settings = claim_run_folder(self.folder, {"format_version": RECORD_FORMAT_VERSION,
                                                       **settings}, provenance=provenance)
        self.records: dict[int, TrialRecord] = dict(self._read())

    def _read(self) -> Iterator[tuple[int, TrialRecord]]:
        if not self.path.exists():
            return
        lines = record_lines(self.path)
        kept: list[bytes] = []
        for number, line in enumerate(lines, start=1):
            try:
                record = record_of_line(line)
            except (json.JSONDecodeError, TypeError, ValueError, KeyError) as error:
                if number == len(lines):  # a crash mid-write: drop the partial last line
                    self.path.write_bytes(b"".join(k + b"\n" for k in kept))
                    return
                raise RunFolderError(f"{self.path} line {number} is damaged: {error}") from None
            kept.append(line)
            yield record.index, record

    def done(self, index: int) -> bool:
        """Whether trial ``index`` already finished."""
        return index in self.records

    def append(self, record: TrialRecord) -> None:
        """Appends one finished trial and forces it to disk before returning."""
        with self.path.open("a", encoding="utf-8") as handle:
            handle.write(record.to_json() + "\n")
            handle.flush()
            os.fsync(handle.fileno())
        self.records[record.index] = record

    def summary(self, n: int) -> TrialSummary:
        """The summary of trials ``0 .. n-1``."""
        return TrialSummary.of([self.records[i] for i in range(n) if i in self.records])
