"""A training that checks itself on scenes it held out: the split, the check, the retries."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from gva_cli import gva
from user_models import TYPES, synthetic_dataset

from perception.interface import ConditionKind, InvalidInputError, LabelKind, Prediction, Target
from perception.judge.grasp_judge import yaw_of
from perception.labels import label_vector, split_label
from perception.learning.data import Dataset, DatasetMetadata
from perception.learning.dataset_file import save_dataset
from perception.learning.learnable import LearnableModel, ModelSpec
from perception.learning.train import TrainConfig, TrainReport
from perception.learning.validation import (
    CheckConfig,
    attempt_seed,
    check_model,
    fit_checked,
    percent,
    read_check,
    split_scenes,
    write_check,
)
from perception.objects.catalog import get_object_spec
from perception.objects.grasps import grasp_pose
from perception.poses import Pose


class LookupModel(LearnableModel):
    """Predicts every sample of a known dataset right, but ``off_m`` off under one condition.

    Stands in for a trained model whose one Query memorised its images: exact elsewhere. Its
    seed picks whether it is off (the seeds in ``bad_seeds``), so retries can be tested.
    """

    name = "lookup"
    bad_seeds: tuple[int, ...] = ()

    def __init__(self, truth: Dataset, seed: int, bad_condition: int = 1,
                 off_m: float = 0.05) -> None:
        self.spec = ModelSpec.from_metadata(truth.metadata)
        self.truth, self.seed = truth, seed
        self.bad_condition, self.off_m = bad_condition, off_m
        self.fitted_on: Dataset | None = None

    def fit(self, dataset: Dataset, config: TrainConfig, progress: bool = True) -> TrainReport:
        self.fitted_on = dataset
        return TrainReport(1, len(dataset), 0.0, ((1, 0.0),), 0.0, 1, config)

    def predict_batch(self, images: np.ndarray, conditions: np.ndarray,
                      depths_m: np.ndarray | None = None) -> list[Prediction]:
        predictions = []
        for image, condition in zip(images, conditions, strict=True):
            n = next(i for i in range(len(self.truth))
                     if np.array_equal(self.truth.images[i], image)
                     and np.array_equal(self.truth.conditions[i], condition))
            position = self.truth.labels[n, 0, :3].astype(float)
            if self.seed in self.bad_seeds and int(condition.argmax()) == self.bad_condition:
                position = position + np.array([self.off_m, 0.0, 0.0])
            predictions.append(Prediction((Target(position),)))
        return predictions

    def save(self, path: str | Path) -> Path:
        raise NotImplementedError

    @classmethod
    def load(cls, path: str | Path) -> LookupModel:
        raise NotImplementedError


def every_condition(size: int = 10) -> Dataset:
    """Synthetic scenes of three squares, each scene asked all three types (a sample each)."""
    base = synthetic_dataset(size, conditioned=True)
    rows = [(n, c) for n in range(size) for c in range(len(TYPES))]
    labels = []
    for n, c in rows:  # the label of square c, from the drawn one's by the scene's corners
        v, u = base.scenes[n]["corners_px"][c]
        labels.append([[0.3 + 0.3 * (v + 4) / 64, 0.2 - 0.4 * (u + 4) / 64, 0.02 * c]])
    return Dataset(replace(base.metadata, size=len(rows)),
                   base.images[[n for n, _ in rows]],
                   np.eye(len(TYPES), dtype=np.float32)[[c for _, c in rows]],
                   np.array(labels, dtype=np.float32),
                   tuple(base.scenes[n] for n, _ in rows))


def test_whole_scenes_are_held_out_the_same_for_a_seed():
    data = every_condition(10)
    kept, held = split_scenes(data, 0.2, seed=3)
    assert held is not None and (len(kept), len(held)) == (24, 6)
    held_scenes = {record["index"] for record in held.scenes}
    assert len(held_scenes) == 2 and held_scenes.isdisjoint(r["index"] for r in kept.scenes)
    again, _ = split_scenes(data, 0.2, seed=3)
    assert again == kept
    assert {r["index"] for r in split_scenes(data, 0.2, seed=4)[1].scenes} != held_scenes
    assert split_scenes(data, 0.0, seed=3) == (data, None)
    small = data.first_scenes(2)
    assert split_scenes(small, 0.2, seed=3) == (small, None)  # too few scenes to hold one out
    assert len({r["index"] for r in split_scenes(data.first_scenes(3), 0.2, 0)[1].scenes}) == 1


def test_the_split_holds_out_each_kind_of_scene_in_its_share():
    data = every_condition(20)
    kinds = ["mug"] * 9 + ["sponge"] * 6 + ["spray_bottle"] * 5  # a single-like spread
    scenes = tuple(record | {"objects": [{"type": kinds[record["index"]]}]}
                   for record in data.scenes)
    typed = Dataset(data.metadata, data.images, data.conditions, data.labels, scenes)
    for seed in range(20):
        _, held = split_scenes(typed, 0.2, seed)
        shown = {r["index"]: r["objects"][0]["type"] for r in held.scenes}
        assert sorted(shown.values()) == ["mug", "mug", "sponge", "spray_bottle"], seed
    rare = tuple(record | {"objects": [{"type": "bottle" if record["index"] == 0 else "mug"}]}
                 for record in data.scenes)
    _, held = split_scenes(Dataset(data.metadata, data.images, data.conditions, data.labels,
                                   rare), 0.2, 0)
    assert 0 not in {r["index"] for r in held.scenes}  # the one bottle is never held out


def test_the_check_names_the_condition_over_the_limit():
    data = every_condition(10)
    LookupModel.bad_seeds = (7,)
    good = check_model(LookupModel(data, seed=0), data, 2.0, attempt=1, model_seed=0)
    assert good.passed and good.reason == "" and good.mean_position_error_cm == 0.0
    assert set(good.per_condition_mean_position_error_cm) == set(TYPES)
    bad = check_model(LookupModel(data, seed=7), data, 2.0, attempt=1, model_seed=7)
    assert not bad.passed
    assert bad.reason == "condition 'green': 5.00 cm > 2.00 cm"  # the mean 1.67 cm passes
    assert bad.per_condition_mean_position_error_cm["red"] == 0.0
    assert "held-out check FAILED: condition 'green': 5.00 cm > 2.00 cm" in bad.headline()


def test_a_failed_attempt_is_retried_from_another_start_and_the_last_is_kept(tmp_path):
    data = every_condition(10)
    built = []

    def build(seed):
        built.append(seed)
        return LookupModel(data, seed)

    LookupModel.bad_seeds = (5,)
    fit = fit_checked(build, data, TrainConfig(seed=5), CheckConfig(attempts=3), progress=False)
    assert built == [5, attempt_seed(5, 2)] and fit.check.passed and fit.check.attempt == 2
    assert [c.passed for c in fit.checks] == [False, True]
    assert len(fit.model.fitted_on) == 24  # trained on the kept scenes only
    LookupModel.bad_seeds = (5, attempt_seed(5, 2))
    failed = fit_checked(lambda seed: LookupModel(data, seed), data, TrainConfig(seed=5),
                         CheckConfig(attempts=2), progress=False)
    assert not failed.check.passed and len(failed.checks) == 2
    write_check(tmp_path, failed)
    assert read_check(tmp_path) == failed.check
    unchecked = fit_checked(lambda seed: LookupModel(data, seed), data, TrainConfig(seed=5),
                            CheckConfig(holdout=0.0), progress=False)
    assert unchecked.check is None and len(unchecked.model.fitted_on) == 30
    write_check(tmp_path, unchecked)  # an unchecked training leaves no older check behind
    assert read_check(tmp_path) is None


@pytest.mark.parametrize(("field", "value", "allowed"), [
    ("holdout", 1.0, "a fraction in [0, 1)"), ("limit_cm", 0.0, "a finite length > 0 [cm]"),
    ("attempts", 0, "an integer >= 1")])
def test_bad_check_settings_are_named(field, value, allowed):
    with pytest.raises(InvalidInputError, match=re.escape(f"{field} = {value!r} is not "
                                                          f"allowed: {allowed}")):
        CheckConfig(**{field: value})


@pytest.mark.slow
def test_gva_train_says_loudly_that_a_starved_training_failed(tmp_path):
    """The held-out check catches a Query that never learned: the bar of issue 17, item 3.

    A `paper-sim` `selected-type` dataset asked every condition, but starved: the duck's
    question is kept in one training scene only (still asked in every scene held out). The
    trained kqv finds the others and not the duck; `gva train` marks it and exits 1. 250
    steps (500 until issue 65's time budget): the others already lie within half the duck's
    error.
    """
    from harness.inputs.collector import CollectSettings, collect

    full = collect(CollectSettings("paper-sim", "selected-type", size=12, seed=6),
                   tmp_path / "full.gva", progress=False)
    _, held = split_scenes(full, 0.2, seed=0)
    held_scenes = {record["index"] for record in held.scenes}
    duck = full.metadata.condition_choices.index("duck")
    starved = [n for n, record in enumerate(full.scenes)
               if record["index"] in held_scenes or full.conditions[n].argmax() != duck
               or record["index"] == min(set(range(12)) - held_scenes)]
    save_dataset(full.subset(starved), tmp_path / "starved.gva")
    status, stdout, stderr = gva("train", "--model", "kqv", "--data", tmp_path / "starved.gva",
                                 "--out", tmp_path / "ckpt", "--steps", "250", "--attempts",
                                 "1", "--check-limit-cm", "2", "--threads", "1",
                                 "--no-progress")
    assert status == 1, stdout + stderr
    check = read_check(tmp_path / "ckpt")
    assert not check.passed and "condition 'duck'" in check.reason
    errors_cm = check.per_condition_mean_position_error_cm
    assert errors_cm["duck"] > 2.0
    assert max(e for c, e in errors_cm.items() if c != "duck") < errors_cm["duck"] / 2, errors_cm
    assert "WARNING: " in stderr and "failed its held-out check" in stderr
    assert "held-out check FAILED: " in stdout


# --- the check of a weak head (issue 75) ---

TYPED = ("sponge", "spray_bottle", "mug")


def picked_scenes(size: int) -> Dataset:
    """``multiple``-like grasp scenes: a sponge, a spray bottle and a mug, a head each."""
    rng = np.random.default_rng(3)
    labels, scenes = [], []
    for n in range(size):
        poses = [Pose.from_xy_yaw(0.40 + 0.05 * k, 0.1 * (k - 1), float(rng.uniform(-1, 1)))
                 for k in range(3)]
        grasps = [grasp_pose(get_object_spec(t), p) for t, p in zip(TYPED, poses, strict=True)]
        labels.append([label_vector(g.position[None], g.rotation[None])[0] for g in grasps])
        scenes.append({"index": n, "targets": [0, 1, 2], "objects": [
            {"type": t, "position_xy_m": [float(p.position[0]), float(p.position[1])],
             "yaw_rad": yaw_of(p.rotation), "distractor": False}
            for t, p in zip(TYPED, poses, strict=True)]})
    images = rng.integers(0, 255, (size, 8, 8, 3), dtype=np.uint8)  # each sample its own
    meta = DatasetMetadata(scene="yumi", task="multiple", size=size, seed=0, image_height_px=8,
                           image_width_px=8, label_kind=LabelKind.GRASP_POSE, targets=3,
                           condition_kind=ConditionKind.NONE, condition_choices=(),
                           camera={}, extra={"object_types": list(TYPED)})
    return Dataset(meta, images, np.zeros((size, 0), np.float32),
                   np.array(labels, dtype=np.float32), tuple(scenes))


class ApproachOff(LearnableModel):
    """Every grasp exact but the bottle head's, pushed along its approach axis: the collapsed
    seed's failure (its errors lay along the ray, 18.6 mm mean)."""

    name = "approach-off"

    def __init__(self, truth: Dataset, off_mm: list[float], axis: int = 2) -> None:
        self.spec, self.truth, self.off_mm = ModelSpec.from_metadata(truth.metadata), truth, off_mm
        self.label_kind, self.axis = LabelKind.GRASP_POSE, axis  # axis of the grasp frame

    def predict_batch(self, images, conditions, depths_m=None):
        out = []
        for image in images:
            n = next(i for i in range(len(self.truth)) if np.array_equal(self.truth.images[i],
                                                                          image))
            truth = split_label(self.truth.labels[n:n + 1].astype(float))
            targets = []
            for k in range(3):
                position, rotation = truth.position_m[0, k], truth.rotation[0, k]
                if k == 1:  # the spray bottle's head
                    position = position + rotation[:, self.axis] * self.off_mm[n] / 1000
                targets.append(Target(position, rotation))
            out.append(Prediction(tuple(targets)))
        return out

    def fit(self, dataset, config, progress=True):
        raise NotImplementedError

    def save(self, path):
        raise NotImplementedError

    @classmethod
    def load(cls, path):
        raise NotImplementedError


@pytest.mark.parametrize(("off_mm", "passes"), [
    ([5.0, 5.0, 5.0, 5.0], True),  # judged 100 %, expected 98 %: sound
    ([12.0, 12.0, 12.0, 12.0], True),  # judged 100 %, expected 88 %: near, sound
    ([8.0, 22.0, 8.0, 22.0], False),  # judged 50 %: a head that misses every other pick
    ([15.0, 15.0, 15.0, 22.0], False),  # judged 75 %, as the collapsed seed's check saw it
])
def test_a_weak_head_fails_its_check_and_a_sound_one_passes(off_mm, passes):
    data = picked_scenes(4)
    check = check_model(ApproachOff(data, off_mm), data, 2.0, attempt=1, model_seed=0,
                        min_expected_success=CheckConfig().min_expected_success)
    assert check.passed is passes, check.reason
    if not passes:
        assert check.reason.startswith("head 1 expected picked:")
    share = check.per_target_judged_success_rate["head 1"]
    assert share == {5.0: 1.0, 12.0: 1.0, 8.0: 0.5, 15.0: 0.75}[off_mm[0]]


def test_a_bottle_off_along_the_axis_it_tolerates_passes_where_the_judge_reads_it():
    """2.1 cm along the bottle's length (the grasp frame's y): the judge expects 0.955 picked;
    the 2 cm sphere refused such a head at seeds 21 and 26, where its trials picked 27, 28."""
    data = picked_scenes(4)
    model = ApproachOff(data, [21.0] * 4, axis=1)
    check = check_model(model, data, 2.0, attempt=1, model_seed=0,
                        min_expected_success=CheckConfig().min_expected_success)
    assert check.passed, check.reason
    assert check.per_target_mean_position_error_cm[1] == pytest.approx(2.1, abs=1e-3)
    assert check.per_target_expected_success["head 1"] > 0.9
    unjudged = check_model(model, data, 2.0, attempt=1, model_seed=0)  # the judge not read
    assert not unjudged.passed and unjudged.reason == "head 1: 2.10 cm > 2.00 cm"


def test_a_share_just_under_its_floor_reads_under_it():
    assert percent(0.7956, 0.8) == "79.6 %" and percent(0.54, 0.8) == "54 %"
