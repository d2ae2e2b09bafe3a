"""A user's own models (found by the registry as ``"user_models:Class"``), tiny synthetic data,
and the small helpers the model tests share (a spec, a camera, a typed dataset).

The synthetic scenes: coloured squares on a wood-coloured background; square ``k`` has type
``TYPES[k]`` and its label is an affine function of where it lies in the image, so a model that
finds the square can predict the label.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from typing import Any

import numpy as np

from perception.camera import PinholeCamera, RgbdFrame
from perception.interface import (
    NO_CONDITION,
    PICTURE_PX,
    Condition,
    ConditionKind,
    LabelKind,
    ModelInput,
    PerceptionModel,
    Prediction,
    Target,
)
from perception.labels import label_vector
from perception.learning.data import Dataset, DatasetMetadata
from perception.learning.learnable import ModelSpec
from perception.learning.torch_pieces import LabelScaler
from perception.models.kqv import KqvModel

TYPES = ("red", "green", "blue")
COLOURS = np.array([[220, 30, 30], [30, 170, 60], [40, 60, 220]], dtype=np.uint8)
BACKGROUND = np.array([200, 170, 130], dtype=np.uint8)
SQUARE_PX = 8
DOWN = np.diag([1.0, -1.0, -1.0])  # a TCP pointing straight down
CAMERA = PinholeCamera((0.0, 0.0, 0.6), (0.45, 0.0, 0.0), (0.0, 0.0, 1.0), 40.0, None, 64, 64)
"""A camera above a synthetic table, for grasp datasets a ray readout can read."""


class CentreModel(PerceptionModel):
    """Always points at the table centre: the smallest model the interface allows."""

    name = "centre"
    label_kind = LabelKind.POSITION

    def predict(self, image: np.ndarray, condition: Condition = NO_CONDITION) -> Prediction:
        return Prediction(targets=(Target(position_m=np.array([0.4, 0.0, 0.0])),))


class MyKqv(KqvModel):
    """A user's variant of the KQV model, under a name of its own (not registered)."""

    name = "my-kqv"


class BlindKqv(KqvModel):
    """A KQV model that hides its attention, as models without attention points (fcn) predict."""

    name = "blind-kqv"

    def to_predictions(self, out, conditions):
        return [Prediction(p.targets) for p in super().to_predictions(out, conditions)]


class FixedGrasp(PerceptionModel):
    """A model without weights for pick trials: a top-down grasp at the workspace's centre."""

    name = "fixed-grasp"
    label_kind = LabelKind.GRASP_POSE

    def predict(self, image: np.ndarray, condition: Condition = NO_CONDITION) -> Prediction:
        return Prediction(targets=(Target(np.array([0.47, 0.0, 0.03]), DOWN.copy()),),
                          attention_px=np.array([[64.0, 70.0]]))


class NotAModel:
    """A class that is no PerceptionModel."""


def spec(q=1, kind=LabelKind.POSITION, choices=(), px=64):
    """A synthetic task's model spec: q targets, a type condition when ``choices``."""
    return ModelSpec(scene="synthetic", task="t", label_kind=kind, targets=q,
                     condition_kind=ConditionKind.OBJECT_TYPE if choices else ConditionKind.NONE,
                     condition_choices=choices, image_height_px=px, image_width_px=px)


def trained_scaler(model):
    """``model`` with a label scaler, as a fit would leave it."""
    model.scaler = LabelScaler((0.4, 0.0, 0.02), 0.2)
    return model


