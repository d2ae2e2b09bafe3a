"""kqv's options for worlds whose colours name no type: a wider view and the depth's rise."""

from dataclasses import replace

import numpy as np
import pytest
import torch
from user_models import BACKGROUND, CAMERA, COLOURS, spec, synthetic_dataset

from perception.interface import InvalidInputError, LabelKind, ModelInput
from perception.learning.train import TrainConfig
from perception.models.kqv import KqvConfig, KqvModel
from perception.models.repaint import OBJECT_RISE_M, Repaint
from perception.models.rise import rise_above_table


@pytest.mark.parametrize(("layers", "reach_px"), [(0, 6), (2, 18)])
def test_context_layers_let_a_key_see_as_far_as_their_receptive_field(layers, reach_px):
    # A Key at the image's centre changes with a pixel as far as its receptive field reaches
    # (13 px wide at 0 context layers: 6 px either side; 37 px at 2: 18 either side) and not
    # one pixel beyond: the context module is what lets a Key see an object's outline.
    config = KqvConfig(seed=3, context_layers=layers, stride=2)
    key_net = KqvModel(spec(), config).network.key_net.eval()
    image = torch.rand(1, 3, 128, 128, generator=torch.Generator().manual_seed(0))

    def key_changes(offset_px: int) -> bool:
        moved = image.clone()
        moved[0, :, 64, 64 + offset_px] += 1.0
        with torch.no_grad():
            return bool((key_net(moved) - key_net(image))[0, :, 32, 32].abs().max() > 0)

    assert key_changes(reach_px - 1)
    assert not key_changes(reach_px + 1)


def test_context_layers_are_bounded_and_left_out_of_identities_at_zero():
    with pytest.raises(InvalidInputError, match=r"context_layers = 5 is not allowed: an integer "
                                                 r">= 0 and <= 4"):
        KqvConfig(context_layers=5)
    assert KqvConfig.SINCE["context_layers"] == KqvConfig().context_layers == 0


def _raised_twins(size: int, seed: int):
    """Grasp scenes of two squares in one colour, square k standing 3 (k + 1) cm off the table:
    only the depth tells the targets apart."""
    dataset = synthetic_dataset(size, targets=2, kind=LabelKind.GRASP_POSE, seed=seed,
                                camera=CAMERA)
    table = np.broadcast_to(BACKGROUND, dataset.images.shape[1:])
    images = np.where((dataset.images != table).any(-1, keepdims=True), COLOURS[0], table)
    depths = np.full(dataset.images.shape[:3], 0.6, np.float32)
    for n, scene in enumerate(dataset.scenes):
        for k, (v, u) in enumerate(scene["corners_px"]):
            depths[n, v:v + 8, u:u + 8] -= 0.03 * (k + 1)
    return replace(dataset, images=images.astype(np.uint8), depths_m=depths)


@pytest.mark.slow
def test_depth_input_tells_apart_twins_the_colour_cannot():
    train, test = _raised_twins(24, seed=3), _raised_twins(16, seed=4)
    errors = {}
    for depth in (False, True):
        model = KqvModel.for_dataset(train, KqvConfig(starts=1, warmup_steps=50,
                                                      depth_input=depth, seed=1))
        model.fit(train, TrainConfig(steps=250, batch_size=8, threads=1), progress=False)
        predicted = np.array([[t.position_m for t in p.targets] for p in model.predict_batch(
            test.images, test.conditions, test.depths_m)])  # (N, 2, 3)
        errors[depth] = np.median(np.linalg.norm(predicted - test.labels[..., :3], axis=-1))
    assert errors[True] < 0.02 < errors[False], errors  # the squares lie about 10 cm apart


def test_a_depth_reading_kqv_says_so_and_refuses_what_has_no_depth():
    dataset = _raised_twins(4, seed=0)
    model = KqvModel.for_dataset(dataset, KqvConfig(depth_input=True))
    assert model.network.rays is not None  # the ray readout also reads each frame's camera
    assert model.inputs == frozenset({ModelInput.RGB, ModelInput.DEPTH, ModelInput.CAMERA})
    assert KqvModel.for_dataset(dataset).inputs == frozenset({ModelInput.RGB, ModelInput.CAMERA})
    with pytest.raises(InvalidInputError, match=r"depths_m = None is not allowed: depth images "
                                                 r"of shape \(4, 64, 64\)"):
        model.predict_batch(dataset.images, dataset.conditions)
    with pytest.raises(InvalidInputError, match=r"depth_input = True is not allowed: false for "
                                                 r"a dataset without depth images"):
        model.fit(replace(dataset, depths_m=None), TrainConfig(steps=1), progress=False)
    with pytest.raises(InvalidInputError, match=r"depth_input = 1 is not allowed: True or False"):
        KqvConfig(depth_input=1)


