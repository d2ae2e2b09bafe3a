from dataclasses import replace

import numpy as np
import pytest
import torch
from user_models import (
    BACKGROUND,
    CAMERA,
    COLOURS,
    TYPES,
    rot_z,
    spec,
    synthetic_dataset,
    trained_scaler,
)

from perception.interface import Condition, ConditionKind, InvalidInputError, LabelKind
from perception.labels import check_rotations
from perception.learning.learnable import ModelSpec
from perception.learning.torch_pieces import (
    LabelScaler,
    images_to_tensor,
    pixels_to_normalised,
)
from perception.learning.train import Batch, TrainConfig
from perception.models.kqv import KqvConfig, KqvModel


@pytest.mark.parametrize("q", [1, 3])
@pytest.mark.parametrize("kind", [LabelKind.POSITION, LabelKind.GRASP_POSE])
@pytest.mark.parametrize("choices", [(), TYPES])
def test_prediction_shapes(q, kind, choices):
    model = trained_scaler(KqvModel(spec(q, kind, choices), KqvConfig(seed=q)))
    assert model.label_kind is kind and model.name == "kqv"
    images = np.broadcast_to(BACKGROUND, (2, 64, 64, 3)).copy()
    conditions = np.eye(len(choices), dtype=np.float32)[[0, 2]] if choices else np.zeros((2, 0))
    predictions = model.predict_batch(images, conditions)
    condition = Condition(ConditionKind.OBJECT_TYPE, "blue", TYPES) if choices else Condition()
    predictions.append(model.predict(images[1], condition))
    for prediction in predictions:
        assert len(prediction.targets) == q
        assert prediction.attention_px.shape == (q, 2)
        assert prediction.heatmaps is not None and prediction.heatmaps.shape == (q, 16, 16)
        np.testing.assert_allclose(prediction.heatmaps.sum(axis=(1, 2)), 1.0, rtol=1e-5)
        for target in prediction.targets:
            assert target.position_m.shape == (3,)
            if kind is LabelKind.GRASP_POSE:
                check_rotations("rotation", target.rotation)
            else:
                assert target.rotation is None
    if choices:
        assert predictions[1].targets[0].object_type == "blue"
        # the same image under the same condition, one by one or batched
        np.testing.assert_allclose(predictions[2].targets[0].position_m,
                                   predictions[1].targets[0].position_m, atol=1e-6)


def test_replacing_the_query_moves_the_attention_point():
    model = trained_scaler(KqvModel(spec(), KqvConfig(seed=3)))
    image = np.broadcast_to(BACKGROUND, (64, 64, 3)).copy()
    image[8:16, 8:16] = COLOURS[0]  # a red square near the top left
    image[44:52, 40:48] = COLOURS[2]  # a blue one near the bottom right
    with torch.no_grad():
        from perception.learning.torch_pieces import images_to_tensor
        keys = model.network.key_net((images_to_tensor(image[None]) - 0.5) / 0.25)
    # Queries taken from the Key at each square: attention goes where the Query matches
    at_red, at_blue = keys[0, :, 3, 3].numpy(), keys[0, :, 12, 11].numpy()  # 16 x 16 cells
    points = model.attend(image[None], np.stack([at_red, at_blue])[None] * 5)["points_px"][0]
    assert np.linalg.norm(points[0] - [11.5, 11.5]) < 6
    assert np.linalg.norm(points[1] - [43.5, 47.5]) < 6
    # and predict_batch takes replaced Queries too: the learned one, then the blue one
    learned = model.queries(np.zeros((1, 0)))
    moved = model.predict_batch(image[None], np.zeros((1, 0)), queries=at_blue[None, None] * 5)[0]
    assert learned.shape == (1, 1, model.config.key_dim + 2)
    np.testing.assert_allclose(moved.attention_px[0], points[1], atol=1e-4)