def rot_z(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def synthetic_dataset(size: int = 8, targets: int = 1, kind: LabelKind = LabelKind.POSITION,
                      conditioned: bool = False, seed: int = 0, image_px: int = 64,
                      camera: PinholeCamera | None = None) -> Dataset:
    """``size`` scenes of coloured squares (``targets`` of them, or all three when conditioned).

    Labels: x = 0.3 + 0.3 v/H, y = 0.2 - 0.4 u/W [m] of the square's centre, z = 0.02 per type
    index; grasp labels add a top-down TCP turned by a random yaw. With a ``camera`` (recorded
    in the metadata), x and y are instead where the ray through the square's centre meets the
    plane z = 0.02 per type index: the camera sees the squares lying at their heights.
    """
    rng = np.random.default_rng(seed)
    shown = len(TYPES) if conditioned else targets
    images = np.broadcast_to(BACKGROUND, (size, image_px, image_px, 3)).copy()
    labels, conditions, scenes = [], [], []
    for n in range(size):
        corners = _spaced_corners(rng, shown, image_px)
        chosen = int(rng.integers(len(TYPES))) if conditioned else None
        wanted = [chosen] if chosen is not None else list(range(targets))
        positions, rotations = [], []
        for k, (v, u) in enumerate(corners):
            images[n, v:v + SQUARE_PX, u:u + SQUARE_PX] = COLOURS[k]
            if k in wanted:
                centre_v, centre_u = v + SQUARE_PX / 2, u + SQUARE_PX / 2
                positions.append([0.3 + 0.3 * centre_v / image_px,
                                  0.2 - 0.4 * centre_u / image_px, 0.02 * k])
                if camera is not None:  # pixel centres are integers: the middle is at - 0.5
                    ray = camera.rays(np.array([[centre_u - 0.5, centre_v - 0.5]]))[0]
                    origin = np.asarray(camera.position_m)
                    positions[-1] = list(origin + ray * (0.02 * k - origin[2]) / ray[2])
                rotations.append(rot_z(rng.uniform(-np.pi, np.pi)) @ DOWN)
        rotation = np.array(rotations) if kind is LabelKind.GRASP_POSE else None
        labels.append(label_vector(np.array(positions), rotation))
        conditions.append(np.eye(len(TYPES), dtype=np.float32)[chosen] if conditioned
                          else np.zeros(0, np.float32))
        scenes.append({"index": n, "corners_px": [list(map(int, c)) for c in corners]})
    metadata = DatasetMetadata(
        scene="synthetic", task="selected-type" if conditioned else "multiple", size=size,
        seed=seed, image_height_px=image_px, image_width_px=image_px, label_kind=kind,
        targets=1 if conditioned else targets,
        condition_kind=ConditionKind.OBJECT_TYPE if conditioned else ConditionKind.NONE,
        condition_choices=TYPES if conditioned else (),
        camera={} if camera is None else camera.to_json())
    return Dataset(metadata, images, np.array(conditions, dtype=np.float32).reshape(size, -1),
                   np.array(labels, dtype=np.float32), tuple(scenes))


def _spaced_corners(rng: np.random.Generator, count: int, image_px: int) -> list[tuple[int, int]]:
    """Top-left corners (v, u) of ``count`` squares that do not touch."""
    corners: list[tuple[int, int]] = []
    while len(corners) < count:
        v, u = (int(c) for c in rng.integers(2, image_px - SQUARE_PX - 2, size=2))
        if all(max(abs(v - a), abs(u - b)) > SQUARE_PX + 2 for a, b in corners):
            corners.append((v, u))
    return corners


def typed_dataset(size, seed, targets=1):
    """Grasp scenes seen by ``CAMERA`` whose squares each take a random type (its colour).

    The scene records name each target's type and the metadata the vocabulary, as the
    simulator's collector writes them.
    """
    base = synthetic_dataset(size, targets=targets, kind=LabelKind.GRASP_POSE, seed=seed,
                             camera=CAMERA)
    types = np.random.default_rng([seed, 1]).integers(len(TYPES), size=(size, targets))
    images = base.images.copy()
    for n in range(size):
        for k in range(targets):
            images[n][(base.images[n] == COLOURS[k]).all(axis=-1)] = COLOURS[types[n, k]]
    scenes = tuple({"objects": [{"type": TYPES[t]} for t in row], "targets": list(range(targets))}
                   for row in types)
    return Dataset(replace(base.metadata, extra={"object_types": list(TYPES)}), images,
                   base.conditions, base.labels, scenes)


class Misbehaving(FixedGrasp):
    """A model for pick trials that misbehaves in the way its subclass's ``wrong`` says."""

    name = "misbehaving"

    def predict(self, image: np.ndarray, condition: Condition = NO_CONDITION) -> Prediction:
        return self.wrong(super().predict(image, condition))

    def wrong(self, right: Prediction) -> Any:
        return right


class Raises(Misbehaving):
    def wrong(self, right: Prediction) -> Any:
        raise RuntimeError("the detector lost its calibration")


class ReturnsNone(Misbehaving):
    def wrong(self, right: Prediction) -> Any:
        return None


class NanPosition(Misbehaving):
    """Builds its Target with a NaN: the Target refuses it, inside predict."""

    def wrong(self, right: Prediction) -> Any:
        return Prediction((Target(np.array([0.47, np.nan, 0.03]), DOWN.copy()),))


class InfAfterwards(Misbehaving):
    """Writes an infinity into a Target's array after building it: the trial's check sees it."""

    def wrong(self, right: Prediction) -> Any:
        right.targets[0].position_m[2] = np.inf
        return right


class TwoTargets(Misbehaving):
    def wrong(self, right: Prediction) -> Any:
        return Prediction(right.targets * 2)


class NotARotation(Misbehaving):
    def wrong(self, right: Prediction) -> Any:
        return Prediction((Target(right.targets[0].position_m, 2.0 * DOWN),))


class ExitsOnSecondCall(Misbehaving):
    """Calls ``sys.exit`` on its second prediction: the run stops, the first trial is kept."""

    calls = 0

    def wrong(self, right: Prediction) -> Any:
        ExitsOnSecondCall.calls += 1
        if ExitsOnSecondCall.calls == 2:
            sys.exit(3)
        return right


class InterruptedOnSecondCall(Misbehaving):
    """Ctrl-C during its second prediction."""

    calls = 0

    def wrong(self, right: Prediction) -> Any:
        InterruptedOnSecondCall.calls += 1
        if InterruptedOnSecondCall.calls == 2:
            raise KeyboardInterrupt
        return right


class Nameless(PerceptionModel):
    """A model class without a name."""

    label_kind = LabelKind.GRASP_POSE


class BrokenConstructor(FixedGrasp):
    def __init__(self) -> None:
        raise FileNotFoundError("weights.bin")


class DepthWithoutFrame(FixedGrasp):
    """Declares depth, but implements only predict(image, ...): it would never get any."""

    inputs = frozenset({ModelInput.RGB, ModelInput.DEPTH})


class StringInputs(FixedGrasp):
    inputs = frozenset({"rgb"})  # type: ignore[assignment]


class DepthReader(FixedGrasp):
    """Reads the frame: grasps the highest point the depth image sees, top-down."""

    name = "depth-reader"
    inputs = frozenset(ModelInput)

    def predict_frame(self, frame: RgbdFrame, condition: Condition = NO_CONDITION
                      ) -> Prediction:
        points = frame.points_world().reshape(-1, 3)
        highest = points[np.nanargmax(points[:, 2])]
        return Prediction((Target(highest, DOWN.copy()),))


def given_as(dataset: Dataset, kind: ConditionKind, rows: np.ndarray,
             queries: list[str | None]) -> Dataset:
    """A conditioned synthetic dataset whose conditions are given as ``kind`` (text, image).

    ``rows`` (N, C) are the vectors a model reads (embeddings, picture pixels); each scene
    record keeps the named type under ``"condition"`` and ``queries[n]`` (a sentence) under
    ``"query"``, as the simulator's collector writes them.
    """
    names = [TYPES[int(i)] for i in dataset.conditions.argmax(axis=1)]
    scenes = tuple(record | {"condition": {"kind": "object_type", "value": name}}
                   | ({} if query is None else {"query": {"kind": kind.value, "value": query}})
                   for record, name, query in zip(dataset.scenes, names, queries, strict=True))
    metadata = replace(dataset.metadata, condition_kind=kind,  # the scene's vocabulary, as
                       extra=dataset.metadata.extra | {"object_types": list(TYPES)})  # collected
    return Dataset(metadata, dataset.images, rows.astype(np.float32), dataset.labels, scenes)


def colour_picture(k: int, rng: np.random.Generator) -> np.ndarray:
    """A (32, 32, 3) picture of type ``k``: its colour, a little off, on a noisy background."""
    picture = rng.integers(90, 160, (PICTURE_PX, PICTURE_PX, 3)).astype(np.int16)
    v, u = (int(c) for c in rng.integers(4, 12, size=2))
    shade = COLOURS[k].astype(np.int16) + rng.integers(-25, 26, 3)
    picture[v:v + 16, u:u + 16] = shade
    return np.clip(picture, 0, 255).astype(np.uint8)
