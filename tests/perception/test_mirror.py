"""Mirror augmentation: the flipped image shows the mirrored labels where the camera sees them."""

from dataclasses import replace

import numpy as np
import pytest
import torch
from user_models import CAMERA, COLOURS, synthetic_dataset

from perception.camera import PinholeCamera
from perception.interface import ConditionKind, InvalidInputError, LabelKind
from perception.labels import check_rotations
from perception.learning.learnable import ModelSpec
from perception.learning.mirror import MIRROR_FLAG, Mirror
from perception.learning.torch_pieces import images_to_tensor
from perception.learning.train import Batch, TrainConfig
from perception.models.kqv import KqvConfig, KqvModel


def batch_of(dataset):
    return Batch(images_to_tensor(dataset.images), torch.as_tensor(dataset.conditions),
                 torch.as_tensor(dataset.labels))


@pytest.mark.parametrize("lens", [None, (-0.2, 0.05, 0.01, 0.0, 0.0)],
                         ids=["pinhole", "radial-and-p1"])
def test_a_mirrored_image_shows_each_target_where_its_mirrored_label_projects(lens):
    camera = CAMERA if lens is None else replace(CAMERA, distortion_k1_k2_p1_p2_k3=lens)
    dataset = synthetic_dataset(6, targets=2, kind=LabelKind.GRASP_POSE, seed=8, camera=camera)
    mirror = Mirror(ModelSpec.from_metadata(dataset.metadata), seed=0)
    batch = batch_of(dataset)
    mirrored = mirror(batch, flip=torch.ones(6, dtype=torch.bool))
    images = (mirrored.images.permute(0, 2, 3, 1) * 255).round().byte().numpy()
    labels = mirrored.labels.double().numpy()  # (6, 2, 12)
    np.testing.assert_allclose(labels[..., :3], dataset.labels[..., :3] * [1, -1, 1], atol=1e-6)
    check_rotations("mirrored", labels[..., 3:].reshape(-1, 3, 3))
    for n in range(6):
        for k in range(2):
            rows, columns = np.nonzero((images[n] == COLOURS[k]).all(axis=-1))
            seen = camera.project(labels[n, k, :3][None])[0]
            np.testing.assert_allclose([columns.mean(), rows.mean()], seen, atol=1e-3)
    # the TCP's approach and closing axes are mirrored too (y components negated)
    rotations = labels[..., 3:].reshape(6, 2, 3, 3)
    original = dataset.labels[..., 3:].reshape(6, 2, 3, 3)
    np.testing.assert_allclose(rotations[..., 1, 2], -original[..., 1, 2], atol=1e-6)
    np.testing.assert_allclose(rotations[..., 1, 0], -original[..., 1, 0], atol=1e-6)
    # mirroring twice gives the batch back, but for the image's first column
    twice = mirror(mirrored, flip=torch.ones(6, dtype=torch.bool))
    torch.testing.assert_close(twice.labels, batch.labels)
    torch.testing.assert_close(twice.images[..., 1:], batch.images[..., 1:])


def test_half_the_samples_are_mirrored_and_a_side_condition_swaps():
    dataset = synthetic_dataset(64, kind=LabelKind.POSITION, seed=9, camera=CAMERA)
    sides = replace(ModelSpec.from_metadata(dataset.metadata), condition_kind=ConditionKind.SIDE,
                    condition_choices=("left", "right"))
    left = torch.tensor([[1.0, 0.0]]).expand(64, 2)
    batch = batch_of(dataset)._replace(conditions=left)
    mirrored = Mirror(sides, seed=3)(batch)
    flipped = mirrored.labels[:, 0, 1] != batch.labels[:, 0, 1]  # (64,)
    assert 16 < int(flipped.sum()) < 48
    assert (mirrored.conditions[flipped] == torch.tensor([0.0, 1.0])).all()
    assert (mirrored.conditions[~flipped] == torch.tensor([1.0, 0.0])).all()
    assert torch.equal(mirrored.images[~flipped], batch.images[~flipped])


def test_the_depth_image_is_mirrored_with_the_colour_image():
    dataset = synthetic_dataset(16, kind=LabelKind.POSITION, seed=9, camera=CAMERA)
    colour = batch_of(dataset)
    depths = colour.images.mean(dim=1)  # (B, H, W): a depth image shaped like the colour one
    mirrored = Mirror(ModelSpec.from_metadata(dataset.metadata), seed=3)(
        colour._replace(depths_m=depths))
    assert mirrored.depths_m is not None
    assert torch.equal(mirrored.depths_m, mirrored.images.mean(dim=1))  # flipped as one
    assert not torch.equal(mirrored.depths_m, depths)  # and some were flipped


