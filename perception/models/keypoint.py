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

With ``readout = "ray"`` and a ``point_loss_weight`` (presets ``keypoint-16-helped``,
``keypoint-min-helped``), the model gets the help the KQV model's readout and loss give it: each
target is read off the camera's ray through one point, a head picks which point serves which
target (:mod:`perception.models.keypoint_ray`), and the point loss pulls that point to where the
camera sees the target.

The FCN's layers match the first two of the KQV model's FCN1 (a 5 x 5 then a 3 x 3 conv, both
stride 2, 16 and 32 channels), so the heatmaps are 32 x 32 for 128 x 128 images, as KQV's are:
the comparison is between attention mechanisms, not between network sizes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, ClassVar

import torch
from torch import Tensor, nn

from perception.interface import InvalidInputError
from perception.learning.learnable import ModelSpec, check_choices, check_number
from perception.learning.torch_pieces import coordinate_grid, softmax2d, spatial_expectation
from perception.learning.train import Batch
from perception.models.baselines import (
    MOST,
    AutoencoderModel,
    BaselineConfig,
    BaselineModel,
    BaselineNet,
    Encoding,
    PoseHead,
    check_channels,
    check_count,
    check_weight,
    conv_stack,
)
from perception.models.keypoint_ray import KeypointRayNet
from perception.models.torch_model import present_mean

READOUTS = ("mlp", "ray")


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
        readout: ``"mlp"``: the paper's MLP maps all 2K coordinates to the targets.
            ``"ray"``: each target is read off the ray, through its point, of the dataset's
            calibrated camera, at a height, offset (and rotation) a head MLP gives (a dataset
            that records its camera only; :mod:`perception.models.keypoint_ray`). With
            K = q point k serves target k; otherwise a selection head picks, per target, a
            softmax-weighted mean of the K points: "a head picks which point serves which
            target".
        point_loss_weight: Weight of kqv's point loss (readout ``"ray"`` only): the squared
            distance (normalised image units) from each target's point to where the camera
            sees the target (its label projected), over the targets present. 0: none, the
            paper's.
        head_width: See :class:`~perception.models.baselines.BaselineConfig`, as are
            ``rotation_loss_weight``, ``input_norm``, ``mirror`` and ``seed``.

    """

    points: int | None = 16
    channels: tuple[int, int] = (16, 32)
    temperature: float = 1.0
    SINCE: ClassVar[Mapping[str, Any]] = MappingProxyType(
        {**BaselineConfig.SINCE, "readout": "mlp", "point_loss_weight": 0.0})

    readout: str = "mlp"
    point_loss_weight: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.points is not None:
            check_count("points", self.points)
        object.__setattr__(self, "channels", check_channels("channels", self.channels,
                                                            range(2, 3)))
        check_number("temperature", self.temperature, 0, MOST["temperature"], open_below=True)
        check_choices("readout", self.readout, READOUTS)
        check_weight("point_loss_weight", self.point_loss_weight)
        if self.point_loss_weight > 0 and self.readout != "ray":
            raise InvalidInputError("point_loss_weight", self.point_loss_weight,
                                    f"0 with readout {self.readout!r} (its points serve no "
                                    "target; readout 'ray' gives each target one)")

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
    # The MLP reads all K points at once; none is a target's. The ray readout's predictions do
    # carry one point per target (its attention_px and heatmaps), but the class says False.
    attention_per_target = False
    config_class = KeypointConfig
    config: KeypointConfig

    def build_network(self) -> BaselineNet:
        """The FCN and spatial softmax, then the MLP on the 2K coordinates or the ray readout.

        The ray readout's network is :class:`~perception.models.keypoint_ray.KeypointRayNet`.
        """
        config, spec, points = self.config, self.spec, self.config.keypoints(self.spec)
        encoder = SpatialSoftmaxEncoder(points, config.channels, config.temperature)
        if config.readout == "mlp":
            return BaselineNet(encoder, PoseHead(2 * points, spec, config.head_width))
        if isinstance(self, AutoencoderModel):
            raise InvalidInputError("readout", config.readout, f"'mlp' for {self.name} (its "
                                    "head trains on the frozen encoder's points)")
        if spec.camera is None:
            raise InvalidInputError("readout", config.readout, "'mlp' for a dataset that "
                                    "records no camera (the ray readout reads through it)")
        return KeypointRayNet(encoder, points, spec, config.head_width)

    def batch_loss(self, batch: Batch) -> Tensor:
        """The target loss of the (mirrored) batch, plus the point loss where the config sets it.

        The point loss is kqv's: :attr:`KeypointConfig.point_loss_weight` times the squared
        distance (normalised image units) from each target's point to where the camera sees the
        target (its label projected), over the targets present.
        """
        network, weight = self.network, self.config.point_loss_weight
        if not isinstance(network, KeypointRayNet) or weight == 0:
            return super().batch_loss(batch)
        batch = self.mirrored(batch)
        out = network(batch.images, batch.conditions)
        loss = self.target_loss(out, batch.labels, batch.present)
        if out.points is None:
            raise InvalidInputError("points", None, "a target's point for the point loss")
        return loss + weight * present_mean(
            (out.points - network.seen(batch.labels)).square().sum(-1), batch.present)
