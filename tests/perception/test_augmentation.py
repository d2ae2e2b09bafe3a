"""The training loop's photometric augmentation: colours move, geometry stays, hues turn."""

import math

import pytest
import torch

from perception.interface import InvalidInputError
from perception.learning.train import TrainConfig, photometric_augment, turn_hues


def test_photometric_augmentation_keeps_shape_range_and_geometry():
    images = torch.zeros(4, 3, 16, 16)
    images[:, 0, 4:8, 4:8] = 0.8  # a red square on black
    out = photometric_augment(images, torch.Generator().manual_seed(0))
    assert out.shape == images.shape and out.min() >= 0 and out.max() <= 1
    # photometric only: the square stays where it was
    red = out[:, 0]
    assert (red[:, 4:8, 4:8].mean(dim=(1, 2)) > red.mean(dim=(1, 2)) + 0.3).all()


def test_hue_jitter_turns_hues_keeps_luma_and_draws_nothing_when_off():
    images = torch.zeros(4, 3, 8, 8)
    images[:, 0] = 0.6  # a dull red: every turn stays inside [0, 1]
    images[:, 1] = 0.3
    images[:, 2] = 0.3
    plain = photometric_augment(images, torch.Generator().manual_seed(0))
    again = photometric_augment(images, torch.Generator().manual_seed(0), hue_jitter=0.0)
    assert torch.equal(plain, again)  # off: the same draws as before the option
    turned = turn_hues(images, torch.tensor([0.0, math.pi / 2, math.pi, -math.pi / 2]))
    assert torch.allclose(turned[0], images[0], atol=1e-6)  # no turn: the image itself
    luma = torch.tensor([0.299, 0.587, 0.114]).view(1, 3, 1, 1)
    assert torch.allclose((turned * luma).sum(1), (images * luma).sum(1), atol=1e-5)
    assert turned[2, 0].mean() < turned[2, 1].mean()  # half a turn: red turns cyan-ish
    jittered = photometric_augment(images, torch.Generator().manual_seed(0), hue_jitter=0.5)
    assert not torch.allclose(jittered, plain) and jittered.min() >= 0 and jittered.max() <= 1
    with pytest.raises(InvalidInputError, match=r"hue_jitter = 0\.7 is not allowed: a share "
                       r"of a turn in \[0, 0\.5\]"):
        TrainConfig(hue_jitter=0.7)
