"""The Key Point model read out through the camera's rays (``KeypointConfig.readout = "ray"``).

The paper's Key Point head maps all K point coordinates to all q targets at once, so the
image-to-world mapping is the MLP's to learn from the demonstrations. Here, as with the KQV
model's ray readout (:class:`~perception.models.readout.CameraRays`), each target is read off
the calibrated camera's ray through one attention point, at a height and offset (and with a
rotation) a head MLP gives: the baseline gets the help kqv's readout gives, so a comparison
measures the attention, not the readout.

Which point serves which target: with K = q (``keypoint-min``) point k serves target k; with
K != q (``keypoint-16``) a selection head picks: per target, softmax weights over the K points
from an MLP of their flat coordinates (and the condition), the target's point their weighted
mean, differentiable, so the target and point losses teach the choice.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from perception.camera import Calibrations
from perception.interface import InvalidInputError, LabelKind
from perception.learning.learnable import ModelSpec
from perception.learning.rotations import decode_rotation, rotation_size
from perception.learning.torch_pieces import MLP
from perception.models.baselines import BaselineNet, Encoding
from perception.models.readout import CameraRays
from perception.models.torch_model import NetOutput

ROTATION_CODE = "6d"
"""The head's rotation code: the paper's Key Point head's (Zhou et al.), its loss the chordal."""

PLACE_SIZE = 4
"""Numbers per target that :meth:`CameraRays.read` places: a height, then an offset (3)."""


class PointSelection(nn.Module):
    """The head that picks which of K points serves which of q targets.

    Per target, softmax weights over the K points from an MLP of their flat coordinates (and
    the condition vector, where the task has one). None of it with K = q: point k serves
    target k.
    """

    def __init__(self, points: int, spec: ModelSpec, width: int) -> None:
        super().__init__()
        self.targets, self.points = spec.targets, points
        self.mlp = None if points == spec.targets else MLP(
            (2 * points + spec.condition_size, width, width, spec.targets * points))

    def forward(self, features: Tensor, conditions: Tensor) -> Tensor | None:
        """Flat points (B, 2K), conditions (B, C) -> weights (B, q, K), rows summing to 1.

        None where point k serves target k.
        """
        if self.mlp is None:
            return None
        logits = self.mlp(torch.cat([features, conditions], dim=-1))  # (B, q K)
        return torch.softmax(logits.unflatten(-1, (self.targets, self.points)), dim=-1)


class KeypointRayNet(BaselineNet):
    """The Key Point network with the ray readout: points, their selection, the ray head.

    The head MLP, shared by the q targets, reads the flat point coordinates, the condition and
    (q > 1) a one-hot target index, and gives per target a height and an offset, which
    :class:`CameraRays` places on the ray through the target's point, then, for grasp-pose
    labels, a 6-D rotation in the frame turned toward that point's bearing.

    Args:
        encoder: The spatial-softmax encoder: its :class:`Encoding` carries points and heatmaps.
        points: K, the encoder's points.
        spec: The task; its camera places the targets.
        width: Width of the head's (and the selection's) two hidden layers.

    """

    def __init__(self, encoder: nn.Module, points: int, spec: ModelSpec, width: int) -> None:
        head_in = 2 * points + spec.condition_size + (spec.targets if spec.targets > 1 else 0)
        rotates = spec.label_kind is LabelKind.GRASP_POSE
        head_out = PLACE_SIZE + (rotation_size(ROTATION_CODE) if rotates else 0)
        super().__init__(encoder, MLP((head_in, width, width, head_out)))
        self.rotates = rotates
        self.selection = PointSelection(points, spec, width)
        self.rays = CameraRays(spec)  # also where the camera sees each target (the point loss)

    def targets_points(self, encoding: Encoding, conditions: Tensor) -> tuple[Tensor, Tensor]:
        """Each target's point (B, q, 2) in [-1, 1] and heatmap (B, q, h, w), summing to 1.

        A selected point is the expectation of the selected heatmaps' mixture: the weighted
        mean of expectations.
        """
        points, heatmaps = encoding.points, encoding.heatmaps  # (B, K, 2), (B, K, h, w)
        if points is None or heatmaps is None:
            raise InvalidInputError("encoder", "one without points",
                                    "a spatial-softmax encoder for readout 'ray'")
        weights = self.selection(encoding.features, conditions)  # (B, q, K) | None
        if weights is None:
            return points, heatmaps
        return weights @ points, torch.einsum("bqk,bkhw->bqhw", weights, heatmaps)

    def targets(self, encoding: Encoding, conditions: Tensor, cameras: Calibrations = None
                ) -> NetOutput:
        """The targets read through the camera's rays, with each target's point and heatmap.

        ``cameras``: each image's calibration (a trial frame's); None: the spec's camera.
        """
        if self.scaler is None:
            raise InvalidInputError("scaler", None, "a LabelScaler before the ray readout runs "
                                    "(KeypointModel sets it on fit and load)")
        points, heatmaps = self.targets_points(encoding, conditions)  # (B, q, 2), (B, q, h, w)
        batch, count = points.shape[:2]
        inputs = torch.cat([encoding.features, conditions], dim=-1)  # (B, 2K + C)
        inputs = inputs[:, None].expand(-1, count, -1)  # (B, q, 2K + C)
        if count > 1:
            index = torch.eye(count, device=points.device).expand(batch, -1, -1)  # (B, q, q)
            inputs = torch.cat([inputs, index], dim=-1)  # (B, q, 2K + C + q)
        out = self.head(inputs)  # (B, q, 4 (+ 6 for a grasp's rotation))
        positions, turn = self.rays.read(points, out[..., :PLACE_SIZE], self.scaler, cameras)
        rotations = decode_rotation(out[..., PLACE_SIZE:], ROTATION_CODE, turn)[0] \
            if self.rotates else None  # (B, q, 3, 3) | None
        return NetOutput(positions, rotations, points, heatmaps)  # positions: (B, q, 3)

    def seen(self, labels: Tensor) -> Tensor:
        """Where the camera sees labelled targets (B, q, 3 | 12) [m]: (B, q, 2) in [-1, 1]."""
        return self.rays.project(labels[..., :3])
