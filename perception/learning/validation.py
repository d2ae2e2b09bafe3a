"""A training that checks itself: scenes held out of its own demonstrations score it.

A model trained on 20 demonstrations can fit them all and still have learned nothing that
carries to a new scene (a Query that memorised its few images); the training loss does not
show it. :func:`fit_checked` holds out a few scenes of the training set (never test scenes),
trains on the rest and scores the trained model on the held-out ones, overall, per condition
value and per head. Over the limit, it tries again from another start; if every attempt fails,
the model is returned marked failed with the reason, and :func:`write_check` keeps that beside
the checkpoint, where ``gva train``, ``gva reproduce`` and the trials read it and say so.

The model it returns is the one it checked, trained on the kept scenes only: a check of one
model that then ships another is no check.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from perception.files import atomic_write
from perception.interface import InvalidInputError
from perception.learning.combined import is_demonstration
from perception.learning.data import Dataset

if TYPE_CHECKING:  # torch: not for the settings of a run (`gva --help`, run identities)
    from perception.learning.learnable import LearnableModel
    from perception.learning.train import TrainConfig, TrainReport

CHECK_FILE = "check.json"
"""The held-out check's file in a checkpoint folder."""


@dataclass(frozen=True)
class CheckConfig:
    """How a training checks itself.

    Args:
        holdout: Fraction of the training scenes held out (rounded, at least one scene where
            two or more remain to train on); 0 trains on every scene and checks nothing.
            Where demonstrations are trained on beside other scenes, of the demonstrations
            (:func:`split_scenes`).
        limit_cm: The largest mean held-out position error allowed, of the whole, of each
            condition value and of each head [cm], where the grasp judge does not judge every
            held-out target (position labels, object types its map never measured). 2 cm: a
            grasp further off misses the spray bottle and the mug
            (``docs/decisions/every-condition.md``). Where the judge judges them all, it reads
            each error along the axis the object tolerates it on, and the 2 cm sphere does
            not (a bottle 2.1 cm off along its length, expected 0.95 picked, refused at seeds
            21 and 26; ``docs/decisions/any-seed.md``): the means are recorded, not checked.
        min_expected_success: For grasp-pose labels, the least share of the held-out targets
            expected picked, of the whole, of each condition value and of each head: the mean
            of the grasp judge's calibrated probabilities
            (:attr:`~perception.learning.judged_errors.JudgedGroup.mean_probability`). A
            position check passes a sponge turned 40 degrees, which the trial misses; and the
            share the judge predicts picked cannot tell, from the 4-8 targets a head has in the
            four scenes a 20-demonstration check holds out, a head that misses one pick in
            three from a sound one (issue 75: a bottle head judged 55 % on test scenes passed
            at 3 of 4), where near misses lower the mean of the probabilities. 0.8: a head
            missing one pick in three (0.67) fails, a sound one (0.93 and above on test
            scenes) passes; set before any run measured with it (docs/decisions/any-seed.md).
        attempts: Trainings tried, each from another start, before the model is marked failed.
            3: what fails a sound training is its start (at seeds 20-29 every checkpoint the
            check refused that got a further start passed it, one at its third), and a third
            training costs only where two failed (1 of 40 there); ``docs/decisions/any-seed.md``.

    """

    holdout: float = 0.2
    limit_cm: float = 2.0
    min_expected_success: float = 0.8
    attempts: int = 3

    def __post_init__(self) -> None:
        if not (math.isfinite(self.holdout) and 0 <= self.holdout < 1):
            raise InvalidInputError("holdout", self.holdout, "a fraction in [0, 1)")
        if not (math.isfinite(self.limit_cm) and self.limit_cm > 0):
            raise InvalidInputError("limit_cm", self.limit_cm, "a finite length > 0 [cm]")
        if not (math.isfinite(self.min_expected_success) and
                0 <= self.min_expected_success <= 1):
            raise InvalidInputError("min_expected_success", self.min_expected_success,
                                    "a fraction in [0, 1]")
        if not isinstance(self.attempts, int) or isinstance(self.attempts, bool) or \
                self.attempts < 1:
            raise InvalidInputError("attempts", self.attempts, "an integer >= 1")