def test_config_errors_name_field_value_and_allowed():
    with pytest.raises(InvalidInputError, match=r"stride = 3 is not allowed: one of None, 1, 2, 4"):
        KqvConfig(stride=3)
    with pytest.raises(InvalidInputError, match=r"query_mode = 'best' is not allowed: one of"):
        KqvConfig(query_mode="best")
    with pytest.raises(InvalidInputError, match=r"temperature = 0.0 is not allowed"):
        KqvConfig(temperature=0.0)
    with pytest.raises(InvalidInputError, match=r"channels = \(16,\) is not allowed: two integ"):
        KqvConfig(channels=(16,))
    with pytest.raises(InvalidInputError, match=r"warmup_steps = -1 is not allowed: an integer "
                                                 r">= 0"):
        KqvConfig(warmup_steps=-1)
    with pytest.raises(InvalidInputError, match=r"start_batch_size = 0 is not allowed: None or "):
        KqvConfig(start_batch_size=0)
    with pytest.raises(InvalidInputError, match=r"starts = 0 is not allowed: an integer >= 1"):
        KqvConfig(starts=0)
    with pytest.raises(InvalidInputError, match=r"warmup_temperature = nan is not allowed"):
        KqvConfig(warmup_temperature=float("nan"))
    with pytest.raises(InvalidInputError, match=r"similarity = 'l2' is not allowed"):
        KqvConfig(similarity="l2")
    with pytest.raises(InvalidInputError, match=r"query_mode = 'conditioned' is not allowed"):
        KqvModel(spec(), KqvConfig(query_mode="conditioned"))
    with pytest.raises(InvalidInputError, match=r"input_norm = 'auto-contrast' is not allowed: "
                                                 r"one of 'auto', 'fixed', 'per-image'"):
        KqvConfig(input_norm="auto-contrast")
    with pytest.raises(InvalidInputError, match=r"rotation = 'euler' is not allowed: one of "
                                                 r"'6d', 'axis-line'"):
        KqvConfig(rotation="euler")
    assert KqvConfig(channels=[8, 16]).channels == (8, 16)  # as JSON gives it back


@pytest.mark.parametrize(("kind", "per_image"), [(LabelKind.GRASP_POSE, True),
                                                 (LabelKind.POSITION, False)])
def test_per_image_scaling_reads_a_dimmed_scene_as_the_bright_one(kind, per_image):
    # PyBullet's brightness scales every pixel alike; "auto" standardises each image for
    # grasp labels (the robot's trials) and keeps the paper's fixed scaling for positions.
    dataset = synthetic_dataset(4, kind=kind, seed=6, camera=CAMERA)
    model = KqvModel.for_dataset(dataset, KqvConfig(seed=1))
    assert model.network.per_image is per_image
    dimmed = (dataset.images.astype(np.float64) * 0.5).round().astype(np.uint8)
    queries = model.queries(dataset.conditions)
    bright, dark = (model.attend(images, queries)["heatmaps"] for images in (dataset.images,
                                                                             dimmed))
    changed = np.abs(bright - dark).sum(axis=(-2, -1)).max()  # of 2: mass moved, worst map
    if per_image:
        assert changed < 0.02  # only rounding to uint8 differs
    else:
        assert changed > 0.1


def test_predict_refuses_wrong_images_and_conditions():
    model = trained_scaler(KqvModel(spec(choices=TYPES)))
    image = np.zeros((64, 64, 3), np.uint8)
    with pytest.raises(InvalidInputError, match=r"image = 'shape \(32, 32, 3\)'"):
        model.predict(np.zeros((32, 32, 3), np.uint8), Condition(ConditionKind.OBJECT_TYPE,
                                                                 "red", TYPES))
    with pytest.raises(InvalidInputError, match=r"condition = .*object_type condition over"):
        model.predict(image)
    with pytest.raises(InvalidInputError, match=r"queries = 'shape \(1, 2, 18\)'"):
        model.predict_batch(image[None], np.eye(3)[:1], queries=np.zeros((1, 2, 18)))
    untrained = KqvModel(spec())
    with pytest.raises(InvalidInputError, match=r"untrained"):
        untrained.predict(image)


def test_for_dataset_reads_the_spec_from_metadata():
    dataset = synthetic_dataset(size=2, targets=3, kind=LabelKind.GRASP_POSE)
    model = KqvModel.for_dataset(dataset)
    assert model.spec.targets == 3 and model.spec.label_dim == 12
    assert model.network.head_features  # grasp labels: the head reads a_feat
    assert not KqvModel.for_dataset(synthetic_dataset(size=2)).network.head_features


