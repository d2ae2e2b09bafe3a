"""Rigid transforms: a pose as a position and a rotation, and the rotations the catalog is made of.

``Pose`` is what the catalog, the grasps, the judge and the trials pass around (``T_world_object``,
``T_object_grasp``); it composes and inverts without a robotics library, so ``perception`` needs
none.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np


class Pose(NamedTuple):
    """A rigid transform, e.g. ``T_world_object``: ``position`` (3,) [m], ``rotation`` (3, 3)."""

    position: np.ndarray  # (3,)
    rotation: np.ndarray  # (3, 3)

    @classmethod
    def from_xy_yaw(cls, x_m: float, y_m: float, yaw_rad: float, z_m: float = 0.0) -> Pose:
        """Make a pose at (x, y, z) turned by ``yaw_rad`` about the world z axis."""
        return cls(np.array([x_m, y_m, z_m], dtype=float), rot_z(yaw_rad))

    @property
    def matrix(self) -> np.ndarray:
        """The homogeneous transform (4, 4), e.g. for ``pinocchio.SE3(pose.matrix)``."""
        matrix = np.eye(4)
        matrix[:3, :3], matrix[:3, 3] = self.rotation, self.position
        return matrix

    def compose(self, other: Pose) -> Pose:
        """Return ``self · other``, e.g. ``T_world_object.compose(T_object_grasp)``."""
        return Pose(self.position + self.rotation @ other.position, self.rotation @ other.rotation)

    def inverse(self) -> Pose:
        """Return ``self⁻¹``, e.g. ``T_grasp_object`` from ``T_object_grasp``."""
        return Pose(-self.rotation.T @ self.position, self.rotation.T)


def rot_z(angle_rad: float) -> np.ndarray:
    """Rotation about z by ``angle_rad``, (3, 3)."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_rpy(rpy_rad: tuple[float, float, float]) -> np.ndarray:
    """URDF roll-pitch-yaw rotation, ``Rz(yaw) · Ry(pitch) · Rx(roll)``, (3, 3)."""
    roll, pitch, yaw = rpy_rad
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    rot_x = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    rot_y = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    return rot_z(yaw) @ rot_y @ rot_x
