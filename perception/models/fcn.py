"""The vanilla "FCN" comparison model of the paper: a conv stack, flattened, then an MLP.

Four 3 x 3 conv layers of stride 2 (3 -> 16 -> 32 -> 32 -> 32 channels) take a 128 x 128 image
to an 8 x 8 x 32 feature map; flattened (2048 numbers), with the one-hot condition in top-down
tasks, an MLP maps it to all q targets. Trained end to end on the target loss. It has no
attention: a prediction's ``attention_px`` is empty. :class:`ConvEncoder` is also the
Convolutional AE's encoder (:mod:`perception.models.conv_ae`).

The widths stay as small as the Key Point model's FCN (16 then 32 channels) so that no
comparison model wins by size; four stride-2 layers leave an 8 x 8 map, where one cell spans
about 10 cm of the table: the head must read positions off which cells respond and how much.
"""

from __future__ import annotations

from dataclasses import dataclass

from torch import Tensor, nn

from perception.learning.learnable import ModelSpec
from perception.models.baselines import (
    BaselineConfig,
    BaselineModel,
    BaselineNet,
    Encoding,
    PoseHead,
    check_channels,
    conv_stack,
)


@dataclass(frozen=True)
class FcnConfig(BaselineConfig):
    """Hyper-parameters of the FCN model (and of the Convolutional AE's encoder).

    Args:
        channels: Output channels of each 3 x 3 stride-2 conv layer, 1 to 6 layers; each halves
            the image's side (four: 128 -> 8 px).
        head_width: See :class:`~perception.models.baselines.BaselineConfig`, as are
            ``rotation_loss_weight`` and ``seed``.

    """

    channels: tuple[int, ...] = (16, 32, 32, 32)

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "channels", check_channels("channels", self.channels,
                                                            range(1, 7)))


class ConvEncoder(nn.Module):
    """Stride-2 convs, flattened, then (for an autoencoder) a linear layer to a latent vector."""

    def __init__(self, spec: ModelSpec, channels: tuple[int, ...],
                 latent_dim: int | None = None) -> None:
        super().__init__()
        layers = len(channels)
        self.fcn = conv_stack((3, *channels), (3,) * layers, (2,) * layers)
        height, width = spec.image_height_px, spec.image_width_px
        for _ in range(layers):  # a 3 x 3 conv, padding 1, stride 2: ceil(side / 2)
            height, width = (height + 1) // 2, (width + 1) // 2
        flat = channels[-1] * height * width
        self.latent = nn.Identity() if latent_dim is None else nn.Linear(flat, latent_dim)
        self.size = flat if latent_dim is None else latent_dim

    def forward(self, x: Tensor) -> Encoding:
        """Normalised images (B, 3, H, W) -> features (B, F): the flat map or the latent."""
        return Encoding(self.latent(self.fcn(x).flatten(1)))  # (B, F)


class FcnModel(BaselineModel):
    """The FCN comparison model behind the :class:`PerceptionModel` interface."""

    name = "fcn"
    config_class = FcnConfig
    config: FcnConfig

    def build_network(self) -> BaselineNet:
        """The encoder and the head MLP on its features."""
        encoder = self.build_encoder()
        return BaselineNet(encoder, PoseHead(encoder.size, self.spec, self.config.head_width))

    def build_encoder(self) -> ConvEncoder:
        """The conv stack, flattened: the head reads the whole feature map."""
        return ConvEncoder(self.spec, self.config.channels)
