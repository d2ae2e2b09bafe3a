"""kqv's range readout: the point on the ray lies where the frame's depth says, not where a head
learned it might (issue 75: a bottle head whose learned range was 2-4 cm off at one seed)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch
from user_models import CAMERA, SQUARE_PX, spec, synthetic_dataset, trained_scaler

from perception.interface import InvalidInputError, LabelKind, ModelInput
from perception.labels import label_vector
from perception.learning.data import Dataset
from perception.learning.torch_pieces import pixels_to_normalised
from perception.learning.train import TrainConfig
from perception.models.kqv import KqvConfig, KqvModel
from perception.models.readout import RANGE_MIN_WEIGHT, attended_range

ORIGIN = np.asarray(CAMERA.position_m)


def _depth_of(pixels: np.ndarray, height_m: float) -> np.ndarray:
    """Depth along the optical axis of where pixels' rays (N, 2) meet the plane z = height."""
    rays = CAMERA.rays(pixels)  # a unit of each is a metre along the optical axis
    return (height_m - ORIGIN[2]) / rays[:, 2]


def _heights_unseen(size: int, seed: int) -> Dataset:
    """Grasp scenes of one square whose height (0-10 cm) shows in the depth alone: its colour and
    size are the same at every height, so no head can learn the range from how it looks."""
    base = synthetic_dataset(size, kind=LabelKind.GRASP_POSE, seed=seed, camera=CAMERA)
    rng = np.random.default_rng(seed + 100)
    v, u = np.mgrid[0:64, 0:64]
    every = np.stack([u.ravel(), v.ravel()], axis=1).astype(float)
    table = _depth_of(every, 0.0).reshape(64, 64).astype(np.float32)
    depths = np.broadcast_to(table, (size, 64, 64)).copy()
    labels = base.labels.copy()
    for n, scene in enumerate(base.scenes):
        (top, left), = scene["corners_px"]
        height_m = float(rng.uniform(0.0, 0.1))
        square = (slice(top, top + SQUARE_PX), slice(left, left + SQUARE_PX))
        depths[n][square] = _depth_of(every.reshape(64, 64, 2)[square].reshape(-1, 2),
                                      height_m).reshape(SQUARE_PX, SQUARE_PX)
        centre = np.array([[left + SQUARE_PX / 2 - 0.5, top + SQUARE_PX / 2 - 0.5]])
        position = ORIGIN + CAMERA.rays(centre)[0] * _depth_of(centre, height_m)[0]
        labels[n, 0] = label_vector(position[None], labels[n, 0, 3:].reshape(1, 3, 3))[0]
    return replace(base, labels=labels, depths_m=depths)


@pytest.mark.slow
def test_the_range_readout_reads_heights_only_the_depth_shows():
    train, test = _heights_unseen(32, seed=3), _heights_unseen(16, seed=4)
    errors = {}
    for readout in ("ray", "range"):
        model = KqvModel.for_dataset(train, KqvConfig(starts=1, warmup_steps=100, seed=1,
                                                      readout=readout))
        model.fit(train, TrainConfig(steps=300, batch_size=8, threads=1), progress=False)
        predicted = np.array([p.targets[0].position_m for p in model.predict_batch(
            test.images, test.conditions, test.depths_m)])
        errors[readout] = np.median(np.linalg.norm(predicted - test.labels[:, 0, :3], axis=1))
    assert errors["range"] < 0.01 < 0.02 < errors["ray"], errors


def test_a_measured_range_places_the_point_there_and_a_hole_falls_back_to_the_height():
    model = trained_scaler(KqvModel(replace(spec(kind=LabelKind.GRASP_POSE), camera=CAMERA),
                                    KqvConfig(readout="range")))
    assert model.inputs == frozenset({ModelInput.RGB, ModelInput.DEPTH, ModelInput.CAMERA})
    scaler, rays = model.scaler, model.network.rays
    pixel = np.array([[20.0, 41.0]])
    coords = pixels_to_normalised(torch.tensor(pixel, dtype=torch.float32), 64, 64)[None]
    on_table = ORIGIN + CAMERA.rays(pixel)[0] * _depth_of(pixel, 0.0)[0]
    raised = ORIGIN + CAMERA.rays(pixel)[0] * _depth_of(pixel, 0.07)[0]
    out = torch.tensor([[[(0.0 - scaler.centre_m[2]) / scaler.scale_m, 0.0, 0.0, 0.0]]])
    measured = torch.tensor([[float(_depth_of(pixel, 0.07)[0]), float("nan")]])  # (2, 1)
    positions, _ = rays.read(coords.expand(2, -1, -1), out.expand(2, -1, -1), scaler,
                             range_m=measured.T)
    found = scaler.denormalise(positions)[:, 0].double().numpy()
    np.testing.assert_allclose(found[0], raised, atol=1e-5)  # the depth, not the head's 0 cm
    np.testing.assert_allclose(found[1], on_table, atol=1e-5)  # no depth: the head's height