def test_conditioned_queries_start_as_the_base_query():
    model = KqvModel(spec(choices=TYPES))  # auto: conditioned + base for a conditioned task
    queries = model.queries(np.eye(3, dtype=np.float32))
    assert model.network.base_queries is not None and model.network.query_mlp is not None
    np.testing.assert_array_equal(queries[0], queries[1])
    np.testing.assert_array_equal(queries[0], queries[2])
    assert KqvModel(spec()).network.query_mlp is None  # no condition: Base Queries only


def test_side_conditions_get_their_own_queries():
    side = ModelSpec(scene="synthetic", task="t", label_kind=LabelKind.POSITION, targets=1,
                     condition_kind=ConditionKind.SIDE, condition_choices=("left", "right"),
                     image_height_px=64, image_width_px=64)
    model = KqvModel(side)  # auto: a side names a place among look-alikes, no shared Query
    assert model.network.base_queries is None and model.network.query_mlp is not None
    queries = model.queries(np.eye(2, dtype=np.float32))
    assert not np.allclose(queries[0], queries[1])  # the two sides start apart


@pytest.mark.parametrize("holdout", [0.25, 0.0])
def test_the_first_fit_keeps_the_start_best_on_held_out_scenes(monkeypatch, holdout):
    import perception.models.kqv as kqv

    dataset = synthetic_dataset(size=4)
    model = KqvModel.for_dataset(dataset, KqvConfig(starts=3, start_steps=3, warmup_steps=4,
                                                    start_holdout=holdout, start_batch_size=2))
    starts = []  # (network, temperature at its first step, final loss, steps, samples)
    batch_sizes = []
    scored = {}  # network id -> its held-out error [cm]
    real_train, real_evaluate = kqv.train, kqv.evaluate

    def recording_train(network, loss, data, config, *args, **kwargs):
        first = []
        original = model.batch_loss

        def noting(batch):
            loss_value = original(batch)
            first.append(network.temperature)
            return loss_value

        report = real_train(network, noting, data, config, *args, **kwargs)
        starts.append((network, first[0], report.final_loss, config.steps, len(data)))
        batch_sizes.append(config.batch_size)
        return report

    def recording_evaluate(scored_model, data):
        result = real_evaluate(scored_model, data)
        scored[id(scored_model.network)] = (result.mean_position_error_cm, len(data))
        return result

    monkeypatch.setattr(kqv, "train", recording_train)
    monkeypatch.setattr(kqv, "evaluate", recording_evaluate)
    report = model.fit(dataset, TrainConfig(steps=7, augment=False, threads=1), progress=False)
    assert [steps for *_, steps, _ in starts] == [3, 3, 3]
    assert batch_sizes == [2, 2, 2]  # KqvConfig.start_batch_size, not the training's 16
    assert [samples for *_, samples in starts] == [3 if holdout else 4] * 3
    assert len({id(network) for network, *_ in starts}) == 3  # three initialisations
    assert all(temperature == pytest.approx(0.3 - 0.05) for _, temperature, *_ in starts)
    if holdout:  # compared on the one scene none of them trained on
        assert {samples for _, samples in scored.values()} == {1} and len(scored) == 3
        best = min(starts, key=lambda start: scored[id(start[0])][0])[0]
    else:
        assert scored == {}
        best = min(starts, key=lambda start: start[2])[0]
    assert model.network is best
    assert report.steps == 7  # 3 of the kept start + the 4 it went on for
    assert model.network.temperature == 0.1
    kept = model.network
    model.fit(dataset, TrainConfig(steps=4, augment=False, threads=1), progress=False)
    assert model.network is kept and len(starts) == 3  # a later fit trains on, no new starts


def test_temperature_warms_up_over_the_first_steps_then_stays():
    dataset = synthetic_dataset(size=4)
    model = KqvModel.for_dataset(dataset, KqvConfig(warmup_temperature=0.5, warmup_steps=4,
                                                    temperature=0.1, starts=1))
    seen = []
    loss = model.batch_loss

    def recording(batch):
        result = loss(batch)
        seen.append(model.network.temperature)
        return result

    model.batch_loss = recording  # type: ignore[method-assign]
    model.fit(dataset, TrainConfig(steps=6, augment=False, threads=1), progress=False)
    np.testing.assert_allclose(seen, [0.4, 0.3, 0.2, 0.1, 0.1, 0.1])
    assert model.network.temperature == 0.1  # inference runs at the final temperature
    model.fit(dataset, TrainConfig(steps=1, augment=False, threads=1), progress=False)
    assert seen[-1] == pytest.approx(0.4)  # a new fit warms up again


