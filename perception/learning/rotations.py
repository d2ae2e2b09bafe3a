"""Grasp rotations a network predicts: how its numbers become a rotation, and the loss on them.

A parallel gripper's grasp and the same grasp turned half a turn about the approach axis (the
TCP's z) are one grasp: ``R`` and ``R @ FLIP_Z``. Two codes turn a head's numbers into a rotation:

* ``"6d"``: the continuous 6-D representation of Zhou et al. (2019), the first two columns by
  Gram-Schmidt, trained with the chordal loss against the nearer of the label and its twin.
* ``"axis-line"``: the approach axis ``z`` and the closing axis's line tensor ``x xᵀ``, which a
  half turn leaves unchanged, trained on those numbers directly. Its closing axis is the
  principal axis of ``x xᵀ`` in the plane normal to ``z``, signed toward
  :data:`CLOSING_REFERENCE`. Why it is the default: ``docs/decisions/kqv.md#axis-line-rotation``.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import Tensor

from perception.learning.learnable import check_choices

ROTATION_CODES = ("6d", "axis-line")

FLIP_Z = torch.diag(torch.tensor([-1.0, -1.0, 1.0]))
"""A half turn about the TCP z axis: ``R @ FLIP_Z`` is the same parallel-gripper grasp as ``R``."""

CLOSING_REFERENCE = (-1.0, 1.0, 0.0)
"""The direction an ``"axis-line"`` closing axis is signed toward, in the frame the head predicts
in: back and to the left, so the canonical grasps of the yumi objects keep their sign (sponge
closing to the left, bottle side grasp, mug rim toward the robot) except sponges turned within
45 degrees of their seam, which get the equivalent twin."""


def rotation_size(code: str) -> int:
    """Numbers a head gives per rotation: 6 (``"6d"``) or 9 (``"axis-line"``: z and ``x xᵀ``)."""
    check_choices("rotation", code, ROTATION_CODES)
    return 6 if code == "6d" else 9


def rotation_from_6d(six: Tensor) -> Tensor:
    """The rotation whose first two columns are Gram-Schmidt of ``six`` (..., 6) -> (..., 3, 3).

    The continuous 6-D representation of Zhou et al. (2019): unlike quaternions or Euler angles
    it has no discontinuity a network must jump across, and any 6 numbers give a proper rotation.
    """
    a1, a2 = six[..., :3], six[..., 3:]  # (..., 3) each
    b1 = torch.nn.functional.normalize(a1, dim=-1)  # (..., 3)
    b2 = torch.nn.functional.normalize(a2 - (b1 * a2).sum(-1, keepdim=True) * b1, dim=-1)
    b3 = torch.cross(b1, b2, dim=-1)  # (..., 3)
    return torch.stack([b1, b2, b3], dim=-1)  # (..., 3, 3), columns b1, b2, b3


def axis_line_from_raw(raw: Tensor) -> Tensor:
    """A head's 9 numbers (..., 9) -> the axis-line code (..., 3, 4): ``[z | x xᵀ]``.

    ``z`` is the first three numbers normalised; the symmetric 3 x 3 line tensor is the other
    six (diagonal, then the (0, 1), (0, 2), (1, 2) entries).
    """
    z = torch.nn.functional.normalize(raw[..., :3], dim=-1)  # (..., 3)
    d0, d1, d2, a01, a02, a12 = raw[..., 3:].unbind(-1)  # (...) each
    line = torch.stack([d0, a01, a02, a01, d1, a12, a02, a12, d2], dim=-1).unflatten(-1, (3, 3))
    return torch.cat([z[..., None], line], dim=-1)  # (..., 3, 4)


def axis_line_of(rotation: Tensor) -> Tensor:
    """The axis-line code (..., 3, 4) of rotations (..., 3, 3): the same for ``R`` and its twin."""
    x, z = rotation[..., :, 0], rotation[..., :, 2]  # (..., 3) each
    return torch.cat([z[..., None], x[..., :, None] * x[..., None, :]], dim=-1)


def turn_axis_line(turn: Tensor, code: Tensor) -> Tensor:
    """The code (..., 3, 4) of a rotation ``R`` -> that of ``turn @ R``, for turns (..., 3, 3)."""
    z = turn @ code[..., :, :1]  # (..., 3, 1)
    line = turn @ code[..., :, 1:] @ turn.transpose(-1, -2)  # (..., 3, 3)
    return torch.cat([z, line], dim=-1)


def rotation_from_axis_line(code: Tensor) -> Tensor:
    """The rotation (..., 3, 3) an axis-line code (..., 3, 4) stands for.

    ``z`` as given; ``x`` the eigenvector of the largest eigenvalue of the line tensor projected
    onto the plane normal to ``z``, signed toward :data:`CLOSING_REFERENCE` (either sign is the
    same grasp); ``y = z × x``. Gradients do not flow through the eigenvectors (the loss is on
    the code itself), so the decoding runs detached from the line tensor.
    """
    z = code[..., :, 0]  # (..., 3), unit
    normal = torch.eye(3, dtype=code.dtype, device=code.device) - z[..., :, None] * z[..., None, :]
    line = normal @ code[..., :, 1:].detach() @ normal  # (..., 3, 3), symmetric; z: null
    # The plane's eigenvalues lifted above z's 0: a line tensor that is negative in the plane
    # (an untrained head's) must still give a closing axis in it, never z itself.
    lift = torch.linalg.matrix_norm(line)[..., None, None] + 1.0  # (..., 1, 1)
    _, vectors = torch.linalg.eigh(line + lift * normal)  # ascending eigenvalues
    x = vectors[..., :, -1]  # (..., 3)
    x = torch.nn.functional.normalize(x - (x * z).sum(-1, keepdim=True) * z, dim=-1)
    reference = torch.tensor(CLOSING_REFERENCE, dtype=code.dtype, device=code.device)
    x = torch.where((x @ reference)[..., None] < 0, -x, x)
    y = torch.cross(z, x, dim=-1)
    return torch.stack([x, y, z], dim=-1)  # (..., 3, 3), columns x, y, z


def decode_rotation(raw: Tensor, code: str, turn: Tensor | None = None
                    ) -> tuple[Tensor, Tensor | None]:
    """A head's rotation numbers (..., 6 | 9) -> rotations (..., 3, 3) and axis-line codes.

    ``turn`` (..., 3, 3), when given, takes both from the frame the head predicts in to the
    world's. The codes (..., 3, 4) are None for ``"6d"``, whose loss reads the rotations.
    """
    if code == "6d":
        rotations, lines = rotation_from_6d(raw), None
    else:
        lines = axis_line_from_raw(raw)
        rotations = rotation_from_axis_line(lines)
    if turn is not None:
        rotations = turn @ rotations
        lines = None if lines is None else turn_axis_line(turn, lines)
    return rotations, lines


def symmetric_chordal_loss(rotation: Tensor, target: Tensor) -> Tensor:
    """||R - R*||²_F, the smaller of R* and R* turned by π about its z axis: (..., 3, 3) -> (...).

    A parallel gripper turned half a turn about its approach axis makes the same grasp, so the
    network is not punished for predicting the equivalent one.
    """
    flipped = target @ FLIP_Z.to(target)  # (..., 3, 3)
    direct = (rotation - target).square().sum(dim=(-2, -1))  # (...)
    other = (rotation - flipped).square().sum(dim=(-2, -1))  # (...)
    return torch.minimum(direct, other)


def axis_line_loss(code: Tensor, target: Tensor) -> Tensor:
    """||z - z*||² + ||x xᵀ - x* x*ᵀ||²_F for codes (..., 3, 4) and label rotations (..., 3, 3).

    For a small turn θ it is 2θ² about z, θ² about x and 3θ² about y, the scale of the chordal
    loss (2θ² about any axis), so one rotation weight serves both codes.
    """
    return (code - axis_line_of(target)).square().sum(dim=(-2, -1))


def symmetric_angle_rad(rotation: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Geodesic angle [rad] between rotations (..., 3, 3), the smaller over the π-about-z twin.

    From the chordal distance, ||R - R*||_F = √8 sin(θ/2), which unlike arccos of the trace
    stays accurate for small angles.
    """
    def angle(other: np.ndarray) -> np.ndarray:
        chord = np.sqrt(np.square(rotation - other).sum(axis=(-2, -1)))
        return 2 * np.arcsin(np.clip(chord / math.sqrt(8), 0.0, 1.0))

    return np.minimum(angle(target), angle(target @ np.diag([-1.0, -1.0, 1.0])))
