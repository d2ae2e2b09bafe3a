"""The Key Point baselines with kqv's help: ray readout, point loss, per-image scaling, mirror."""

import json
from dataclasses import asdict, replace

import numpy as np
import pytest
import torch
from user_models import CAMERA, spec, synthetic_dataset

from perception.interface import InvalidInputError, LabelKind
from perception.labels import check_rotations
from perception.learning.checkpoint import config_sha256
from perception.learning.mirror import MIRROR_FLAG
from perception.learning.torch_pieces import (
    LabelScaler,
    coordinate_grid,
    images_to_tensor,
    pixels_to_normalised,
    spatial_expectation,
)
from perception.learning.train import Batch, TrainConfig
from perception.models.baselines import BaselineConfig
from perception.models.dsae import DsaeConfig, DsaeModel
from perception.models.keypoint import KeypointConfig, KeypointModel
from perception.models.keypoint_ray import KeypointRayNet
from perception.registry import PRESETS, new_model

SHORT = TrainConfig(steps=6, batch_size=4, threads=1)
HELPED = ("keypoint-16-helped", "keypoint-min-helped")
# A default KeypointModel's weights (q = 1, position labels), as they were before the help.
DEFAULT_WEIGHTS = {
    "encoder.log_temperature": (), "encoder.fcn.0.weight": (16, 3, 5, 5),
    "encoder.fcn.0.bias": (16,), "encoder.fcn.2.weight": (32, 16, 3, 3),
    "encoder.fcn.2.bias": (32,), "encoder.fcn.4.weight": (16, 32, 3, 3),
    "encoder.fcn.4.bias": (16,), "head.mlp.0.weight": (64, 32), "head.mlp.0.bias": (64,),
    "head.mlp.2.weight": (64, 64), "head.mlp.2.bias": (64,), "head.mlp.4.weight": (3, 64),
    "head.mlp.4.bias": (3,),
}


def grasps(size=8, targets=1, conditioned=False, seed=0, kind=LabelKind.GRASP_POSE):
    return synthetic_dataset(size, targets, kind, conditioned, seed, camera=CAMERA)


def positions_of(model, dataset):
    return np.array([[t.position_m for t in p.targets]
                     for p in model.predict_batch(dataset.images, dataset.conditions)])


def test_the_defaults_keep_the_papers_keypoint_models():
    model = KeypointModel(spec())
    shapes = {name: tuple(w.shape) for name, w in model.network.state_dict().items()}
    assert shapes == DEFAULT_WEIGHTS
    assert type(model.network).__name__ == "BaselineNet" and not model.network.per_image
    built = KeypointModel(spec(), KeypointConfig()).network.state_dict()
    assert all(torch.equal(built[name], w) for name, w in model.network.state_dict().items())
    config = new_model("keypoint-16", synthetic_dataset(1)).config
    assert PRESETS["keypoint-16"] == ("keypoint", {"points": 16})
    assert asdict(config) == {"head_width": 64, "rotation_loss_weight": 0.1,
                              "input_norm": "fixed", "mirror": False, "seed": 0, "points": 16,
                              "channels": (16, 32), "temperature": 1.0, "readout": "mlp",
                              "point_loss_weight": 0.0}


def test_a_checkpoint_from_before_the_help_loads_as_it_was(tmp_path):
    dataset = synthetic_dataset(4, seed=2)
    model = new_model("keypoint-min", dataset)
    model.fit(dataset, SHORT, progress=False)
    folder = model.save(tmp_path / "old")
    config = json.loads((folder / "config.json").read_text())
    for field in ("readout", "point_loss_weight", "input_norm", "mirror"):
        del config["hyperparameters"][field]  # an older checkpoint never had them
    config["config_sha256"] = config_sha256(config)  # as that gva saved it
    (folder / "config.json").write_text(json.dumps(config))
    np.testing.assert_array_equal(positions_of(KeypointModel.load(folder), dataset),
                                  positions_of(model, dataset))


@pytest.mark.parametrize(("name", "targets", "conditioned", "kind"), [
    ("keypoint-16-helped", 2, False, LabelKind.GRASP_POSE),
    ("keypoint-min-helped", 2, False, LabelKind.GRASP_POSE),
    ("keypoint-16-helped", 1, True, LabelKind.GRASP_POSE),
    ("keypoint-min-helped", 1, False, LabelKind.POSITION)])  # as kqv's ray reads positions
