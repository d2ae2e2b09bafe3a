"""Replays trial records through the grasp judge: which misses the perception explains.

Every record keeps the scene's objects and, per pick, the true and the predicted grasps, so any
run, also one made before the judge existed, can be judged again (``gva judge RUN``). A pick's
verdict is set beside how the physics ended it: a miss the judge predicted is *flagged*, a
success it predicted to fail is a *false alarm*. Agreement alone would say little: with 95 % of
picks succeeding, "always success" agrees 95 %; so the counts are reported by what they are.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from harness.calibration import Calibration
from harness.trial_summary import PickCounts
from perception.judge.grasp_judge import GraspVerdict, judge_grasp
from perception.judge.grasp_tolerance import ToleranceMap, default_tolerance_map
from perception.objects.catalog import get_object_spec
from perception.poses import Pose
from sim.errors import InvalidInputError
from sim.trials.records import TrialOutcome, TrialRecord, read_trial_records


def pose_of(data: dict[str, Any]) -> Pose:
    """A pose as a record keeps it (``position_m``, ``rotation``)."""
    return Pose(np.asarray(data["position_m"], dtype=float),
                np.asarray(data["rotation"], dtype=float))


def object_yaw_rad(objects: Sequence[dict[str, Any]], object_type: str, truth: Pose
                   ) -> float | None:
    """The placed yaw of the scene's ``object_type`` nearest the true grasp; None if none.

    Objects settle a fraction of a millimetre after they are placed; the yaw a scene placed
    them at is what the mug's allowed rim turns are measured from.
    """
    centre = get_object_spec(object_type).grasp.object_frame(truth).position[:2]
    candidates = [o for o in objects if o.get("type") == object_type and not o.get("distractor")]
    if not candidates:
        return None
    nearest = min(candidates, key=lambda o: float(np.linalg.norm(
        np.asarray(o["position_xy_m"]) - centre)))
    return float(nearest["yaw_rad"])


def judge_pick(pick: dict[str, Any], objects: Sequence[dict[str, Any]],
               tolerance: ToleranceMap | None = None) -> GraspVerdict | None:
    """The judge's verdict on one pick of a record; None where the model gave no grasp.

    Raises:
        InvalidInputError: A grasp of the pick holds a value that is not finite (or not a
            position or rotation at all), naming it (``predicted.position_m``). gva trials
            never records one (a :class:`~perception.interface.Target` refuses a non-finite
            grasp), so such a record is damaged: it is refused, as a damaged line is, rather
            than scored as an error of nan mm or left out of counts that say they are the
            whole run's.

    """
    if pick.get("predicted") is None or pick.get("truth") is None or \
            "rotation" not in pick["predicted"]:
        return None
    for key in ("truth", "predicted"):
        _check_finite(key, pick[key])
    predicted, truth = pose_of(pick["predicted"]), pose_of(pick["truth"])
    spec = get_object_spec(pick["target"])
    return judge_grasp(spec, truth, predicted, object_yaw_rad(objects, spec.name, truth),
                       tolerance)


def _check_finite(key: str, grasp: dict[str, Any]) -> None:
    """An error naming ``key.part`` unless the grasp's position and rotation are finite."""
    for part, shape in (("position_m", (3,)), ("rotation", (3, 3))):
        value = grasp.get(part)
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):  # a string, a ragged list: not numbers at all
            array = np.full(0, np.nan)
        if array.shape != shape or not np.all(np.isfinite(array)):
            raise InvalidInputError(f"{key}.{part}", value,
                                    f"{' x '.join(map(str, shape))} finite numbers, as gva "
                                    "trials records them (this record is damaged)")


@dataclass(frozen=True)
class JudgedPick:
    """One pick: how the physics ended it and what the judge predicted.

    ``verdict`` is None where the model gave no grasp (the judge predicts a miss).
    """

    trial: int
    number: int
    target: str
    outcome: TrialOutcome
    reason: str
    verdict: GraspVerdict | None

    @property
    def picked(self) -> bool:
        """Whether the physics says the pick held."""
        return self.outcome is TrialOutcome.SUCCESS

    @property
    def predicted_success(self) -> bool:
        """Whether the judge says it would."""
        return self.verdict is not None and self.verdict.predicted_success

    @property
    def probability(self) -> float:
        """The judge's probability that the pick holds (the map's calibrated chance), or 0."""
        return 0.0 if self.verdict is None else self.verdict.probability


def judged_picks(record: TrialRecord, tolerance: ToleranceMap | None = None
                 ) -> tuple[JudgedPick, ...]:
    """Every pick of a record, judged."""
    picks = record.picks or ([] if record.target is None else [{
        "target": record.target, "truth": record.truth, "predicted": record.predicted,
        "outcome": record.outcome.value, "reason": record.reason}])
    judged = []
    for number, pick in enumerate(picks):
        try:
            verdict = judge_pick(pick, record.objects, tolerance)
        except InvalidInputError as error:  # which trial and pick the field is of
            raise InvalidInputError(f"trial {record.index} pick {number} {error.field}",
                                    error.value, error.allowed) from None
        judged.append(JudgedPick(record.index, number, pick["target"],
                                 TrialOutcome(pick["outcome"]), pick.get("reason", ""), verdict))
    return tuple(judged)