def test_a_sentence_naming_a_side_is_swapped_by_the_row_of_the_side_it_names():
    """A sentence task trains each sentence as its named side's row (kqv's unit prototypes): a
    mirrored sample gets the other side's row, as a one-hot side gets the other entry."""
    dataset = synthetic_dataset(64, kind=LabelKind.POSITION, seed=9, camera=CAMERA)
    sentences = replace(ModelSpec.from_metadata(dataset.metadata),
                        condition_kind=ConditionKind.TEXT, condition_choices=("left", "right"))
    rows = np.linalg.qr(np.random.default_rng(2).normal(size=(384, 2)))[0].T  # (2, 384) unit
    batch = batch_of(dataset)._replace(conditions=torch.as_tensor(
        rows[np.arange(64) % 2], dtype=torch.float32))  # left, right, left, ...
    mirrored = Mirror(sentences, seed=3, named_rows=rows)(batch)
    flipped = mirrored.labels[:, 0, 1] != batch.labels[:, 0, 1]  # (64,)
    assert 16 < int(flipped.sum()) < 48
    expected = np.where(flipped.numpy()[:, None], rows[(np.arange(64) + 1) % 2],
                        rows[np.arange(64) % 2])
    np.testing.assert_allclose(mirrored.conditions.numpy(), expected, atol=1e-6)
    with pytest.raises(InvalidInputError, match=r"mirror = True .* unless each named side's "
                                                r"condition row is given"):
        Mirror(sentences, seed=3)
    types = replace(sentences, condition_choices=("sponge", "mug"))  # a type stays a type
    kept = Mirror(types, seed=3, named_rows=rows)(batch)
    torch.testing.assert_close(kept.conditions, batch.conditions)
    assert not torch.equal(kept.labels, batch.labels)


def test_a_camera_off_the_mirror_plane_is_refused():
    dataset = synthetic_dataset(2, kind=LabelKind.GRASP_POSE, seed=1, camera=CAMERA)
    aside = PinholeCamera((0.0, 0.05, 0.6), (0.45, 0.0, 0.0), (0.0, 0.0, 1.0), 40.0, None, 64, 64)
    with pytest.raises(InvalidInputError, match=r"mirror = True .* y components must be 0 .*"
                                                r"position_m"):
        Mirror(replace(ModelSpec.from_metadata(dataset.metadata), camera=aside), seed=0)
    p2 = replace(CAMERA, distortion_k1_k2_p1_p2_k3=(0.0, 0.0, 0.0, 0.01, 0.0))
    with pytest.raises(InvalidInputError, match=r"mirror = True .* tangential p2 \(0.01\)"):
        Mirror(replace(ModelSpec.from_metadata(dataset.metadata), camera=p2), seed=0)
    with pytest.raises(InvalidInputError, match=r"mirror = True .* records no camera"):
        Mirror(replace(ModelSpec.from_metadata(dataset.metadata), camera=None), seed=0)
    with pytest.raises(InvalidInputError, match=r"mirror = 'yes' is not allowed: None, True or "
                                                 r"False"):
        KqvConfig(mirror="yes")


@pytest.mark.parametrize(("mirror", "flag", "mirrors"), [
    (None, True, True), (None, None, False), (None, False, False), (True, None, True),
    (False, True, False)])
def test_kqv_mirrors_samples_when_told_or_when_the_dataset_allows_it(mirror, flag, mirrors):
    dataset = synthetic_dataset(8, kind=LabelKind.GRASP_POSE, seed=2, camera=CAMERA)
    if flag is not None:
        extra = dataset.metadata.extra | {MIRROR_FLAG: flag}
        dataset = replace(dataset, metadata=replace(dataset.metadata, extra=extra))
    model = KqvModel.for_dataset(dataset, KqvConfig(mirror=mirror, starts=1, warmup_steps=2))
    seen = []
    original = model.network.forward

    def recording(images, conditions, queries=None, depths_m=None, value_images=None):
        seen.append(images.clone())
        return original(images, conditions, queries, depths_m, value_images)

    model.network.forward = recording  # type: ignore[method-assign]
    model.fit(dataset, TrainConfig(steps=3, batch_size=8, augment=False, threads=1),
              progress=False)
    shown = torch.cat(seen)  # (24, 3, H, W)
    plain = images_to_tensor(dataset.images)
    as_given = [any(torch.equal(image, p) for p in plain) for image in shown]
    if mirrors:
        assert 0 < sum(as_given) < len(shown)  # some samples were mirrored, some not
    else:
        assert sum(as_given) == len(shown)