@dataclass(frozen=True)
class HeldOutCheck:
    """How a trained model did on the scenes its training held out.

    Args:
        passed: Whether every expected share is at its floor (grasp poses the judge judges
            whole) or every mean is within ``limit_cm`` (the rest).
        reason: What failed, e.g. ``"condition 'mug': 7.31 cm > 2.00 cm"``; "" when passed.
        held_out_scenes: The scene indices held out (their records' ``"index"``).
        samples: Held-out samples scored (a scene may give several).
        mean_position_error_cm: Mean over every present target [cm].
        per_condition_mean_position_error_cm: Mean per condition value [cm]; None: no condition.
        per_target_mean_position_error_cm: Mean per head [cm].
        limit_cm: The limit checked against [cm].
        attempt: Which attempt this is, from 1.
        model_seed: The seed of the attempt's weights and batches.
        judged_success_rate: The share of held-out targets the grasp judge predicts picked;
            None for position labels (and checks written before the judge).
        per_condition_judged_success_rate: The same per condition value; None: no condition.
        per_target_judged_success_rate: The same per head; None: one head.
        min_judged_success: The least share checked against, by checks written before the
            expected share replaced it; None since.
        expected_success: The mean of the judge's calibrated probabilities over the held-out
            targets (the share expected picked); None for position labels and older checks.
        per_condition_expected_success: The same per condition value; None: no condition.
        per_target_expected_success: The same per head; None: one head.
        min_expected_success: The least expected share checked against.

    """

    passed: bool
    reason: str
    held_out_scenes: tuple[int, ...]
    samples: int
    mean_position_error_cm: float
    per_condition_mean_position_error_cm: dict[str, float] | None
    per_target_mean_position_error_cm: tuple[float, ...]
    limit_cm: float
    attempt: int
    model_seed: int
    judged_success_rate: float | None = None
    per_condition_judged_success_rate: dict[str, float] | None = None
    per_target_judged_success_rate: dict[str, float] | None = None
    min_judged_success: float | None = None
    expected_success: float | None = None
    per_condition_expected_success: dict[str, float] | None = None
    per_target_expected_success: dict[str, float] | None = None
    min_expected_success: float | None = None

    def headline(self) -> str:
        """One line: passed or FAILED, and the held-out errors."""
        parts = [f"mean {self.mean_position_error_cm:.2f} cm"]
        if self.per_condition_mean_position_error_cm:
            parts.append("per condition " + ", ".join(
                f"{value} {e:.2f}" for value, e in
                self.per_condition_mean_position_error_cm.items()))
        if len(self.per_target_mean_position_error_cm) > 1:
            parts.append("per head " + ", ".join(
                f"{e:.2f}" for e in self.per_target_mean_position_error_cm))
        if self.judged_success_rate is not None:
            parts.append(f"judged picked {100 * self.judged_success_rate:.0f} %")
        if self.per_target_expected_success:
            parts.append("expected per head " + ", ".join(
                f"{100 * p:.0f} %" for p in self.per_target_expected_success.values()))
        elif self.expected_success is not None:
            parts.append(f"expected {100 * self.expected_success:.0f} %")
        where = (f"{len(self.held_out_scenes)} held-out scene(s), attempt {self.attempt}: "
                 + "; ".join(parts))
        if self.passed:
            return f"held-out check passed ({where}; limit {self.limit_cm:g} cm)"
        return f"held-out check FAILED: {self.reason} ({where})"

    def to_json(self) -> dict[str, Any]:
        """The check as JSON-able data."""
        return asdict(self) | {"held_out_scenes": list(self.held_out_scenes),
                               "per_target_mean_position_error_cm":
                                   list(self.per_target_mean_position_error_cm)}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> HeldOutCheck:
        """The check :meth:`to_json` wrote."""
        return cls(**data | {"held_out_scenes": tuple(data["held_out_scenes"]),
                             "per_target_mean_position_error_cm":
                                 tuple(data["per_target_mean_position_error_cm"])})


class AttemptTime(NamedTuple):
    """Where one attempt of :func:`fit_checked` spent its time [s]: training, then checking."""

    train_s: float
    check_s: float


@dataclass(frozen=True)
class CheckedFit:
    """What :func:`fit_checked` returns: the model it kept, its report, and every check."""

    model: LearnableModel
    report: TrainReport
    checks: tuple[HeldOutCheck, ...]  # one per attempt; the last is the kept model's
    times: tuple[AttemptTime, ...] = ()  # one per attempt: what a retry cost

    @property
    def check(self) -> HeldOutCheck | None:
        """The kept model's check; None where nothing was held out."""
        return self.checks[-1] if self.checks else None


def scene_kind(record: dict[str, Any]) -> tuple[str, ...]:
    """What a scene shows, for a stratified split: its objects' types, sorted; () if unnamed."""
    return tuple(sorted(str(o.get("type")) for o in record.get("objects", ())
                        if isinstance(o, dict) and not o.get("distractor")))


