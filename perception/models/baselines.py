"""What the paper's four comparison models share: conv stacks, the head, the decoder, two phases.

Table II of the paper compares the KQV model with two visual attention models, "Key Point"
(a vanilla FCN and a spatial softmax: Levine et al. 2016, Kulkarni et al. 2019) and "Deep
Spatial AE" (Finn et al. 2016), and with two vanilla FCN models, "Convolutional AE" and "FCN".
Each is one file built from the pieces here; every network is a :class:`BaselineNet`, an encoder
giving one feature vector per image (an :class:`Encoding`) and a :class:`PoseHead` MLP::

    model      encoder (file)                    phase 1: reconstruct      head reads
    keypoint   spatial softmax (keypoint.py)     -                         2K point coordinates
    dsae       spatial softmax (keypoint.py)     linear -> grey 32 x 32    frozen 2K coordinates
    conv-ae    conv stack + linear (fcn.py)      convs -> RGB 32 x 32      frozen latent vector
    fcn        conv stack, flattened (fcn.py)    -                         the flat feature map

In top-down tasks the one-hot condition is concatenated with the features before the head MLP:
the paper gives these models the target "with the coordinates" to an MLP. The two autoencoders
(:class:`AutoencoderModel`) train the encoder and decoder on reconstruction first, then the head
alone on the frozen encoder, as the paper trains them ("separately training vision models").

Every baseline can have the help the KQV model trains with, off by default (the paper's models):
each image's colours standardised by their own statistics (``input_norm = "per-image"``) and a
random half of each batch mirrored where the task allows it (``mirror``), as
:class:`~perception.models.kqv_config.KqvConfig`'s fields of the same names do.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, ClassVar, NamedTuple

import torch
from torch import Tensor, nn

from perception.camera import Calibrations
from perception.interface import ConditionKind, InvalidInputError
from perception.learning.data import Dataset
from perception.learning.learnable import (
    ModelSpec,
    check_choices,
    check_integer,
    check_number,
)
from perception.learning.mirror import MIRROR_FLAG, Mirror
from perception.learning.torch_pieces import MLP, LabelScaler, normalise_images
from perception.learning.train import Batch, TrainConfig, TrainReport
from perception.models.torch_model import NetOutput, Phase, TorchModel, pose_size, split_pose

RECONSTRUCTION_PX = (16, 32, 64)
"""Reconstruction sizes a decoder allows (square, a multiple of 8 for conv-ae's upsampling)."""

GREY_WEIGHTS = (0.299, 0.587, 0.114)
"""ITU-R BT.601 luma weights of R, G and B: the grey image DSAE reconstructs."""

INPUT_NORMS = ("fixed", "per-image")


MOST: Mapping[str, int | float] = MappingProxyType({
    # The largest value of each number of the baselines' configs, each with why a larger one is
    # a mistake (a typo, a unit slip) rather than a setting; a config file asking more is refused.
    "head_width": 4096,  # 64 x the default head; as wide as the widest MLP heads (VGG's fc)
    "rotation_loss_weight": 1000.0,  # 10,000 x the default: positions would not be learned
    "channels": 1024,  # per conv layer on 128 px images: 32 x the widest default (32)
    "points": 1024,  # K heatmaps: 64 x the paper's q = 16, a point per cell of a 32 x 32 map
    "temperature": 1000.0,  # 1000 x the default 1.0: the spatial softmax is flat, points central
    "point_loss_weight": 1000.0,  # 100 x kqv's 10: the pose loss it helps is drowned
    "latent_dim": 65536,  # more than a 128 x 128 RGB image's 49,152 values: no compression
})


def check_count(name: str, value: Any) -> None:
    """An error unless ``value`` is an integer >= 1 and at most its field's :data:`MOST`."""
    check_integer(name, value, 1, int(MOST[name]))


def check_channels(name: str, value: Any, lengths: range) -> tuple[int, ...]:
    """``value`` as a tuple of integers in [1, MOST] of a length in ``lengths`` (JSON: a list)."""
    channels = tuple(value) if isinstance(value, list | tuple) else ()
    most = MOST["channels"]
    if len(channels) not in lengths or not all(
            isinstance(c, int) and not isinstance(c, bool) and 1 <= c <= most for c in channels):
        count = str(lengths[0]) if len(lengths) == 1 else f"{lengths[0]} to {lengths[-1]}"
        raise InvalidInputError(name, value, f"{count} integers >= 1 and <= {most}")
    return channels


def check_weight(name: str, value: Any) -> None:
    """An error unless ``value`` is a finite number >= 0 and at most its field's :data:`MOST`."""
    check_number(name, value, 0, MOST[name])


@dataclass(frozen=True)
class BaselineConfig:
    """Hyper-parameters every comparison model has (each model's config adds its own).

    Args:
        head_width: Width of the head MLP's two hidden layers; 64, as the KQV model's head, so
            the models differ in what the head reads, not in its size.
        rotation_loss_weight: Weight of the chordal rotation loss against the position loss
            (squared distance in scaled units); 0.1 weighs 1 cm (at a 0.2 m label scale) like
            about 6 degrees of rotation.
        input_norm: ``"fixed"``: ``(image - 0.5) / 0.25``, the paper's; ``"per-image"``: each
            image's colour channels standardised by their own mean and spread, as kqv's.
        mirror: Whether training also shows a random half of each batch mirrored across the
            world's xz-plane, labels with it (:mod:`perception.learning.mirror`); every phase of
            an autoencoder alike. None: where the dataset's collector says its task allows it.
            False: the paper's.
        seed: Seeds the initial weights.

    """

    SINCE: ClassVar[Mapping[str, Any]] = MappingProxyType({"input_norm": "fixed",
                                                          "mirror": False})
    """Fields added after run folders recorded these configs, with the value that behaves as
    before they existed: a record leaves such a field out at that value, so older run folders
    still resume (``experiments.tables.model_config``)."""

    head_width: int = 64
    rotation_loss_weight: float = 0.1
    input_norm: str = "fixed"
    mirror: bool | None = False
    seed: int = 0

    def __post_init__(self) -> None:
        check_count("head_width", self.head_width)
        check_weight("rotation_loss_weight", self.rotation_loss_weight)
        check_choices("input_norm", self.input_norm, INPUT_NORMS)
        if self.mirror not in (None, True, False):
            raise InvalidInputError("mirror", self.mirror, "None, True or False")
        if not isinstance(self.seed, int) or isinstance(self.seed, bool) or self.seed < 0:
            raise InvalidInputError("seed", self.seed, "an integer >= 0")


def check_reconstruction_px(value: Any, spec: ModelSpec | None = None) -> None:
    """An error unless ``value`` is an allowed reconstruction size (no larger than the image)."""
    check_choices("reconstruction_px", value, RECONSTRUCTION_PX)
    if spec is not None and value > min(spec.image_height_px, spec.image_width_px):
        raise InvalidInputError("reconstruction_px", value, f"at most the image's "
                                f"{spec.image_height_px} x {spec.image_width_px} px")


def conv_stack(channels: Sequence[int], kernels: Sequence[int], strides: Sequence[int],
               activate_last: bool = True) -> nn.Sequential:
    """Convolutions ``channels[i] -> channels[i + 1]`` ('same' padding), ReLU after each.

    ``activate_last=False`` leaves the last layer linear (logits for a spatial softmax).
    """
    layers: list[nn.Module] = []
    for index, (kernel, stride) in enumerate(zip(kernels, strides, strict=True)):
        layers.append(nn.Conv2d(channels[index], channels[index + 1], kernel, stride,
                                kernel // 2))
        if activate_last or index < len(kernels) - 1:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class Encoding(NamedTuple):
    """What an encoder makes of a batch of images (tensors, batch first)."""

    features: Tensor  # (B, F) what the head (and the decoder) reads
    points: Tensor | None = None  # (B, K, 2) attention points, (x, y) in [-1, 1]
    heatmaps: Tensor | None = None  # (B, K, h, w), each summing to 1


class PoseHead(nn.Module):
    """The MLP from features (+ the one-hot condition) to all q targets at once."""

    def __init__(self, features: int, spec: ModelSpec, width: int) -> None:
        super().__init__()
        self.targets, self.pose = spec.targets, pose_size(spec.label_kind)
        self.mlp = MLP((features + spec.condition_size, width, width, self.targets * self.pose))

    def forward(self, features: Tensor, conditions: Tensor) -> tuple[Tensor, Tensor | None]:
        """Features (B, F), conditions (B, C) -> positions (B, q, 3), rotations (B, q, 3, 3)."""
        out = self.mlp(torch.cat([features, conditions], dim=-1))  # (B, q * (3 | 9))
        return split_pose(out.unflatten(-1, (self.targets, self.pose)))


class Decoder(nn.Module):
    """Reconstructs a small image (B, c, r, r) from an encoding's features (B, F).

    Its target is the normalised input image average-pooled to r x r, in grey (c = 1) or RGB.
    """

    def __init__(self, body: nn.Module, channels: int, size_px: int) -> None:
        super().__init__()
        self.body, self.channels, self.size_px = body, channels, size_px

    def forward(self, features: Tensor) -> Tensor:
        """Features (B, F) -> the reconstruction (B, c, r, r)."""
        return self.body(features).reshape(-1, self.channels, self.size_px, self.size_px)

    def target(self, images: Tensor) -> Tensor:
        """Normalised images (B, 3, H, W) -> what the decoder should give back (B, c, r, r)."""
        if self.channels == 1:
            weights = images.new_tensor(GREY_WEIGHTS).view(1, 3, 1, 1)
            images = (images * weights).sum(dim=1, keepdim=True)  # (B, 1, H, W)
        return nn.functional.adaptive_avg_pool2d(images, self.size_px)  # (B, c, r, r)


class BaselineNet(nn.Module):
    """An encoder, the head on its features and, for an autoencoder, a decoder."""

    per_image = False  # BaselineConfig.input_norm == "per-image"; set by BaselineModel
    scaler: LabelScaler | None = None  # for a head that places targets in metres (ray readout)

    def __init__(self, encoder: nn.Module, head: nn.Module, decoder: Decoder | None = None
                 ) -> None:
        super().__init__()
        self.encoder, self.head, self.decoder = encoder, head, decoder

    def encode(self, images: Tensor) -> Encoding:
        """The encoding of images (B, 3, H, W) in [0, 1]."""
        encoding: Encoding = self.encoder(normalise_images(images, self.per_image))
        return encoding

    def targets(self, encoding: Encoding, conditions: Tensor, cameras: Calibrations = None
                ) -> NetOutput:
        """The head's targets for an encoding under one-hot conditions (B, C).

        ``cameras``: each image's calibration, for a head that reads through the camera (the
        ray readout's); this head maps features to positions and reads none.
        """
        positions, rotations = self.head(encoding.features, conditions)  # (B, q, 3), ...
        return NetOutput(positions, rotations, encoding.points, encoding.heatmaps)

    def forward(self, images: Tensor, conditions: Tensor, cameras: Calibrations = None
                ) -> NetOutput:
        """Targets for images (B, 3, H, W) in [0, 1] under conditions (B, C) (and calibrations)."""
        return self.targets(self.encode(images), conditions, cameras)

    def reconstruction_loss(self, images: Tensor) -> Tensor:
        """Mean squared error of the decoder's reconstruction of images (B, 3, H, W)."""
        if self.decoder is None:
            raise InvalidInputError("decoder", None, "a network built with a decoder")
        x = normalise_images(images, self.per_image)  # (B, 3, H, W)
        return (self.decoder(self.encoder(x).features) - self.decoder.target(x)).square().mean()


class BaselineModel(TorchModel):
    """A comparison model: a :class:`BaselineNet` trained end to end on the target loss."""

    config: BaselineConfig
    network: BaselineNet
    _mirror: Mirror | None = None  # mirrors training samples (BaselineConfig.mirror)

    def seeded_network(self, seed: int) -> nn.Module:
        """The network, told how to scale its images and (once known) the label scaler."""
        network = super().seeded_network(seed)
        if isinstance(network, BaselineNet):
            network.per_image = self.config.input_norm == "per-image"
            network.scaler = self.scaler
        return network

    def fit(self, dataset: Dataset, config: TrainConfig | None = None,
            progress: bool = True) -> TrainReport:
        """Trains as :meth:`TorchModel.fit` does, mirroring samples where the config says.

        The label scaler is set before the first step, where the network reads it too.
        """
        config = config or TrainConfig()
        mirror = self.config.mirror
        if mirror is None:  # a baseline reads a sentence's embedding: it cannot swap its side
            mirror = dataset.metadata.extra.get(MIRROR_FLAG) is True and \
                self.spec.condition_kind is not ConditionKind.TEXT
        self._mirror = Mirror(self.spec, config.seed) if mirror else None
        if self.scaler is None:
            self.spec.check_dataset(dataset)
            self.scaler = LabelScaler.fit(dataset.labels[..., :3])
        self.network.scaler = self.scaler
        return super().fit(dataset, config, progress)

    def mirrored(self, batch: Batch) -> Batch:
        """The batch as training sees it: with :attr:`BaselineConfig.mirror`, half mirrored."""
        return batch if self._mirror is None else self._mirror(batch)

    def batch_loss(self, batch: Batch) -> Tensor:
        """The target loss of the network's prediction for the (mirrored) batch."""
        return super().batch_loss(self.mirrored(batch))


class AutoencoderModel(BaselineModel):
    """A comparison model trained in two phases, as the paper trains its autoencoders.

    Phase ``"autoencoder"``: encoder and decoder lower the reconstruction error. Phase
    ``"head"``: the head alone lowers the target loss on the frozen encoder's features (computed
    without gradients, so the encoder neither changes nor costs a backward pass).
    """

    def phases(self) -> list[Phase]:
        """Reconstruction (encoder + decoder), then the targets (head only)."""
        net = self.network
        if net.decoder is None:
            raise InvalidInputError("decoder", None, "a network built with a decoder")
        return [Phase("autoencoder", self.reconstruction_loss,
                      [*net.encoder.parameters(), *net.decoder.parameters()]),
                Phase("head", self.head_loss, list(net.head.parameters()))]

    def reconstruction_loss(self, batch: Batch) -> Tensor:
        """Phase 1's loss: the reconstruction error of the batch's (mirrored) images."""
        return self.network.reconstruction_loss(self.mirrored(batch).images)

    def head_loss(self, batch: Batch) -> Tensor:
        """Phase 2's loss: the target loss, the encoder frozen."""
        batch = self.mirrored(batch)
        with torch.no_grad():
            encoding = self.network.encode(batch.images)
        return self.target_loss(self.network.targets(encoding, batch.conditions), batch.labels,
                                batch.present)
