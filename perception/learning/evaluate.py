"""Scores a perception model on a dataset of untrained scenes, as the paper reports it.

The headline number is the mean position error in cm over every target of every sample (paper
Table II), counting only the targets in the image: a demonstration of several picks keeps the
image before each pick, and the ones already picked are gone from it
(``Dataset.target_present``); each pick stage is scored on its own too. For grasp-pose labels
the angle between predicted and true TCP rotations is reported too, in degrees, counting a half
turn about the TCP's z (approach) axis as no error: a parallel gripper turned that way makes the
same grasp. Where the model states the object type of each target and the dataset's scene
records name it, the fraction stated right is reported as well.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from perception.camera import RgbdFrame
from perception.checks import check_inputs
from perception.interface import (
    ConditionKind,
    InvalidInputError,
    ModelInput,
    PerceptionModel,
    Prediction,
)
from perception.labels import split_label
from perception.learning.data import Dataset
from perception.learning.judged_errors import JudgedErrors, judge_predictions
from perception.learning.learnable import LearnableModel
from perception.learning.rotations import symmetric_angle_rad


@dataclass(frozen=True)
class EvaluationResult:
    """A model's errors on a dataset; every field is JSON-able through :meth:`to_json`.

    Args:
        model: The model's name.
        scene: The dataset's scene.
        task: The dataset's task.
        samples: N, images evaluated.
        targets: q, targets per image.
        mean_position_error_cm: Mean over the targets in the images [cm].
        median_position_error_cm: Median over the targets in the images [cm].
        per_target_mean_position_error_cm: (q,) mean per target index [cm].
        position_errors_cm: (N, q) every error [cm]; None for a target not in its image.
        mean_angle_error_deg: Mean rotation error [deg] (grasp labels), else None.
        median_angle_error_deg: Median rotation error [deg] (grasp labels), else None.
        per_target_mean_angle_error_deg: (q,) [deg] (grasp labels), else None.
        angle_errors_deg: (N, q) [deg] (grasp labels), else None.
        per_stage_mean_position_error_cm: Mean per pick stage [cm]: stage s holds the images
            taken after s picks that still have a target to score (one stage where every
            image shows every target).
        type_accuracy: Fraction of the targets of known type whose stated ``object_type`` is
            right (stating none is wrong); None where the model or the scene records name none.
        per_condition_mean_position_error_cm: Mean per condition value [cm], where a Query
            that memorised its demonstrations shows; None for a task without a condition.
        median_heatmap_entropy_nats: Median entropy of the heatmaps [nats]: near ``ln(h w)``
            (6.9 for 32 x 32) where the attention found nothing to look at. For a model whose
            head k looks for target k (kqv), the present targets' heatmaps; for heads tied to
            no target (keypoint-16's and dsae-16's 16 points, keypoint-min's q), every
            heatmap of every image. None for a model without heatmaps.
        attention_on_named_fraction: Under a condition that names one target: the fraction of
            images whose attention point is nearer the named object than any other object (in
            pixels, each object's centre projected at the target's height); None where the
            task has no such condition, the dataset no camera, or the model not one attention
            point for its one target (a key-point model's points look for no target).
        attention_switch_fraction: The same per scene, over the scenes asked under two or more
            conditions (``gva collect --every-condition``): the fraction whose attention lands
            on the named object under every one, i.e. moves when the condition changes.
        judged: Grasp-pose labels: every target through the grasp judge, as the trials judge
            a pick (errors in the grasp's frame, each object's tolerance), over all and per
            object type, condition value and head; None for position labels.

    """

    model: str
    scene: str
    task: str
    samples: int
    targets: int
    mean_position_error_cm: float
    median_position_error_cm: float
    per_target_mean_position_error_cm: tuple[float, ...]
    position_errors_cm: tuple[tuple[float | None, ...], ...]
    mean_angle_error_deg: float | None = None
    median_angle_error_deg: float | None = None
    per_target_mean_angle_error_deg: tuple[float, ...] | None = None
    angle_errors_deg: tuple[tuple[float | None, ...], ...] | None = None
    type_accuracy: float | None = None
    per_stage_mean_position_error_cm: tuple[float, ...] = ()
    per_condition_mean_position_error_cm: dict[str, float] | None = None
    median_heatmap_entropy_nats: float | None = None
    attention_on_named_fraction: float | None = None
    attention_switch_fraction: float | None = None
    judged: JudgedErrors | None = None

    def to_json(self) -> dict[str, Any]:
        """The result as JSON-able data (tuples become lists)."""
        return asdict(self)

    def headline(self) -> str:
        """One line: the mean and median errors."""
        line = (f"{self.model} on {self.scene} / {self.task} ({self.samples} images): position "
                f"error mean {self.mean_position_error_cm:.2f} cm, median "
                f"{self.median_position_error_cm:.2f} cm")
        if self.mean_angle_error_deg is not None:
            line += (f"; angle error mean {self.mean_angle_error_deg:.1f}°, median "
                     f"{self.median_angle_error_deg:.1f}°")
        if self.judged is not None:
            line += (f"; judged picked {100 * self.judged.all.predicted_success_rate:.1f} % of "
                     f"{self.judged.all.targets}")
        return line


OFFLINE_INPUTS = frozenset({ModelInput.RGB})
"""What offline evaluation gives every model: a dataset's colour images (and a learnable
model, their depth where the dataset keeps it and each sample's calibration where it records
one)."""


def predict_dataset(model: PerceptionModel, dataset: Dataset, batch_size: int = 32,
                    frames: bool = False) -> list[Prediction]:
    """Every sample's prediction, batched for a :class:`LearnableModel`, one by one otherwise.

    A dataset holds colour images, and depth images where its collector kept them: a model
    that reads what the dataset lacks (or the camera) is refused (one line, before any
    prediction); it is measured in trials. ``frames``: each sample is given as a trial's frame
    instead (:func:`_predict_frames`: a served model, which only ``predict_frame`` reaches).
    """
    if not isinstance(batch_size, int) or batch_size < 1:
        raise InvalidInputError("batch_size", batch_size, "an integer >= 1")
    if frames:
        return _predict_frames(model, dataset)
    if not isinstance(model, LearnableModel):
        check_inputs(model, OFFLINE_INPUTS, getattr(model, "name", type(model).__name__))
        return [model.predict(image, dataset.condition(index))
                for index, image in enumerate(dataset.images)]
    check_inputs(model, OFFLINE_INPUTS | ({ModelInput.DEPTH} if dataset.depths_m is not None
                                          else set())
                 | ({ModelInput.CAMERA} if dataset.cameras() is not None else set()), model.name)
    predictions: list[Prediction] = []
    for start in range(0, len(dataset), batch_size):
        predictions += model.predict_samples(dataset,
                                             range(start, min(start + batch_size, len(dataset))))
    return predictions


def _predict_frames(model: PerceptionModel, dataset: Dataset) -> list[Prediction]:
    """``predict_frame`` of each sample, given as a trial's frame would be.

    Its RGB, its depth where the dataset keeps it (else 0 everywhere: no measurement) and the
    sample's calibration (:meth:`Dataset.camera`); a model that reads depth the dataset lacks is
    refused first.
    """
    cameras = dataset.cameras()
    if cameras is None:
        raise InvalidInputError("dataset camera", "no geometry", "a dataset that records its "
                                "camera (the model is given calibrated frames)")
    depths = dataset.depths_m
    given = {ModelInput.RGB, ModelInput.CAMERA} | (set() if depths is None else
                                                   {ModelInput.DEPTH})
    check_inputs(model, frozenset(given), getattr(model, "name", type(model).__name__))
    blank = np.zeros(dataset.images.shape[1:3], np.float32)
    return [model.predict_frame(RgbdFrame(image, blank if depths is None else depths[index],
                                          cameras[index]), dataset.condition(index))
            for index, image in enumerate(dataset.images)]


def evaluate(model: PerceptionModel, dataset: Dataset, batch_size: int = 32,
             frames: bool = False) -> EvaluationResult:
    """The errors of ``model``'s predictions against ``dataset``'s labels.

    ``frames``: the model is given each sample as a trial's frame (:func:`predict_dataset`).

    Raises:
        InvalidInputError: The model predicts a different number of targets than the dataset
            holds, or no rotation where the dataset has grasp poses.

    """
    if len(dataset) == 0:
        raise InvalidInputError("dataset", "0 samples", "at least one sample")
    predictions = predict_dataset(model, dataset, batch_size, frames)
    meta, truth = dataset.metadata, split_label(dataset.labels.astype(np.float64))
    counts = {len(p.targets) for p in predictions}
    if counts != {meta.targets}:
        raise InvalidInputError("model targets", sorted(counts), f"{meta.targets} per image, as "
                                f"the dataset's {meta.task} task has")
    positions = np.array([[t.position_m for t in p.targets] for p in predictions])  # (N, q, 3)
    position_cm = np.linalg.norm(positions - truth.position_m, axis=-1) * 100  # (N, q)
    angle_deg = None
    if truth.rotation is not None:
        if any(t.rotation is None for p in predictions for t in p.targets):
            raise InvalidInputError("model rotation", None, "a rotation per target: the "
                                    "dataset's labels are grasp poses")
        rotations = np.array([[t.rotation for t in p.targets] for p in predictions])
        angle_deg = np.degrees(symmetric_angle_rad(rotations, truth.rotation))  # (N, q)

    present = dataset.target_present()  # (N, q)
    stage = (~present).sum(axis=1)  # (N,) targets already picked

    def table(errors: np.ndarray) -> tuple[tuple[float | None, ...], ...]:
        return tuple(tuple(float(e) if seen else None for e, seen in zip(row, shown, strict=True))
                     for row, shown in zip(errors, present, strict=True))

    def per_target(errors: np.ndarray) -> tuple[float, ...]:
        return tuple(float(errors[present[:, k], k].mean()) for k in range(meta.targets))

    return EvaluationResult(
        model=model.name, scene=meta.scene, task=meta.task, samples=len(dataset),
        targets=meta.targets, mean_position_error_cm=float(position_cm[present].mean()),
        median_position_error_cm=float(np.median(position_cm[present])),
        per_target_mean_position_error_cm=per_target(position_cm),
        position_errors_cm=table(position_cm),
        mean_angle_error_deg=None if angle_deg is None else float(angle_deg[present].mean()),
        median_angle_error_deg=None if angle_deg is None else float(
            np.median(angle_deg[present])),
        per_target_mean_angle_error_deg=None if angle_deg is None else per_target(angle_deg),
        angle_errors_deg=None if angle_deg is None else table(angle_deg),
        type_accuracy=type_accuracy(predictions, dataset),
        per_stage_mean_position_error_cm=tuple(
            float(position_cm[scored].mean()) for scored in
            ((stage == s)[:, None] & present for s in range(int(stage.max()) + 1))
            if scored.any()),
        per_condition_mean_position_error_cm=per_condition(position_cm, present, dataset),
        median_heatmap_entropy_nats=heatmap_entropy(predictions, present,
                                                    model.attention_per_target),
        **attention_on_named(predictions, dataset, model.attention_per_target),
        judged=None if angle_deg is None else judge_predictions(predictions, dataset),
    )


def attention_on_named(predictions: list[Prediction], dataset: Dataset,
                       per_target: bool = True) -> dict[str, float | None]:
    """Whether each image's attention lands on the object its condition names (see the fields).

    The objects' centres come from the scene records (x, y) at the label's height; the nearest
    one to the attention point in the image is the one attended to. ``per_target``: whether
    the model's attention head k looks for target k
    (:attr:`~perception.interface.PerceptionModel.attention_per_target`); if not, or where a
    prediction has other than one point, there is no attention to judge.
    """
    none: dict[str, float | None] = {"attention_on_named_fraction": None,
                                     "attention_switch_fraction": None}
    meta = dataset.metadata
    cameras = dataset.cameras()  # each sample's own: a look may have moved the camera
    if meta.condition_kind is ConditionKind.NONE or meta.targets != 1 or cameras is None or \
            not per_target or any(p.attention_px.shape[0] != 1 for p in predictions):
        return none
    height_m = split_label(dataset.labels.astype(np.float64)).position_m[:, 0, 2]  # (N,)
    on_named = []
    for prediction, record, z, camera in zip(predictions, dataset.scenes, height_m, cameras,
                                             strict=True):
        centres = np.array([[*o["position_xy_m"], z] for o in record["objects"]])  # (k, 3)
        distance = np.linalg.norm(camera.project(centres) - prediction.attention_px[0], axis=1)
        on_named.append(int(np.argmin(distance)) == record["targets"][0])
    by_scene: dict[int, list[bool]] = {}
    for key, hit in zip(dataset.scene_keys(), on_named, strict=True):
        by_scene.setdefault(key, []).append(hit)
    switched = [all(hits) for hits in by_scene.values() if len(hits) > 1]
    return {"attention_on_named_fraction": float(np.mean(on_named)),
            "attention_switch_fraction": float(np.mean(switched)) if switched else None}


def heatmap_entropy(predictions: list[Prediction], present: np.ndarray,
                    per_target: bool = True) -> float | None:
    """The median entropy [nats] of the heatmaps; None without heatmaps.

    ``present`` (N, q) marks the targets in each image. Where ``per_target`` and an image has
    a heatmap per target, heatmap k is target k's and counts only while that target is
    present; otherwise (16 key points for 1-3 targets) each of the image's heatmaps counts.
    """
    entropies = []
    for prediction, shown in zip(predictions, present, strict=True):
        if prediction.heatmaps is None:
            continue
        maps = prediction.heatmaps  # (p, h, w)
        if per_target and len(maps) == len(shown):
            maps = maps[shown]  # the present targets' own maps
        entropies += [float(-(m * np.log(np.clip(m, 1e-12, None))).sum()) for m in maps]
    return float(np.median(entropies)) if entropies else None


def per_condition(errors: np.ndarray, present: np.ndarray, dataset: Dataset
                  ) -> dict[str, float] | None:
    """Mean of ``errors`` (N, q) over the present targets of each condition's images."""
    meta = dataset.metadata
    if meta.condition_kind is ConditionKind.NONE:
        return None
    chosen = np.array(dataset.condition_names())  # (N,)
    return {value: float(errors[(chosen == value)[:, None] & present].mean())
            for value in meta.condition_choices
            if ((chosen == value)[:, None] & present).any()}


def type_accuracy(predictions: list[Prediction], dataset: Dataset) -> float | None:
    """The fraction of targets of known type that ``predictions`` state right; None: no type.

    Targets not in their image are left out. None where no prediction states a type or no
    scene record names one.
    """
    if not any(t.object_type is not None for p in predictions for t in p.targets):
        return None
    right = [stated.object_type == true
             for p, row, shown in zip(predictions, dataset.target_types(),
                                      dataset.target_present(), strict=True)
             for stated, true, seen in zip(p.targets, row, shown, strict=True)
             if true is not None and seen]
    return float(np.mean(right)) if right else None


def label_mean_error_cm(train: Dataset, test: Dataset) -> float:
    """The mean position error [cm] on ``test`` of a reference that never looks at the image.

    It predicts, for each target index, the mean training position, taken over the training
    samples with the same condition where the task has one (a side or type condition tells it
    which half of the table or which object's spread to expect). A model whose error is near
    this one has learned the label distribution, not where the object is.

    Raises:
        InvalidInputError: The two datasets differ in scene, task or targets, or ``train`` is
            empty.

    """
    for field in ("scene", "task", "targets", "condition_choices"):
        ours, theirs = getattr(train.metadata, field), getattr(test.metadata, field)
        if ours != theirs:
            raise InvalidInputError(f"test {field}", theirs, f"the training set's {ours!r}")
    if len(train) == 0:
        raise InvalidInputError("train", "0 samples", "at least one sample")
    train_m = split_label(train.labels.astype(np.float64)).position_m  # (N, q, 3)
    test_m = split_label(test.labels.astype(np.float64)).position_m
    if train.metadata.condition_kind is ConditionKind.NONE:
        predicted_m = np.broadcast_to(train_m.mean(axis=0), test_m.shape)
    else:
        train_choice = np.array(train.condition_names())
        overall_m = train_m.mean(axis=0)
        predicted_m = np.stack([
            train_m[train_choice == c].mean(axis=0) if np.any(train_choice == c) else overall_m
            for c in test.condition_names()])
    return float(np.linalg.norm(predicted_m - test_m, axis=-1).mean() * 100)