def split_scenes(dataset: Dataset, holdout: float, seed: int) -> tuple[Dataset, Dataset | None]:
    """(kept, held out): whole scenes, ``round(holdout x scenes)`` of them drawn with ``seed``.

    At least one scene is held out where ``holdout`` > 0 and two or more scenes remain to
    train on; None where nothing is held out. The split is stratified by what each scene shows
    (:func:`scene_kind`): each kind gives its share, never its last scene, so a rare object
    type is not held out whole (a random split of 20 ``single`` demonstrations once held out
    four of the five spray bottles, and the training never learned the bottle).

    A training set that mixes demonstrations with other scenes (catalog-labelled, randomised
    looks: :func:`~perception.learning.combined.is_demonstration`) holds out demonstrations
    only, the fraction taken of them: the same scenes their split alone holds out, so the check
    scores the kind of scene the trials show, comparably with or without the extra scenes.
    """
    pool = [n for n, record in enumerate(dataset.scenes) if is_demonstration(record)]
    if 0 < len(pool) < len(dataset):
        _, drawn = split_scenes(dataset.subset(pool), holdout, seed)
        if drawn is None:
            return dataset, None
        gone = set(drawn.scene_keys())
        return dataset.subset([n for n, key in enumerate(dataset.scene_keys())
                               if key not in gone]), drawn
    keys = dataset.scene_keys()
    scenes = list(dict.fromkeys(keys))
    count = min(max(round(holdout * len(scenes)), 1 if holdout > 0 else 0), len(scenes) - 2)
    if count <= 0:
        return dataset, None
    first = {key: n for n, key in reversed(list(enumerate(keys)))}
    strata: dict[tuple[str, ...], list[int]] = {}
    for key in scenes:
        strata.setdefault(scene_kind(dataset.scenes[first[key]]), []).append(key)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x486F6C64]))  # "Hold"
    if len(strata) == 1:  # one kind of scene: a plain draw (the split before strata existed)
        held = {scenes[i] for i in rng.choice(len(scenes), size=count, replace=False)}
        return (dataset.subset([n for n, key in enumerate(keys) if key not in held]),
                dataset.subset([n for n, key in enumerate(keys) if key in held]))
    kinds = sorted(strata)
    room = {kind: len(strata[kind]) - 1 for kind in kinds}  # each kind keeps one scene
    exact = {kind: count * len(strata[kind]) / len(scenes) for kind in kinds}
    quota = {kind: min(int(exact[kind]), room[kind]) for kind in kinds}
    ties = rng.random(len(kinds))
    by_remainder = sorted(range(len(kinds)), key=lambda k: (-(exact[kinds[k]] % 1), ties[k]))
    while sum(quota.values()) < count and any(quota[k] < room[k] for k in kinds):
        for k in by_remainder:
            kind = kinds[k]
            if sum(quota.values()) < count and quota[kind] < room[kind]:
                quota[kind] += 1
    held = {strata[kind][i] for kind in kinds
            for i in rng.choice(len(strata[kind]), size=quota[kind], replace=False)}
    return (dataset.subset([n for n, key in enumerate(keys) if key not in held]),
            dataset.subset([n for n, key in enumerate(keys) if key in held]))


def check_model(model: LearnableModel, held_out: Dataset, limit_cm: float, attempt: int,
                model_seed: int, min_expected_success: float | None = None) -> HeldOutCheck:
    """Scores ``model`` on ``held_out``: whole, each condition, each head.

    For grasp-pose labels, where ``min_expected_success`` is given, against that expected
    share of targets picked (the mean of the grasp judge's calibrated probabilities; the share
    it predicts picked is recorded beside it); against ``limit_cm`` of mean position error
    where the judge does not judge every present target (position labels).
    """
    from perception.learning.evaluate import evaluate  # torch, once a model is trained

    result = evaluate(model, held_out)
    judged = result.judged
    means = [("held-out mean", result.mean_position_error_cm)]
    means += [(f"condition {value!r}", e) for value, e in
              (result.per_condition_mean_position_error_cm or {}).items()]
    if held_out.metadata.targets > 1:
        means += [(f"head {k}", e) for k, e in
                  enumerate(result.per_target_mean_position_error_cm)]
    over = []
    if not (judged is not None and min_expected_success is not None and
            judged.all.targets == int(held_out.target_present().sum())):
        over = [f"{name}: {e:.2f} cm > {limit_cm:.2f} cm" for name, e in means
                if not e <= limit_cm]
    rates: dict[str, Any] = {}
    if judged is not None and min_expected_success is not None:
        conditions, heads = judged.per_condition or {}, judged.per_head or {}
        expected = [("expected picked", judged.all.mean_probability)]
        expected += [(f"condition {name!r} expected picked", g.mean_probability)
                     for name, g in conditions.items()]
        expected += [(f"{name} expected picked", g.mean_probability) for name, g in heads.items()]
        over += [f"{name}: {percent(p, min_expected_success)} < "
                 f"{100 * min_expected_success:.0f} %"
                 for name, p in expected if not p >= min_expected_success]
        rates = {"judged_success_rate": judged.all.predicted_success_rate,
                 "per_condition_judged_success_rate": {
                     name: g.predicted_success_rate for name, g in conditions.items()} or None,
                 "per_target_judged_success_rate": {
                     name: g.predicted_success_rate for name, g in heads.items()} or None,
                 "expected_success": judged.all.mean_probability,
                 "per_condition_expected_success": {
                     name: g.mean_probability for name, g in conditions.items()} or None,
                 "per_target_expected_success": {
                     name: g.mean_probability for name, g in heads.items()} or None,
                 "min_expected_success": min_expected_success}
    return HeldOutCheck(
        passed=not over, reason="; ".join(over),
        held_out_scenes=tuple(sorted(set(held_out.scene_keys()))), samples=len(held_out),
        mean_position_error_cm=result.mean_position_error_cm,
        per_condition_mean_position_error_cm=result.per_condition_mean_position_error_cm,
        per_target_mean_position_error_cm=result.per_target_mean_position_error_cm,
        limit_cm=limit_cm, attempt=attempt, model_seed=model_seed, **rates)