def test_values_from_depth_read_the_rise_and_not_the_colours():
    # value_input = "depth": the Value map (what the pose and type heads read) changes with the
    # depth and not with the colours, while the Key map still reads both.
    dataset = _raised_twins(2, seed=0)
    network = KqvModel.for_dataset(dataset, KqvConfig(depth_input=True, value_input="depth",
                                                      seed=2)).network.eval()
    images = torch.rand(1, 3, 64, 64, generator=torch.Generator().manual_seed(0))
    depths = torch.as_tensor(dataset.depths_m[:1])
    queries = network.queries(torch.as_tensor(dataset.conditions[:1]))
    value_maps: list[torch.Tensor] = []
    network.value_net.register_forward_hook(lambda _m, _i, out: value_maps.append(out))
    with torch.no_grad():
        plain = network.attend(images, queries, depths)
        recoloured = network.attend(1.0 - images, queries, depths)
        network.attend(images, queries, depths - 0.03 * torch.rand(depths.shape))
    assert not torch.allclose(plain.heatmaps, recoloured.heatmaps)  # the Key sees colour
    assert torch.equal(value_maps[0], value_maps[1])  # the Values do not
    assert not torch.allclose(value_maps[0], value_maps[2])  # but see the rise


def test_values_from_depth_need_the_depth():
    with pytest.raises(InvalidInputError, match=r"value_input = 'depth' is not allowed: 'image', "
                                                 r"or 'depth' with depth_input = true"):
        KqvConfig(value_input="depth")
    with pytest.raises(InvalidInputError, match=r"value_input = 'rgb' is not allowed"):
        KqvConfig(value_input="rgb", depth_input=True)
    assert KqvConfig.SINCE["value_input"] == KqvConfig().value_input == "image"


def test_repaint_paints_the_objects_the_depth_finds_and_nothing_else():
    dataset = _raised_twins(4, seed=5)
    images = torch.from_numpy(dataset.images).permute(0, 3, 1, 2).float() / 255.0
    depths = torch.from_numpy(dataset.depths_m)
    painted = Repaint(1.0, seed=0)(images, depths)
    changed = (painted != images).any(dim=1)  # (B, H, W)
    raised = torch.from_numpy(dataset.depths_m < 0.6 - 0.01)  # the squares, 3 and 6 cm up
    assert not (changed & ~raised).any()  # the table is never painted
    assert changed[raised].float().mean() > 0.9  # the squares are (a pattern may match a pixel)
    again = Repaint(1.0, seed=0)(images, depths)
    assert torch.equal(painted, again)  # seeded
    assert torch.equal(Repaint(1e-9, seed=0)(images, depths), images)  # none chosen


def test_a_repainting_kqv_paints_only_what_its_values_see_and_needs_depth():
    dataset = _raised_twins(8, seed=6)
    model = KqvModel.for_dataset(dataset, KqvConfig(depth_input=True, repaint=1.0, starts=1,
                                                    warmup_steps=2, type_steps=1))
    seen: list[torch.Tensor] = []
    model.network.key_net.register_forward_hook(lambda _m, inputs, _o: seen.append(inputs[0]))
    model.network.value_net.register_forward_hook(lambda _m, inputs, _o: seen.append(inputs[0]))
    model.fit(dataset, TrainConfig(steps=1, batch_size=4, threads=1, augment=False),
              progress=False)
    key_input, value_input = seen[0], seen[1]
    assert torch.equal(key_input[:, 3], value_input[:, 3])  # the same rise
    assert not torch.equal(key_input[:, :3], value_input[:, :3])  # other colours
    # What is repainted, and when (issue 79: only "the colours differ" was checked, so
    # repainting the Key, the table, or at inference passed): the images attend() is given
    attended: list[tuple[torch.Tensor, torch.Tensor | None, bool]] = []
    attend = model.network.attend

    def spy(images, queries, depths_m=None, value_images=None):
        attended.append((images, value_images, model.network.training))
        return attend(images, queries, depths_m, value_images)

    model.network.attend = spy  # type: ignore[method-assign]
    model.fit(dataset, TrainConfig(steps=1, batch_size=8, threads=1, augment=False),
              progress=False)
    images, repainted, training = attended[0]
    assert training and repainted is not None
    objects = (rise_above_table(torch.from_numpy(dataset.depths_m)) > OBJECT_RISE_M)[:, None]
    objects = objects.expand_as(images)  # the batch is the whole dataset, in some order
    order = [int(np.argmin([(images[b] - torch.from_numpy(d).permute(2, 0, 1) / 255).abs().sum()
                            for d in dataset.images])) for b in range(len(images))]
    objects = objects[order]
    assert torch.equal(repainted[~objects], images[~objects])  # the table untouched
    assert (repainted[objects] != images[objects]).float().mean() > 0.9  # the objects painted
    attended.clear()
    model.predict_batch(dataset.images, dataset.conditions, dataset.depths_m)
    assert attended and all(v is None and not t for _, v, t in attended)  # never at inference
    with pytest.raises(InvalidInputError, match=r"repaint = 0.5 is not allowed: 0 for a "
                                                 r"dataset without depth images"):
        KqvModel.for_dataset(dataset, KqvConfig(repaint=0.5)).fit(
            replace(dataset, depths_m=None), TrainConfig(steps=1), progress=False)
    with pytest.raises(InvalidInputError, match=r"repaint = 1.5 is not allowed"):
        KqvConfig(repaint=1.5)
    assert KqvConfig.SINCE["repaint"] == KqvConfig().repaint == 0.0