def test_the_helped_presets_train_predict_and_survive_a_checkpoint(tmp_path, name, targets,
                                                                   conditioned, kind):
    dataset = grasps(6, targets, conditioned, seed=1, kind=kind)
    model = new_model(name, dataset)
    network = model.network
    assert isinstance(network, KeypointRayNet) and network.per_image
    assert (network.selection.mlp is None) == (name == "keypoint-min-helped")
    model.fit(dataset, SHORT, progress=False)
    assert model._mirror is None  # mirror None: the synthetic collector allows none
    predictions = model.predict_batch(dataset.images, dataset.conditions)
    q = dataset.metadata.targets
    for prediction in predictions:
        assert prediction.attention_px.shape == (q, 2)  # one point per target, as read
        assert prediction.heatmaps is not None and prediction.heatmaps.shape[0] == q
        np.testing.assert_allclose(prediction.heatmaps.sum(axis=(1, 2)), 1.0, rtol=1e-5)
        if kind is LabelKind.GRASP_POSE:
            check_rotations("predicted rotation", np.array([t.rotation for t in
                                                            prediction.targets]))
        else:
            assert all(t.rotation is None for t in prediction.targets)
    again = KeypointModel.load(model.save(tmp_path / name))
    assert again.config == model.config and again.network.scaler == model.scaler
    np.testing.assert_array_equal(positions_of(again, dataset), positions_of(model, dataset))


def test_the_selection_head_reads_each_target_from_a_mean_of_the_points():
    model = new_model("keypoint-16-helped", grasps(2, targets=2))
    network = model.network
    assert isinstance(network, KeypointRayNet)
    images = torch.rand(2, 3, 64, 64, generator=torch.Generator().manual_seed(0))
    encoding = network.encode(images)
    weights = network.selection(encoding.features, torch.zeros(2, 0))  # (B, q, K)
    assert weights.shape == (2, 2, 16)
    torch.testing.assert_close(weights.sum(-1), torch.ones(2, 2))
    points, heatmaps = network.targets_points(encoding, torch.zeros(2, 0))
    torch.testing.assert_close(points, weights @ encoding.points)
    grid = coordinate_grid(*heatmaps.shape[-2:], images.device)  # (2, h, w)
    torch.testing.assert_close(spatial_expectation(heatmaps, grid), points)  # the mixture's


@pytest.mark.slow
def test_keypoint_min_helped_learns_positions_and_the_point_loss_pulls_its_points():
    train = grasps(24, seed=3)
    test = grasps(16, seed=4)
    seen = pixels_to_normalised(torch.tensor(CAMERA.project(test.labels[:, 0, :3].astype(
        float))), 64, 64).numpy()  # (N, 2) where the camera sees each square
    point_error, position_error_m = {}, {}
    for weight in (10.0, 0.0):
        model = new_model("keypoint-min-helped", train, point_loss_weight=weight)
        model.fit(train, TrainConfig(steps=300, batch_size=8, threads=1), progress=False)
        predictions = model.predict_batch(test.images, test.conditions)
        points = pixels_to_normalised(torch.tensor(np.array([p.attention_px[0] for p in
                                                             predictions])), 64, 64).numpy()
        point_error[weight] = np.median(np.linalg.norm(points - seen, axis=1))
        predicted = np.array([p.targets[0].position_m for p in predictions])
        position_error_m[weight] = np.linalg.norm(predicted - test.labels[:, 0, :3], axis=1)
    # the squares span 20 cm; 1 px is about 0.5 cm (here about 1 cm: the point's px and the
    # head's height and offset)
    assert np.median(position_error_m[10.0]) < 0.02, position_error_m[10.0]
    assert point_error[10.0] < 0.6 * point_error[0.0], point_error


def test_the_point_loss_is_kqvs_on_each_targets_point():
    dataset = grasps(6, targets=2, seed=5)
    batch = Batch(images_to_tensor(dataset.images), torch.as_tensor(dataset.conditions),
                  torch.as_tensor(dataset.labels))
    losses = {}
    for weight in (0.0, 2.0):
        model = new_model("keypoint-16-helped", dataset, point_loss_weight=weight)
        model.scaler = model.network.scaler = LabelScaler.fit(dataset.labels[..., :3])
        losses[weight] = model.batch_loss(batch).item()
        points = model.network(batch.images, batch.conditions).points.detach().double().numpy()
    seen = pixels_to_normalised(torch.tensor(CAMERA.project(dataset.labels[..., :3].reshape(
        -1, 3).astype(float))), 64, 64).numpy().reshape(6, 2, 2)  # (N, q, 2)
    distance = np.square(points - seen).sum(axis=-1).mean()
    assert losses[2.0] - losses[0.0] == pytest.approx(2.0 * distance, rel=1e-4)