# A camera above and behind the synthetic scenes, looking down at 53 degrees.


LENS = (-0.2, 0.05, 0.01, -0.01, 0.0)
"""A strong lens (the D435's colour lens is k1 = -0.024): a readout that ignored it is mm off."""


@pytest.mark.parametrize("lens", [None, LENS], ids=["pinhole", "distorted"])
def test_the_ray_readout_reads_a_point_where_its_ray_meets_the_height(lens):
    camera = CAMERA if lens is None else replace(CAMERA, distortion_k1_k2_p1_p2_k3=lens)
    model = trained_scaler(KqvModel(replace(spec(kind=LabelKind.GRASP_POSE), camera=camera)))
    network, scaler = model.network, model.scaler
    assert network.readout == "ray"
    ray = camera.rays(np.array([[6.0, 5.0]]))[0]  # near a corner, where a lens shows most
    point_m = np.asarray(camera.position_m) + ray * (0.05 - camera.position_m[2]) / ray[2]
    pixels = torch.tensor(camera.project(point_m[None]), dtype=torch.float32)  # (1, 2)
    if lens is not None:  # the lens moves the point by pixels: reading it as a pinhole fails
        assert np.abs(CAMERA.project(point_m[None]) - camera.project(point_m[None])).max() > 1
    coords = pixels_to_normalised(pixels, 64, 64)[None]  # (1, 1, 2)
    height = (point_m[2] - scaler.centre_m[2]) / scaler.scale_m
    out = torch.tensor([[[height, 0.0, 0.0, 0.0]]])  # (1, 1, 4)
    positions, turns = network.rays.read(coords, out, scaler)
    found = model.scaler.denormalise(positions)[0, 0].double().numpy()
    np.testing.assert_allclose(found, point_m, atol=1e-5)
    bearing = np.arctan2(point_m[1], point_m[0])
    np.testing.assert_allclose(turns[0, 0].double().numpy(), rot_z(bearing), atol=1e-6)
    # the offset is turned toward the point's bearing from the origin
    out[0, 0, 1] = 0.01 / scaler.scale_m
    shifted = model.scaler.denormalise(network.rays.read(coords, out, scaler)[0])[0, 0]
    np.testing.assert_allclose(shifted.double().numpy() - found,
                               [0.01 * np.cos(bearing), 0.01 * np.sin(bearing), 0.0], atol=1e-5)
    # and projecting the point gives back where it was read
    torch.testing.assert_close(network.rays.project(torch.tensor(point_m, dtype=torch.float32)),
                               coords[0, 0], atol=1e-5, rtol=0)


@pytest.mark.parametrize("kind", [LabelKind.GRASP_POSE, LabelKind.POSITION])
def test_the_point_loss_pulls_attention_onto_the_projected_target(kind):
    # grasp poses are read through the camera's rays; positions by the paper's MLP, but the
    # point is taught where the camera sees the target on either readout
    dataset = synthetic_dataset(6, kind=kind, seed=5, camera=CAMERA)
    batch = Batch(images_to_tensor(dataset.images), torch.as_tensor(dataset.conditions),
                  torch.as_tensor(dataset.labels))
    losses = {}
    for weight in (0.0, 2.0):
        model = KqvModel.for_dataset(dataset, KqvConfig(point_loss_weight=weight))
        assert model.network.readout == ("ray" if kind is LabelKind.GRASP_POSE else "mlp")
        model.scaler = model.network.scaler = LabelScaler.fit(dataset.labels[..., :3])
        losses[weight] = model.batch_loss(batch).item()
        points = model.network(batch.images, batch.conditions).points.detach().double().numpy()
    seen = CAMERA.project(dataset.labels[:, 0, :3].astype(float))  # (N, 2) px, numpy camera
    distance = np.square(points[:, 0] - pixels_to_normalised(
        torch.tensor(seen), 64, 64).numpy()).sum(axis=-1).mean()
    assert losses[2.0] - losses[0.0] == pytest.approx(2.0 * distance, rel=1e-4)