def percent(share: float, floor: float) -> str:
    """``share`` in per cent, to as many decimals as it takes to read below ``floor``.

    0.7956 against 0.8 reads "79.6 %", never "80 % < 80 %".
    """
    for decimals in range(4):
        text = f"{100 * share:.{decimals}f}"
        if float(text) < 100 * floor:
            return f"{text} %"
    return f"{100 * share:.4f} %"


def attempt_seed(seed: int, attempt: int) -> int:
    """The seed of attempt ``attempt`` (from 1): ``seed`` first, then derived ones."""
    if attempt == 1:
        return seed
    return int(np.random.SeedSequence([seed, attempt]).generate_state(1)[0] >> 1)


def fit_checked(build: Callable[[int], LearnableModel], dataset: Dataset, config: TrainConfig,
                check: CheckConfig | None = None, progress: bool = True,
                log: Callable[[str], None] | None = None) -> CheckedFit:
    """Trains ``build(seed)`` on the kept scenes and checks it on the held-out ones.

    ``build`` makes a fresh model whose weights are seeded with its argument; each attempt
    uses another seed for the weights and the batches (:func:`attempt_seed`). The held-out
    scenes are the same for every attempt (drawn with ``config.seed``). Returns the first
    model that passes, else the last one, marked failed by its check. ``log`` is told each
    attempt's check line.
    """
    check = check or CheckConfig()
    kept, held_out = split_scenes(dataset, check.holdout, config.seed)
    checks: list[HeldOutCheck] = []
    times: list[AttemptTime] = []
    for attempt in range(1, check.attempts + 1):
        seed = attempt_seed(config.seed, attempt)
        started = time.perf_counter()
        model = build(seed)
        report = model.fit(kept, replace(config, seed=seed), progress=progress)
        trained = time.perf_counter()
        if held_out is None:
            return CheckedFit(model, report, (), (AttemptTime(trained - started, 0.0),))
        checks.append(check_model(model, held_out, check.limit_cm, attempt, seed,
                                  check.min_expected_success))
        times.append(AttemptTime(trained - started, time.perf_counter() - trained))
        if log is not None:
            log(checks[-1].headline())
        if checks[-1].passed:
            break
    return CheckedFit(model, report, tuple(checks), tuple(times))


def write_check(folder: str | Path, fit: CheckedFit) -> Path | None:
    """Writes the kept model's check (and the earlier attempts') beside its checkpoint.

    A fit that checked nothing removes an older check from the folder.
    """
    path = Path(folder) / CHECK_FILE
    if fit.check is None:
        path.unlink(missing_ok=True)
        return None
    data = fit.check.to_json() | {"attempts": [c.to_json() for c in fit.checks]}
    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    atomic_write(path, lambda temporary: temporary.write_text(text, encoding="utf-8"))
    return path


def read_check(folder: str | Path) -> HeldOutCheck | None:
    """The held-out check of a checkpoint folder; None where its training checked nothing."""
    path = Path(folder) / CHECK_FILE
    if not path.is_file():
        return None
    data = json.loads(path.read_text(encoding="utf-8"))
    data.pop("attempts", None)
    return HeldOutCheck.from_json(data)
