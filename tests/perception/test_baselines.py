import numpy as np
import pytest
import torch
from user_models import BACKGROUND, TYPES, synthetic_dataset

from perception.interface import Condition, ConditionKind, InvalidInputError, LabelKind
from perception.labels import check_rotations
from perception.learning.learnable import ModelSpec
from perception.learning.torch_pieces import LabelScaler
from perception.learning.train import TrainConfig, train
from perception.models.baselines import GREY_WEIGHTS, Decoder
from perception.models.conv_ae import ConvAeConfig, ConvAeModel
from perception.models.dsae import DsaeConfig, DsaeModel
from perception.models.fcn import FcnConfig, FcnModel
from perception.models.keypoint import KeypointConfig, KeypointModel
from perception.registry import MODELS, load_model, new_model

FAST = TrainConfig(steps=40, batch_size=8, learning_rate=3e-3, log_every=10, threads=1)
NAMES = ("keypoint-16", "keypoint-min", "dsae-16", "conv-ae", "fcn")
TWO_PHASES = ("dsae-16", "conv-ae")


def spec(q=1, kind=LabelKind.POSITION, choices=(), px=64):
    return ModelSpec(scene="synthetic", task="t", label_kind=kind, targets=q,
                     condition_kind=ConditionKind.OBJECT_TYPE if choices else ConditionKind.NONE,
                     condition_choices=choices, image_height_px=px, image_width_px=px)


def model_for(name, model_spec):
    """A registered model (or preset) built for a spec, with a label scaler as fit would set."""
    template = new_model(name, synthetic_dataset(size=1), seed=0)  # its class and config
    return type(template)(model_spec, template.config, LabelScaler((0.4, 0.0, 0.02), 0.2))


def points_of(name, q):
    return {"keypoint-16": 16, "dsae-16": 16, "keypoint-min": q}.get(name, 0)


def scenes(count=2, px=64):
    images = np.broadcast_to(BACKGROUND, (count, px, px, 3)).copy()
    images[0, 8:16, 8:16] = (220, 30, 30)
    return images