def pick_counts(picks: Iterable[JudgedPick]) -> PickCounts:
    """The judge against the physics over ``picks``."""
    return PickCounts.of((pick.picked, pick.predicted_success) for pick in picks)


@dataclass(frozen=True)
class TrialSetJudgement:
    """One folder of trials (a task, a seed, a model, a world): real and predicted counts."""

    folder: str
    task: str
    seed: int
    model: str
    n: int
    successes: int
    predicted_successes: int
    picks: PickCounts
    per_object: dict[str, PickCounts] = field(default_factory=dict)


@dataclass(frozen=True)
class RunJudgement:
    """A run folder judged: each trial set, all their picks together, each pick missed.

    ``calibration`` scores the judge's probabilities over every pick
    (:mod:`harness.calibration`); ``probabilities`` lists each pick's (where, held, p).
    """

    sets: tuple[TrialSetJudgement, ...]
    picks: PickCounts
    per_object: dict[str, PickCounts]
    misses: tuple[dict[str, Any], ...]
    false_alarms: tuple[dict[str, Any], ...]
    tolerance_map: dict[str, Any]
    calibration: Calibration | None = None
    probabilities: tuple[dict[str, Any], ...] = ()
    probability_scaling: dict[str, Any] | None = None  # the map's PlattScaling, as its JSON

    def to_json(self) -> dict[str, Any]:
        """JSON-ready, as ``gva judge --json`` writes it."""
        data = asdict(self)
        data["calibration"] = None if self.calibration is None else self.calibration.to_json()
        return data


def _pick_row(folder: str, record: TrialRecord, pick: JudgedPick) -> dict[str, Any]:
    """One pick as the report lists it: where, how it ended, what the judge saw."""
    row: dict[str, Any] = {"folder": folder, "seed": record.seed, "trial": pick.trial,
                           "pick": pick.number, "target": pick.target,
                           "outcome": pick.outcome.value, "reason": pick.reason}
    if pick.verdict is not None:
        row["judge"] = pick.verdict.to_record()
    return row


def trial_folders(run: Path) -> list[Path]:
    """Every folder under ``run`` (itself included) that holds a ``trials.jsonl``."""
    if not run.is_dir():
        raise InvalidInputError("run folder", str(run), "an existing folder")
    found = sorted(path.parent for path in run.rglob("trials.jsonl"))
    if not found:
        raise InvalidInputError("run folder", str(run),
                                "a folder of gva trials or gva reproduce real (no trials.jsonl "
                                "under it)")
    return found


def judge_run(run: Path, tolerance: ToleranceMap | None = None) -> RunJudgement:
    """Judges every trial under ``run``: per trial set and over all picks."""
    tolerance = tolerance or default_tolerance_map()
    sets, every, misses, alarms, probabilities = [], [], [], [], []
    for folder in trial_folders(run):
        name = str(folder.relative_to(run)) if folder != run else "."
        path = folder / "trials.jsonl"
        records = read_trial_records(path)
        if not records:
            continue
        try:
            judged = [(record, judged_picks(record, tolerance)) for record in records]
        except InvalidInputError as error:  # and which file
            raise InvalidInputError(f"{path} {error.field}", error.value, error.allowed) from None
        picks = [pick for _, these in judged for pick in these]
        every.extend(picks)
        for record, these in judged:
            for pick in these:
                probabilities.append({"folder": name, "seed": record.seed, "trial": pick.trial,
                                      "pick": pick.number, "target": pick.target,
                                      "held": pick.picked, "probability": pick.probability})
                if not pick.picked:
                    misses.append(_pick_row(name, record, pick))
                elif not pick.predicted_success:
                    alarms.append(_pick_row(name, record, pick))
        first = records[0]
        sets.append(TrialSetJudgement(
            folder=name, task=first.task, seed=first.seed, model=first.model, n=len(records),
            successes=sum(r.success for r in records),
            predicted_successes=sum(bool(these) and all(p.predicted_success for p in these)
                                    for _, these in judged),
            picks=pick_counts(picks), per_object=_per_object(picks)))
    calibration = Calibration.of([(p.probability, p.picked) for p in every]) if every else None
    return RunJudgement(tuple(sets), pick_counts(every), _per_object(every), tuple(misses),
                        tuple(alarms), dict(tolerance.provenance), calibration,
                        tuple(probabilities),
                        None if tolerance.calibration is None else tolerance.calibration.to_json())


def _per_object(picks: Sequence[JudgedPick]) -> dict[str, PickCounts]:
    types = sorted({pick.target for pick in picks})
    return {t: pick_counts(p for p in picks if p.target == t) for t in types}


def describe_error(row: dict[str, Any]) -> str:
    """A missed or alarmed pick's errors in one line."""
    judge = row.get("judge")
    if judge is None:
        return "no grasp"
    return (f"closing {judge['closing_mm']:+.1f} mm, across {judge['across_mm']:+.1f} mm, "
            f"approach {judge['approach_mm']:+.1f} mm, yaw {judge['yaw_deg']:.0f}°, "
            f"tilt {judge['tilt_deg']:.0f}°, p = {judge['success_rate']:.2f}")

