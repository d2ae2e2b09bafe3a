"""The "Key Point" comparison model of the paper: a vanilla FCN, a spatial softmax, an MLP.

A plain FCN (no coordinate channels, unlike the KQV model's Key network) turns the image into K
logit maps; a 2-D spatial softmax with a learned temperature (Levine et al. 2016) turns each
into a heatmap, and its expected (x, y) is a key point (Kulkarni et al. 2019). An MLP maps the
2K coordinates, with the one-hot condition in top-down tasks, to all q targets. Trained end to
end on the target loss. Each map learns one visual pattern, wherever it is: there are no
Queries, so the condition reaches only the MLP.

The paper trains it with K = 16 ("q=16", preset ``keypoint-16``) and with K = q, as many points
as targets ("q=min", ``points=None``, preset ``keypoint-min``). :class:`SpatialSoftmaxEncoder`
is also the Deep Spatial AE's encoder (:mod:`perception.models.dsae`).

The FCN's layers match the first two of the KQV model's FCN1 (a 5 x 5 then a 3 x 3 conv, both
stride 2, 16 and 32 channels), so the heatmaps are 32 x 32 for 128 x 128 images, as KQV's are:
the comparison is between attention mechanisms, not between network sizes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import Tensor, nn

from perception.interface import InvalidInputError
from perception.learning.learnable import ModelSpec
from perception.models.base import coordinate_grid, softmax2d, spatial_expectation
from perception.models.baselines import (
    BaselineConfig,
    BaselineModel,
    BaselineNet,
    Encoding,
    PoseHead,
    check_channels,
    check_count,
    conv_stack,
)


@dataclass(frozen=True)
class KeypointConfig(BaselineConfig):
    """Hyper-parameters of the Key Point model (and of the DSAE's encoder).

    Args:
        points: K, the key points (heatmaps); None: as many as the task's targets, the paper's
            "q=min". 16 is the paper's "q=16".
        channels: Output channels of the FCN's first two conv layers (5 x 5 and 3 x 3, stride 2
            each); the third (3 x 3, stride 1) gives the K logit maps.
        temperature: Initial temperature of the spatial softmax (the logits are divided by it);
            learned from there, as in Levine et al., in log form so it stays positive.
        head_width: See :class:`~perception.models.baselines.BaselineConfig`, as are
            ``rotation_loss_weight`` and ``seed``.

    """

    points: int | None = 16
    channels: tuple[int, int] = (16, 32)
    temperature: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.points is not None:
            check_count("points", self.points)
        object.__setattr__(self, "channels", check_channels("channels", self.channels,
                                                            range(2, 3)))
        if not (math.isfinite(self.temperature) and self.temperature > 0):
            raise InvalidInputError("temperature", self.temperature, "a finite value > 0")

    def keypoints(self, spec: ModelSpec) -> int:
        """K for a task: ``points``, or the task's number of targets when that is None."""
        return spec.targets if self.points is None else self.points


class SpatialSoftmaxEncoder(nn.Module):
    """FCN -> K heatmaps (2-D softmax, learned temperature) -> K expected (x, y) points."""

    def __init__(self, points: int, channels: tuple[int, ...], temperature: float) -> None:
        super().__init__()
        wide1, wide2 = channels
        self.fcn = conv_stack((3, wide1, wide2, points), (5, 3, 3), (2, 2, 1),
                              activate_last=False)  # (B, 3, H, W) -> (B, K, H/4, W/4)
        self.log_temperature = nn.Parameter(torch.tensor(math.log(temperature)))

    def forward(self, x: Tensor) -> Encoding:
        """Normalised images (B, 3, H, W) -> the flat points (B, 2K), points and heatmaps."""
        logits = self.fcn(x)  # (B, K, h, w)
        heatmaps = softmax2d(logits / self.log_temperature.exp())  # (B, K, h, w)
        height, width = logits.shape[-2:]
        grid = coordinate_grid(height, width, x.device)  # (2, h, w)
        points = spatial_expectation(heatmaps, grid)  # (B, K, 2)
        return Encoding(points.flatten(1), points, heatmaps)  # features (B, 2K)


class KeypointModel(BaselineModel):
    """The Key Point comparison model behind the :class:`PerceptionModel` interface."""

    name = "keypoint"
    attention_per_target = False  # the MLP reads all K points at once; none is a target's
    config_class = KeypointConfig
    config: KeypointConfig

    def build_network(self) -> BaselineNet:
        """The FCN and spatial softmax, and the head MLP on the 2K point coordinates."""
        config, points = self.config, self.config.keypoints(self.spec)
        return BaselineNet(SpatialSoftmaxEncoder(points, config.channels, config.temperature),
                           PoseHead(2 * points, self.spec, config.head_width))
