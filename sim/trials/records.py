"""Trial outcomes and records: one line of a run's ``trials.jsonl`` each, and reading them.

A record is one pick trial as it goes into ``trials.jsonl``; :func:`read_trial_records` reads a
file back, leaving out a half-written last line (a crash mid-write) and refusing any other
damage. Writing and resuming a run's file: :class:`harness.trial_log.TrialLog`.
"""

from __future__ import annotations

import enum
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from sim.errors import RunFolderError

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
    (:func:`perception.objects.catalog.clear_of_table`). ``grip`` and ``obstacles`` are what the
    planner was given: the grip the model's prediction asked for
    (:meth:`sim.world.grip.Grip.to_record`) and the obstacles' source with their size (points,
    occupied cells). The top-level pick fields describe the last pick tried; ``picks`` lists
    every pick of a multi-target trial.
    ``judge`` is the grasp judge's verdict on the pick (:mod:`perception.judge.grasp_judge`), absent
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
