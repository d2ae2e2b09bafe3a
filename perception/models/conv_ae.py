"""The "Convolutional AE" comparison model of the paper: an hourglass compressing the image.

The FCN model's conv stack (:class:`~perception.models.fcn.ConvEncoder`), flattened, then a
linear layer compress the RGB image into one latent vector; a decoder (a linear layer, then
three rounds of 2x upsampling and a 3 x 3 conv) reconstructs a small RGB image from it. Training
runs in two phases (:class:`~perception.models.baselines.AutoencoderModel`): encoder and decoder
on the reconstruction, then the head MLP on the frozen latent (with the one-hot condition in
top-down tasks). No attention: a prediction's ``attention_px`` is empty.

The reconstruction is the input average-pooled to 32 x 32 RGB, the DSAE's size (colour kept:
the objects differ in colour); the latent has 32 numbers, as the DSAE's 16 points do.
Upsampling and a conv, rather than transposed convs, avoid checkerboard artefacts.
"""

from __future__ import annotations

from dataclasses import dataclass

from torch import nn

from perception.models.baselines import (
    AutoencoderModel,
    BaselineNet,
    Decoder,
    check_count,
    check_reconstruction_px,
)
from perception.models.fcn import ConvEncoder, FcnConfig, FcnModel

UPSAMPLINGS = 3
"""Rounds of 2x upsampling in the decoder: it starts at an eighth of the reconstruction's side."""


@dataclass(frozen=True)
class ConvAeConfig(FcnConfig):
    """Hyper-parameters of the Convolutional AE: the FCN's, the latent's and the decoder's.

    Args:
        latent_dim: Length of the latent vector the image is compressed into (and the head
            reads).
        reconstruction_px: Side of the square RGB image the decoder reconstructs [px]: the
            input average-pooled to it; 16, 32 or 64, at most the image size.
        channels: The encoder's conv channels, as in :class:`~perception.models.fcn.FcnConfig`;
            the decoder's convs have ``channels[-1]``. ``head_width``, ``rotation_loss_weight``
            and ``seed`` as there.

    """

    latent_dim: int = 32
    reconstruction_px: int = 32

    def __post_init__(self) -> None:
        super().__post_init__()
        check_count("latent_dim", self.latent_dim)
        check_reconstruction_px(self.reconstruction_px)


def upsampling_decoder(latent_dim: int, width: int, size_px: int) -> Decoder:
    """Linear -> (width, r/8, r/8), then 3 x (2x upsample, conv 3 x 3, ReLU), conv -> RGB."""
    start = size_px // 2 ** UPSAMPLINGS
    layers: list[nn.Module] = [nn.Linear(latent_dim, width * start * start), nn.ReLU(),
                               nn.Unflatten(1, (width, start, start))]
    for _ in range(UPSAMPLINGS):
        layers += [nn.Upsample(scale_factor=2), nn.Conv2d(width, width, 3, 1, 1), nn.ReLU()]
    layers.append(nn.Conv2d(width, 3, 3, 1, 1))  # (B, 3, r, r)
    return Decoder(nn.Sequential(*layers), 3, size_px)


class ConvAeModel(AutoencoderModel, FcnModel):
    """The Convolutional AE comparison model behind the :class:`PerceptionModel` interface.

    The FCN model's network with a latent layer and a decoder, trained in the autoencoder's two
    phases.
    """

    name = "conv-ae"
    config_class = ConvAeConfig
    config: ConvAeConfig

    def build_network(self) -> BaselineNet:
        """The FCN network on the latent vector, plus the upsampling decoder."""
        config = self.config
        check_reconstruction_px(config.reconstruction_px, self.spec)
        network = super().build_network()
        network.decoder = upsampling_decoder(config.latent_dim, config.channels[-1],
                                             config.reconstruction_px)
        return network

    def build_encoder(self) -> ConvEncoder:
        """The FCN's conv stack, flattened, then a linear layer to the latent vector."""
        return ConvEncoder(self.spec, self.config.channels, self.config.latent_dim)
