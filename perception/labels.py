"""The label layout shared by dataset writers and models.

A label is float32 ``(..., 3)``: a position (x, y, z) [m] in the world frame, or ``(..., 12)``:
the TCP position followed by the 3x3 TCP rotation, row-major (columns: the TCP axes in the
world; z is the approach direction).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple

import numpy as np

from perception.interface import InvalidInputError, LabelKind

LABEL_DIMS: Mapping[LabelKind, int] = {LabelKind.POSITION: 3, LabelKind.GRASP_POSE: 12}
ROTATION_TOLERANCE = 1e-4  # |R Rᵀ - I|: float32 rounding of a true rotation stays near 1e-7


class Label(NamedTuple):
    """A label split into its parts (shared by dataset writers and models)."""

    position_m: np.ndarray  # (..., 3) [m], world frame
    rotation: np.ndarray | None  # (..., 3, 3) TCP rotation (columns: TCP axes); None: position


def label_vector(position_m: np.ndarray, rotation: np.ndarray | None = None) -> np.ndarray:
    """The float32 label layout: (..., 3) position [m], or (..., 12) with the rotation row-major."""
    position = np.asarray(position_m, dtype=np.float64)
    if position.ndim < 1 or position.shape[-1] != 3 or not np.all(np.isfinite(position)):
        raise InvalidInputError("position_m", position.tolist(), "finite values of shape (..., 3)")
    if rotation is None:
        return position.astype(np.float32)
    matrix = np.asarray(rotation, dtype=np.float64)
    if matrix.shape != (*position.shape[:-1], 3, 3):
        raise InvalidInputError("rotation", f"shape {matrix.shape}",
                                f"shape {(*position.shape[:-1], 3, 3)} to match position_m")
    check_rotations("rotation", matrix)
    flat = matrix.reshape(*position.shape[:-1], 9)
    return np.concatenate([position, flat], axis=-1).astype(np.float32)


def split_label(vector: np.ndarray) -> Label:
    """The position and (for 12-long labels) rotation in ``vector`` (..., 3) or (..., 12)."""
    array = np.asarray(vector)
    if array.ndim < 1 or array.shape[-1] not in (3, 12):
        raise InvalidInputError("label", f"shape {array.shape}", "shape (..., 3) or (..., 12)")
    if array.shape[-1] == 3:
        return Label(array[..., :3], None)
    return Label(array[..., :3], array[..., 3:].reshape(*array.shape[:-1], 3, 3))


def check_rotations(name: str, rotation: np.ndarray) -> None:
    """An error unless every (3, 3) matrix in ``rotation`` (..., 3, 3) is a proper rotation."""
    matrices = rotation.reshape(-1, 3, 3).astype(np.float64)
    error = np.abs(matrices @ matrices.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2))
    bad = np.flatnonzero((error > ROTATION_TOLERANCE) | (np.linalg.det(matrices) <= 0))
    if bad.size:
        raise InvalidInputError(name, f"matrix {int(bad[0])} = {matrices[bad[0]].tolist()}",
                                f"rotations: R Rᵀ = I within {ROTATION_TOLERANCE}, det(R) = +1")


def nearest_rotation(name: str, rotation: np.ndarray) -> np.ndarray:
    """The proper rotation nearest a model's (3, 3) ``rotation``, in float64.

    A float32 network output is a rotation only to about 1e-6, short of what an exact consumer
    (inverse kinematics) demands; the SVD projection makes it exact. A matrix further than
    :data:`ROTATION_TOLERANCE` from any rotation is an error naming ``name``: a wrong output,
    not rounding.
    """
    matrix = np.asarray(rotation, dtype=np.float64)
    if matrix.shape != (3, 3) or not np.all(np.isfinite(matrix)):
        raise InvalidInputError(name, f"shape {matrix.shape}", "a finite (3, 3) rotation")
    check_rotations(name, matrix)
    left, _, right = np.linalg.svd(matrix)
    return left @ right  # det +1: check_rotations refused a reflection