def test_the_attended_range_weighs_measured_pixels_and_gives_up_on_holes():
    depth = torch.full((1, 4, 4), 0.5)
    depth[0, :2, :2] = torch.tensor([[0.4, 0.0], [0.4, float("inf")]])  # two holes in cell 0
    heatmaps = torch.zeros(1, 3, 2, 2)
    heatmaps[0, 0, 0, 0] = 1.0  # on cell 0: its two measured pixels
    heatmaps[0, 1, 0, 0] = heatmaps[0, 1, 1, 1] = 0.5  # half on cell 0, half on the 0.5 m
    heatmaps[0, 2, 0, 0], heatmaps[0, 2, 1, 1] = 0.9, 0.1  # mostly on a cell half holes
    got = attended_range(heatmaps, depth)[0]
    assert got[0].item() == pytest.approx(0.4)
    assert got[1].item() == pytest.approx((0.5 * 0.5 * 0.4 + 0.5 * 0.5) / (0.5 * 0.5 + 0.5))
    weight = 0.9 * 0.5 + 0.1  # measured share under head 2
    assert (weight >= RANGE_MIN_WEIGHT) == bool(torch.isfinite(got[2]))
    empty = torch.zeros(1, 4, 4)
    assert torch.isnan(attended_range(heatmaps, empty)).all()


def test_the_range_readout_refuses_what_has_no_depth():
    data = synthetic_dataset(4, kind=LabelKind.GRASP_POSE, seed=0, camera=CAMERA)
    model = KqvModel.for_dataset(data, KqvConfig(readout="range"))
    with pytest.raises(InvalidInputError, match=r"readout = 'range' is not allowed: 'ray', 'mlp'"):
        model.fit(data, TrainConfig(steps=1), progress=False)
    with pytest.raises(InvalidInputError, match=r"depths_m = None .* readout = 'range'"):
        model.predict_batch(data.images, data.conditions)
    with pytest.raises(InvalidInputError, match=r"readout = 'depth' is not allowed"):
        KqvConfig(readout="depth")


D435 = {"sensor": "d435"}  # a dataset's record of a depth sensor's images (ModelSpec.sensor)


def test_the_default_reads_the_range_through_a_depth_sensor_and_the_ray_through_the_ideal_camera(
        tmp_path):
    """``auto-range`` (issue 75): range for grasp poses seen through the D435, ray through the
    ideal camera (its runs read as they always did), the MLP for positions; ``auto`` keeps the
    choice it always made, so a checkpoint that saved it loads as it was trained."""
    grasp = replace(spec(kind=LabelKind.GRASP_POSE), camera=CAMERA)
    assert KqvConfig().readout == "auto-range"
    assert KqvModel(replace(grasp, sensor=D435)).network.readout == "range"
    assert ModelInput.DEPTH in KqvModel(replace(grasp, sensor=D435)).inputs
    assert KqvModel(grasp).network.readout == "ray"
    assert KqvModel(replace(spec(), camera=CAMERA, sensor=D435)).network.readout == "mlp"
    assert KqvModel(replace(grasp, sensor=D435), KqvConfig(readout="auto")).network.readout \
        == "ray"
    saved = trained_scaler(KqvModel(replace(grasp, sensor=D435))).save(tmp_path / "range")
    assert KqvModel.load(saved).network.readout == "range"


def test_the_default_reads_the_ray_where_a_depth_sensors_dataset_kept_no_depth():
    data = synthetic_dataset(4, kind=LabelKind.GRASP_POSE, seed=0, camera=CAMERA)
    data = replace(data, metadata=replace(data.metadata, camera=data.metadata.camera | D435))
    model = KqvModel.for_dataset(data, KqvConfig(starts=1, seed=1))
    assert model.network.readout == "range"
    model.fit(data, TrainConfig(steps=2, batch_size=4, threads=1), progress=False)
    assert (model.network.readout, model.config.readout) == ("ray", "ray")
    assert ModelInput.DEPTH not in model.inputs
    assert len(model.predict_batch(data.images, data.conditions)) == 4