def test_without_a_camera_the_attention_stays_free():
    model = KqvModel.for_dataset(synthetic_dataset(6, seed=5), KqvConfig(point_loss_weight=2.0))
    assert model.spec.camera is None and model.network.seen is None
    with pytest.raises(InvalidInputError, match=r"point_loss_weight = -1.0 .* >= 0"):
        KqvConfig(point_loss_weight=-1.0)


def test_the_readout_is_chosen_by_label_and_camera_and_refused_without_one():
    grasp, position = spec(kind=LabelKind.GRASP_POSE), spec()
    ray, mlp = KqvModel(replace(grasp, camera=CAMERA)), KqvModel(replace(position, camera=CAMERA))
    assert (ray.network.readout, ray.network.stride) == ("ray", 2)
    assert (mlp.network.readout, mlp.network.stride) == ("mlp", 4)
    assert ray.network.attend(torch.zeros(1, 3, 64, 64), torch.ones(1, 1, 18)).heatmaps.shape \
        == (1, 1, 32, 32)  # 64 px at stride 2
    assert KqvModel(grasp).network.readout == "mlp"
    assert KqvModel(replace(position, camera=CAMERA), KqvConfig(readout="ray")).network.rays
    with pytest.raises(InvalidInputError, match=r"readout = 'ray' .* records no camera"):
        KqvModel(grasp, KqvConfig(readout="ray"))
    with pytest.raises(InvalidInputError, match=r"camera = '64 x 64 px' .* 32 x 32 px"):
        KqvModel(replace(grasp, camera=CAMERA, image_height_px=32, image_width_px=32),
                 KqvConfig(readout="ray"))
    with pytest.raises(InvalidInputError,
                       match=r"readout = 'rays' .* one of 'auto-range', 'auto', 'mlp'"):
        KqvConfig(readout="rays")


@pytest.mark.slow
def test_the_ray_readout_learns_positions_at_untrained_places_and_survives_a_checkpoint(
        tmp_path):
    train = synthetic_dataset(24, kind=LabelKind.GRASP_POSE, seed=3, camera=CAMERA)
    test = synthetic_dataset(16, kind=LabelKind.GRASP_POSE, seed=4, camera=CAMERA)
    model = KqvModel.for_dataset(train, KqvConfig(starts=1, warmup_steps=100))
    model.fit(train, TrainConfig(steps=300, batch_size=8, threads=1), progress=False)
    assert model.network.readout == "ray"
    predicted = np.array([p.targets[0].position_m for p in
                          model.predict_batch(test.images, test.conditions)])
    error_m = np.linalg.norm(predicted - test.labels[:, 0, :3], axis=1)
    assert np.median(error_m) < 0.01, error_m  # the squares span 20 cm; 1 px is about 0.5 cm
    again = KqvModel.load(model.save(tmp_path / "ray"))
    assert again.spec.camera == CAMERA
    reloaded = np.array([p.targets[0].position_m for p in
                         again.predict_batch(test.images, test.conditions)])
    np.testing.assert_allclose(reloaded, predicted, atol=1e-6)


def test_the_ray_readouts_head_reads_where_the_point_is_only_when_asked():
    dataset = synthetic_dataset(4, kind=LabelKind.GRASP_POSE, seed=6, camera=CAMERA)
    plain = KqvModel.for_dataset(dataset, KqvConfig(seed=1))
    coords = KqvModel.for_dataset(dataset, KqvConfig(seed=1, head_coords=True, starts=1))

    def head_inputs(model: KqvModel) -> int:
        return next(m for m in model.network.head.modules()
                    if isinstance(m, torch.nn.Linear)).in_features

    assert head_inputs(coords) == head_inputs(plain) + 2  # a_coord's (x, y)
    assert not plain.network.head_coords and coords.network.head_coords
    coords.fit(dataset, TrainConfig(steps=2, batch_size=2, threads=1), progress=False)
    (target,) = coords.predict(dataset.images[0]).targets  # trains and predicts with them
    check_rotations("predicted rotation", target.rotation[None])
    with pytest.raises(InvalidInputError, match="head_coords = 'yes'"):
        KqvConfig(head_coords="yes")