@pytest.mark.parametrize("name", NAMES)
def test_loss_falls_on_a_tiny_synthetic_dataset(name):
    dataset = synthetic_dataset(size=8, seed=1)
    report = new_model(name, dataset, seed=0).fit(dataset, FAST, progress=False)
    phases = [[loss for step, loss in report.losses if (step - 1) // FAST.steps == phase]
              for phase in range(report.steps // FAST.steps)]
    if name in TWO_PHASES:
        reconstruction, targets = phases
        assert reconstruction[-1] < 0.6 * reconstruction[0], report.losses
        assert targets[-1] < targets[0], report.losses
    else:
        (targets,) = phases
        assert targets[-1] < 0.7 * targets[0], report.losses


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("q", [1, 3])
@pytest.mark.parametrize("kind", [LabelKind.POSITION, LabelKind.GRASP_POSE])
@pytest.mark.parametrize("choices", [(), TYPES])
def test_prediction_shapes(name, q, kind, choices):
    model = model_for(name, spec(q, kind, choices))
    images = scenes()
    conditions = np.eye(len(choices), dtype=np.float32)[[0, 2]] if choices else np.zeros((2, 0))
    predictions = model.predict_batch(images, conditions)
    condition = Condition(ConditionKind.OBJECT_TYPE, "blue", TYPES) if choices else Condition()
    predictions.append(model.predict(images[1], condition))
    points = points_of(name, q)
    for prediction in predictions:
        assert len(prediction.targets) == q
        assert prediction.attention_px.shape == (points, 2)
        if points:
            assert prediction.heatmaps is not None and prediction.heatmaps.shape == \
                (points, 16, 16)  # a quarter of the 64 px image
            np.testing.assert_allclose(prediction.heatmaps.sum(axis=(1, 2)), 1.0, rtol=1e-5)
            assert (prediction.attention_px > -0.5).all() and (prediction.attention_px < 63.5).all()
        else:
            assert prediction.heatmaps is None
    targets = [target for prediction in predictions for target in prediction.targets]
    assert all(target.position_m.shape == (3,) for target in targets)
    if kind is LabelKind.GRASP_POSE:
        check_rotations("rotation", np.array([target.rotation for target in targets]))
    else:
        assert all(target.rotation is None for target in targets)
    # one by one or batched, the same image under the same condition gives the same targets
    np.testing.assert_allclose(predictions[2].targets[0].position_m,
                               predictions[1].targets[0].position_m, atol=1e-6)
    if choices:
        assert predictions[1].targets[0].object_type == "blue"


@pytest.mark.parametrize("name", NAMES)
def test_the_condition_reaches_the_head(name):
    model = model_for(name, spec(choices=TYPES))
    head_inputs = model.network.head.mlp[0].in_features
    features = model.network.encode(torch.zeros(1, 3, 64, 64)).features.shape[1]
    assert head_inputs == features + len(TYPES)
    if name.startswith(("keypoint", "dsae")):
        assert features == 2 * points_of(name, 1)
    image = scenes(1)
    red, green = (model.predict_batch(image, np.eye(3, dtype=np.float32)[[k]])[0]
                  for k in (0, 1))
    assert not np.allclose(red.targets[0].position_m, green.targets[0].position_m)
    np.testing.assert_array_equal(red.attention_px, green.attention_px)  # no Queries


def test_keypoint_min_has_one_point_per_target():
    dataset = synthetic_dataset(size=2, targets=3)
    model = new_model("keypoint-min", dataset, seed=0)
    assert type(model) is KeypointModel and model.config.points is None
    assert model.network.encoder.fcn[-1].out_channels == 3
    assert new_model("keypoint", dataset).network.encoder.fcn[-1].out_channels == 16


@pytest.mark.parametrize("name", TWO_PHASES)
def test_the_head_phase_leaves_the_encoder_alone(name):
    dataset = synthetic_dataset(size=8, conditioned=True, seed=2)
    model = new_model(name, dataset, seed=0)
    model.scaler = LabelScaler.fit(dataset.labels[..., :3])
    autoencoder, head = model.phases()
    assert (autoencoder.name, head.name) == ("autoencoder", "head")
    config = TrainConfig(steps=5, batch_size=4, threads=1)
    train(model.network, autoencoder.loss, dataset, config, False,
          parameters=autoencoder.parameters)
    before = {key: value.clone() for key, value in model.network.state_dict().items()}
    train(model.network, head.loss, dataset, config, False, parameters=head.parameters)
    after = model.network.state_dict()
    for key, value in after.items():
        if key.startswith("head."):
            assert not torch.equal(value, before[key]), key
        else:  # encoder and decoder
            assert torch.equal(value, before[key]), key


def test_decoder_targets_are_the_pooled_image_in_grey_or_colour():
    images = torch.zeros(2, 3, 64, 64)
    images[:, 0, :32] = 1.0  # the top half red
    grey = Decoder(torch.nn.Identity(), 1, 16).target(images)
    assert grey.shape == (2, 1, 16, 16)
    torch.testing.assert_close(grey[:, 0, :8], torch.full((2, 8, 16), GREY_WEIGHTS[0]))
    torch.testing.assert_close(grey[:, 0, 8:], torch.zeros(2, 8, 16))
    colour = Decoder(torch.nn.Identity(), 3, 32).target(images)
    assert colour.shape == (2, 3, 32, 32) and colour[:, 0, :16].min() == 1.0
    dsae = model_for("dsae-16", spec())
    assert dsae.network.decoder(torch.zeros(2, 32)).shape == (2, 1, 32, 32)
    conv_ae = model_for("conv-ae", spec())
    assert conv_ae.network.decoder(torch.zeros(2, 32)).shape == (2, 3, 32, 32)


@pytest.mark.parametrize("name", NAMES)
def test_save_then_load_predicts_the_same(name, tmp_path):
    dataset = synthetic_dataset(size=4, kind=LabelKind.GRASP_POSE, conditioned=True, seed=3)
    model = new_model(name, dataset, seed=1)
    model.fit(dataset, TrainConfig(steps=2, batch_size=4, threads=1), progress=False)
    loaded = load_model(model.save(tmp_path / "ckpt"))
    assert type(loaded) is type(model) and loaded.config == model.config
    for before, after in zip(model.predict_batch(dataset.images, dataset.conditions),
                             loaded.predict_batch(dataset.images, dataset.conditions),
                             strict=True):
        np.testing.assert_array_equal(before.attention_px, after.attention_px)
        np.testing.assert_array_equal(before.targets[0].position_m, after.targets[0].position_m)
        np.testing.assert_array_equal(before.targets[0].rotation, after.targets[0].rotation)


def test_registry_names_and_presets():
    assert [MODELS[name] for name in ("keypoint", "dsae", "conv-ae", "fcn")] == \
        [KeypointModel, DsaeModel, ConvAeModel, FcnModel]
    dataset = synthetic_dataset(size=2)
    keypoint = new_model("keypoint-16", dataset, seed=0)
    assert type(keypoint) is KeypointModel and keypoint.config == KeypointConfig(points=16)
    assert keypoint.network.encoder.fcn[-1].out_channels == 16
    dsae = new_model("dsae-16", dataset, seed=0)
    assert type(dsae) is DsaeModel and dsae.config.points == 16
    assert new_model("dsae-16", dataset, points=4).config.points == 4  # a preset is a default
    with pytest.raises(InvalidInputError, match=r"hyper-parameters = \['points'\] is not "
                       r"allowed: fields of fcn's FcnConfig: head_width, rotation_loss_weight, "
                       r"input_norm, mirror, seed, channels$"):
        new_model("fcn", dataset, points=3)


@pytest.mark.parametrize(("build", "message"), [
    (lambda: KeypointConfig(points=0), r"points = 0 is not allowed: an integer >= 1"),
    (lambda: KeypointConfig(points=2.5), r"points = 2.5 is not allowed: an integer >= 1"),
    (lambda: KeypointConfig(channels=(16,)), r"channels = \(16,\) is not allowed: 2 integers"),
    (lambda: KeypointConfig(temperature=0.0), r"temperature = 0.0 is not allowed: a finite "
                                              r"value > 0"),
    (lambda: DsaeConfig(reconstruction_px=20), r"reconstruction_px = 20 is not allowed: one of "
                                               r"16, 32, 64"),
    (lambda: DsaeConfig(head_width=0), r"head_width = 0 is not allowed: an integer >= 1"),
    (lambda: FcnConfig(channels=()), r"channels = \(\) is not allowed: 1 to 6 integers >= 1"),
    (lambda: FcnConfig(rotation_loss_weight=-1.0), r"rotation_loss_weight = -1.0 is not "
                                                   r"allowed: a finite value >= 0"),
    (lambda: FcnConfig(seed=-1), r"seed = -1 is not allowed: an integer >= 0"),
    (lambda: ConvAeConfig(latent_dim=0), r"latent_dim = 0 is not allowed: an integer >= 1"),
    (lambda: ConvAeModel(spec(px=32), ConvAeConfig(reconstruction_px=64)),
     r"reconstruction_px = 64 is not allowed: at most the image's 32 x 32 px"),
    (lambda: DsaeModel(spec(px=16), DsaeConfig(reconstruction_px=32)),
     r"reconstruction_px = 32 is not allowed: at most the image's 16 x 16 px"),
    (lambda: FcnModel(spec(), KeypointConfig()), r"config = 'KeypointConfig' is not allowed: "
                                                 r"a FcnConfig for model 'fcn'"),
])
def test_config_errors_name_field_value_and_allowed(build, message):
    with pytest.raises(InvalidInputError, match=message):
        build()


def test_channels_read_back_from_json_lists():
    assert KeypointConfig(channels=[8, 16]).channels == (8, 16)
    assert ConvAeConfig(channels=[8, 16, 16]).channels == (8, 16, 16)