def test_bad_settings_name_field_value_and_what_is_allowed():
    with pytest.raises(InvalidInputError, match=r"readout = 'rays' .* one of 'mlp', 'ray'"):
        KeypointConfig(readout="rays")
    with pytest.raises(InvalidInputError, match=r"point_loss_weight = -1.0 .* >= 0"):
        KeypointConfig(readout="ray", point_loss_weight=-1.0)
    with pytest.raises(InvalidInputError, match=r"point_loss_weight = 1.0 .* 0 with readout "
                                                r"'mlp'"):
        KeypointConfig(point_loss_weight=1.0)
    with pytest.raises(InvalidInputError, match=r"readout = 'ray' is not allowed: 'mlp' for "
                                                r"a dataset that records no camera"):
        new_model("keypoint-min-helped", synthetic_dataset(2))  # positions, no camera
    with pytest.raises(InvalidInputError, match=r"readout = 'ray' .* records no camera"):
        KeypointModel(spec(kind=LabelKind.GRASP_POSE), KeypointConfig(readout="ray"))
    with pytest.raises(InvalidInputError, match=r"readout = 'ray' .* 'mlp' for dsae"):
        DsaeModel(replace(spec(kind=LabelKind.GRASP_POSE), camera=CAMERA),
                  DsaeConfig(readout="ray"))
    with pytest.raises(InvalidInputError, match=r"input_norm = 'auto' .* one of 'fixed', "
                                                r"'per-image'"):
        BaselineConfig(input_norm="auto")
    with pytest.raises(InvalidInputError, match=r"mirror = 'yes' .* None, True or False"):
        BaselineConfig(mirror="yes")
    model = new_model("fcn", synthetic_dataset(2), mirror=True)
    with pytest.raises(InvalidInputError, match=r"mirror = True .* records no camera"):
        model.fit(synthetic_dataset(2), SHORT, progress=False)


@pytest.mark.parametrize("name", ["keypoint-16", "dsae-16", "conv-ae", "fcn"])
def test_every_baseline_scales_each_image_and_mirrors_where_told(name):
    dataset = synthetic_dataset(4, seed=7, camera=CAMERA)
    flagged = replace(dataset, metadata=replace(dataset.metadata,
                                                extra={MIRROR_FLAG: True}))
    model = new_model(name, flagged, input_norm="per-image", mirror=None)
    images = torch.rand(2, 3, 64, 64, generator=torch.Generator().manual_seed(1))
    conditions = torch.zeros(2, 0)
    with torch.no_grad():  # a dimmer room reads the same
        dim, bright = (model.network(images * scale, conditions).positions
                       for scale in (0.5, 1.0))
    torch.testing.assert_close(dim, bright, atol=1e-4, rtol=1e-4)
    plain = images_to_tensor(dataset.images)
    seen = _fit_seeing(model, flagged)
    assert model._mirror is not None  # the collector allows it
    assert 0 < sum(any(torch.equal(image, p) for p in plain) for image in seen) < len(seen)
    fixed = new_model(name, dataset)
    seen = _fit_seeing(fixed, dataset)
    assert fixed._mirror is None and not fixed.network.per_image
    assert all(any(torch.equal(image, p) for p in plain) for image in seen)  # none mirrored


def _fit_seeing(model, dataset) -> torch.Tensor:
    """Fits ``model`` (no photometric augmentation); every image its network was shown."""
    seen = []
    network = model.network
    for name in ("forward", "encode", "reconstruction_loss"):  # where images enter the network
        if hasattr(network, name):
            original = getattr(network, name)

            def recording(images, *rest, _original=original, **kw):
                seen.append(images.detach().clone())
                return _original(images, *rest, **kw)

            setattr(network, name, recording)
    model.fit(dataset, replace(SHORT, augment=False), progress=False)
    return torch.cat(seen)  # (N, 3, H, W): the batches as the network saw them


def test_fcn_helped_gets_the_help_a_model_without_points_can_take():
    dataset = synthetic_dataset(4, seed=7, camera=CAMERA)
    flagged = replace(dataset, metadata=replace(dataset.metadata, extra={MIRROR_FLAG: True}))
    model = new_model("fcn-helped", flagged)
    assert (model.config.input_norm, model.config.mirror) == ("per-image", None)
    model.fit(flagged, SHORT, progress=False)
    assert model._mirror is not None and model.network.per_image
