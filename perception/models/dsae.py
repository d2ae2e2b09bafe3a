"""The "Deep Spatial AE" comparison model of the paper (Finn et al. 2016).

The Key Point model's encoder (:class:`~perception.models.keypoint.SpatialSoftmaxEncoder`: FCN,
spatial softmax, K expected points) feeds a linear decoder that reconstructs a small grey
version of the input from the 2K point coordinates alone, so the points must say where things
are. Training runs in two phases (:class:`~perception.models.baselines.AutoencoderModel`):
encoder and decoder on the reconstruction, then the head MLP on the frozen points (with the
one-hot condition in top-down tasks). The paper trains it with K = 16 (preset ``dsae-16``).

As in Finn et al., the decoder is one linear layer and its target is the grey image at a
quarter of the input's size (their 240 -> 60 px; here 128 -> 32 px, the size of the heatmaps):
small enough that the decoder stays cheap (2K x 1024 weights), large enough that a 10 cm object
(13-20 px across in a 128 px paper-sim image) still covers some 4 x 4 px.
"""

from __future__ import annotations

from dataclasses import dataclass

from torch import nn

from perception.models.baselines import (
    AutoencoderModel,
    BaselineNet,
    Decoder,
    check_reconstruction_px,
)
from perception.models.keypoint import KeypointConfig, KeypointModel


@dataclass(frozen=True)
class DsaeConfig(KeypointConfig):
    """Hyper-parameters of the Deep Spatial AE: the Key Point model's and the decoder's.

    Args:
        reconstruction_px: Side of the square grey image the decoder reconstructs [px]: the
            input average-pooled to it; 16, 32 or 64, at most the image size.
        points: K, as in :class:`~perception.models.keypoint.KeypointConfig`, as are
            ``channels``, ``temperature``, ``head_width``, ``rotation_loss_weight``, ``seed``.

    """

    reconstruction_px: int = 32

    def __post_init__(self) -> None:
        super().__post_init__()
        check_reconstruction_px(self.reconstruction_px)


class DsaeModel(AutoencoderModel, KeypointModel):
    """The Deep Spatial AE comparison model behind the :class:`PerceptionModel` interface.

    The Key Point model's network plus a decoder, trained in the autoencoder's two phases.
    """

    name = "dsae"
    config_class = DsaeConfig
    config: DsaeConfig

    def build_network(self) -> BaselineNet:
        """The Key Point network plus the linear decoder from its 2K coordinates."""
        size = self.config.reconstruction_px
        check_reconstruction_px(size, self.spec)
        network = super().build_network()
        coordinates = 2 * self.config.keypoints(self.spec)
        network.decoder = Decoder(nn.Linear(coordinates, size * size), 1, size)
        return network
