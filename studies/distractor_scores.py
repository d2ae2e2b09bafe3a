"""How ``check_distractor_offline.py`` scores a checkpoint and prints its table (issue 49).

A checkpoint's judged picks, mean error and grasps nearer the block on one test set
(:func:`score_set`), every seed's sets pooled (:func:`pooled`), and the printed table.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import astuple, dataclass
from pathlib import Path

import numpy as np

from perception.interface import Prediction
from perception.learning.data import Dataset
from perception.learning.dataset_file import load_dataset
from perception.learning.evaluate import evaluate, predict_dataset
from perception.learning.learnable import LearnableModel
from perception.objects.catalog import DISTRACTOR_TYPES
from sim.errors import SimError

SET_NAMES = ("block", "clean")
"""The test sets a :class:`Score` holds, in its fields' order."""


@dataclass(frozen=True)
class ObjectScore:
    """One object type's judged picks: how many, and how many the judge predicts picked."""

    picks: int
    predicted_picked: int


@dataclass(frozen=True)
class SetScore:
    """A model on one test set: judged picks, position error, grasps nearer the block."""

    test_set: str  # block | clean
    dataset: str
    scenes: int
    redrawn: int  # test scenes the oracle failed, replaced by later ones of the stream
    picks: int  # targets judged: in an image, of a known type (gva evaluate's count)
    predicted_picked: int
    expected_success_rate: float
    mean_position_error_cm: float
    scored_targets: int  # present targets behind the mean error
    per_object: dict[str, ObjectScore]
    nearer_block: int | None  # predicted grasps nearer a block than the target; None: no block


@dataclass(frozen=True)
class Score:
    """One checkpoint (a candidate's or a run's) on one seed's two test sets."""

    source: str  # the candidate's name or the run folder
    task: str
    seed: int | None  # None: every seed's sets pooled
    checkpoint: str
    block: SetScore
    clean: SetScore


def nearer_block(predictions: Sequence[Prediction], dataset: Dataset) -> int | None:
    """How many present targets' predicted grasps lie nearer a block than the target (x, y)."""
    nearer: list[bool] = []
    for prediction, record, shown in zip(predictions, dataset.scenes, dataset.target_present(),
                                         strict=True):
        objects = record["objects"]
        blocks = [o["position_xy_m"] for o in objects if o["type"] in DISTRACTOR_TYPES]
        xy = [np.asarray(target.position_m[:2]) for target in prediction.targets]
        nearer += [min(np.linalg.norm(xy[k] - block) for block in blocks) < np.linalg.norm(
            xy[k] - objects[record["targets"][k]]["position_xy_m"])
            for k in range(len(xy)) if blocks and shown[k]]
    return int(sum(nearer)) if nearer else None


def score_set(model: LearnableModel, name: str, path: Path) -> SetScore:
    """The model's judged picks, error and grasps nearer the block on one test set."""
    dataset = load_dataset(path)
    model.spec.check_dataset(dataset)
    result = evaluate(model, dataset)
    judged, extra = result.judged, dataset.metadata.extra
    if judged is None:
        raise SimError(f"{path}: no target the grasp judge can judge (grasp labels)")
    return SetScore(
        name, str(path), extra.get("scenes", len(dataset)),
        extra.get("demonstrations_redrawn", 0), judged.all.targets,
        round(judged.all.targets * judged.all.predicted_success_rate),
        judged.all.expected_success_rate, result.mean_position_error_cm,
        sum(e is not None for row in result.position_errors_cm for e in row),
        {kind: ObjectScore(g.targets, round(g.targets * g.predicted_success_rate))
         for kind, g in judged.per_object.items()},
        nearer_block(predict_dataset(model, dataset), dataset))


def pooled(sets: Sequence[SetScore]) -> SetScore:
    """Every seed's set as one: counts summed, rate and error weighted by their targets."""
    picks, targets = sum(s.picks for s in sets), sum(s.scored_targets for s in sets)
    near = [s.nearer_block for s in sets if s.nearer_block is not None]
    return SetScore(
        sets[0].test_set, "", sum(s.scenes for s in sets), sum(s.redrawn for s in sets), picks,
        sum(s.predicted_picked for s in sets),
        sum(s.expected_success_rate * s.picks for s in sets) / max(picks, 1),
        sum(s.mean_position_error_cm * s.scored_targets for s in sets) / max(targets, 1),
        targets, {kind: ObjectScore(*map(sum, zip(*(astuple(s.per_object[kind]) for s in sets
                                                    if kind in s.per_object), strict=True)))
                  for kind in dict.fromkeys(k for s in sets for k in s.per_object)},
        sum(near) if near else None)


def cell(x: SetScore) -> str:
    """``25/30 1.2cm 3>blk``: judged picked / picks, mean error, grasps nearer the block."""
    near = "" if x.nearer_block is None else f" {x.nearer_block}>blk"
    return f"{x.predicted_picked}/{x.picks} {x.mean_position_error_cm:.1f}cm{near}"


def table(scores: Sequence[Score], seeds: Sequence[int]) -> tuple[list[str], list[Score]]:
    """The printed table's lines (a row per source, task and test set), and the pooled scores."""
    rows, totals = [["source", "task", "set", *(f"s{seed}" for seed in seeds), "pooled"]], []
    for source, task in dict.fromkeys((s.source, s.task) for s in scores):
        mine = {s.seed: s for s in scores if (s.source, s.task) == (source, task)}
        totals.append(Score(source, task, None, "", *(
            pooled([getattr(s, name) for s in mine.values()]) for name in SET_NAMES)))
        rows += [[source, task, name, *(cell(getattr(mine[seed], name)) if seed in mine else "-"
                                        for seed in seeds), cell(getattr(totals[-1], name))]
                 for name in SET_NAMES]
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return ["  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)).rstrip()
            for r in rows], totals

