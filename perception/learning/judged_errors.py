"""A dataset's predictions judged as the trials judge them: errors in the grasp frame, by group.

A mean position error pools a mug 2 mm off with a sponge turned 40 degrees; the trial misses
the second. Here every target of a grasp-pose dataset goes through the grasp judge
(:mod:`perception.judge.grasp_judge`), and the errors are reported per object type, per condition
value and per head: mean, 90th and 95th percentile and worst of each error, and the share of
targets the judge predicts would be picked. The tail is where picks are lost.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from perception.interface import Prediction
from perception.judge.grasp_judge import GraspVerdict, judge_grasp
from perception.judge.grasp_tolerance import ToleranceMap, default_tolerance_map
from perception.labels import split_label
from perception.learning.data import Dataset
from perception.objects.catalog import get_object_spec
from perception.poses import Pose

ERRORS = ("position_cm", "closing_mm", "across_mm", "approach_mm", "yaw_deg", "tilt_deg")
"""The errors each group reports; offsets as their size (no sign)."""


@dataclass(frozen=True)
class Spread:
    """One error over a group's targets: its mean, 90th and 95th percentile and worst."""

    mean: float
    p90: float
    p95: float
    worst: float

    @classmethod
    def of(cls, values: np.ndarray) -> Spread:
        """The spread of ``values`` (n,), n >= 1."""
        return cls(float(values.mean()), float(np.percentile(values, 90)),
                   float(np.percentile(values, 95)), float(values.max()))


@dataclass(frozen=True)
class JudgedGroup:
    """The judged targets of one group (an object type, a condition value, a head, or all).

    Attributes:
        targets: How many targets the group holds.
        predicted_success_rate: The share the judge predicts would be picked.
        expected_success_rate: The mean of the map's chances: smoother than the share, it
            ranks models that the share ties (a few held-out scenes).
        mean_probability: The mean of the calibrated probabilities (the chance a real run's
            pick holds, :attr:`GraspVerdict.probability`): the picks the group's targets are
            expected to give, per target, near misses counted as the partial picks they are.
        errors: Each of :data:`ERRORS` over the group.

    """

    targets: int
    predicted_success_rate: float
    expected_success_rate: float
    errors: dict[str, Spread]
    mean_probability: float

    @classmethod
    def of(cls, verdicts: list[GraspVerdict]) -> JudgedGroup:
        """The group made of ``verdicts`` (at least one)."""
        table: dict[str, list[float]] = {name: [] for name in ERRORS}
        for verdict in verdicts:
            error = verdict.error
            for name, value in (("position_cm", 100 * error.position_m),
                                ("closing_mm", 1000 * abs(error.closing_m)),
                                ("across_mm", 1000 * abs(error.across_m)),
                                ("approach_mm", 1000 * abs(error.approach_m)),
                                ("yaw_deg", math.degrees(error.yaw_rad)),
                                ("tilt_deg", math.degrees(error.tilt_rad))):
                table[name].append(value)
        return cls(len(verdicts), float(np.mean([v.predicted_success for v in verdicts])),
                   float(np.mean([v.success_rate for v in verdicts])),
                   {name: Spread.of(np.asarray(values)) for name, values in table.items()},
                   float(np.mean([v.probability for v in verdicts])))

    def line(self) -> str:
        """One line: the predicted success, and each error's mean / p95 / worst."""
        errors = ", ".join(f"{name} {s.mean:.1f}/{s.p95:.1f}/{s.worst:.1f}"
                           for name, s in self.errors.items())
        return (f"{self.targets} targets, judged picked {100 * self.predicted_success_rate:.1f} "
                f"%; mean/p95/worst: {errors}")


@dataclass(frozen=True)
class JudgedErrors:
    """A dataset's targets judged: over all, and per object type, condition value and head.

    Attributes:
        all: Every present target of a type the map knows.
        per_object: By the target's object type.
        per_condition: By the condition value (None for a task without a condition).
        per_head: By target index (None for one target per image).

    """

    all: JudgedGroup
    per_object: dict[str, JudgedGroup]
    per_condition: dict[str, JudgedGroup] | None
    per_head: dict[str, JudgedGroup] | None

    def to_json(self) -> dict[str, Any]:
        """JSON-ready form."""
        return asdict(self)


def judge_predictions(predictions: list[Prediction], dataset: Dataset,
                      tolerance: ToleranceMap | None = None) -> JudgedErrors | None:
    """Judges every present target whose scene record names a type the map measured.

    None where the labels are no grasp poses (positions only: the paper's simulator) or no
    target can be judged.
    """
    truth = split_label(dataset.labels.astype(np.float64))
    if truth.rotation is None:
        return None
    tolerance = tolerance or default_tolerance_map()
    judged = set(tolerance.object_types)
    present = dataset.target_present()
    types = dataset.target_types()
    conditions = dataset.condition_names()
    groups: dict[tuple[str, str], list[GraspVerdict]] = {}
    for n, (prediction, record) in enumerate(zip(predictions, dataset.scenes, strict=True)):
        for k, target in enumerate(prediction.targets):
            object_type = types[n][k]
            if not present[n, k] or object_type not in judged or target.rotation is None:
                continue
            yaw = record["objects"][record["targets"][k]].get("yaw_rad")
            verdict = judge_grasp(
                get_object_spec(object_type),
                Pose(truth.position_m[n, k], truth.rotation[n, k]),
                Pose(np.asarray(target.position_m, dtype=float),
                     np.asarray(target.rotation, dtype=float)),
                None if yaw is None else float(yaw), tolerance)
            keys = [("all", "all"), ("object", object_type), ("head", f"head {k}")]
            if conditions[n] is not None:
                keys.append(("condition", str(conditions[n])))
            for key in keys:
                groups.setdefault(key, []).append(verdict)
    if not groups:
        return None

    def by(kind: str) -> dict[str, JudgedGroup]:
        return {name: JudgedGroup.of(v) for (k, name), v in sorted(groups.items()) if k == kind}

    heads = by("head")
    return JudgedErrors(JudgedGroup.of(groups[("all", "all")]), by("object"),
                        by("condition") or None, heads if len(heads) > 1 else None)
