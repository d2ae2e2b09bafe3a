"""How far each pixel rises above the table: a colour-free image of the objects' shapes.

A depth image shows the table as a plane and the objects as what stands out of it. A plane seen
by a pinhole camera has an inverse depth linear in the pixel coordinates (``1/z = a u + b v +
c``), so the table is found per image by least squares on inverse depth, refitted on the pixels
within :data:`INLIER_M` of the last fit (the objects and the depth's noise drop out), with no
calibration read. The rise is the plane's depth less the pixel's: 0 on the table, an object's
height-ish above it (along the ray), 0 where the sensor gave no depth. A model that reads it
(``KqvConfig.depth_input``) sees a mug as a mug whatever its colour or print.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from perception.errors import InvalidInputError

FIT_STRIDE = 4
"""The plane is fitted on every this-th pixel of each row and column (a 128 px image: 1,024
pixels, ample for three parameters), and read at every pixel."""
REFITS = 3
"""Plane fits per image: the first on every pixel with depth, each next on the last's inliers."""
INLIER_M = 0.01
"""A pixel within this of the plane's depth is the table's, for the next fit [m]: the D435's
depth noise at 0.5-0.8 m is a few millimetres (docs/decisions/d435-sensor.md)."""
RISE_SCALE_M = 0.1
"""The rise is given to a network in units of this [m]: about a mug's height."""
RISE_MOST_M = 0.5
"""Rises clipped to [-this, this] [m]: a stray far or near pixel is not a tall object."""


def rise_above_table(depths_m: Tensor) -> Tensor:
    """Depth images (B, H, W) [m] (0 or inf: none) -> each pixel's rise above the table (B, H, W).

    Positive towards the camera; 0 where the depth is missing or no plane could be fitted.
    """
    batch, height, width = depths_m.shape
    valid = torch.isfinite(depths_m) & (depths_m > 0)  # (B, H, W)
    depth_m = torch.where(valid, depths_m.double(), 1.0)  # (B, H, W)
    v, u = torch.meshgrid(torch.linspace(-1, 1, height, dtype=torch.float64),
                          torch.linspace(-1, 1, width, dtype=torch.float64), indexing="ij")
    basis = torch.stack([u, v, torch.ones_like(u)], dim=-1)  # (H, W, 3)
    coarse = basis[::FIT_STRIDE, ::FIT_STRIDE].reshape(-1, 3)  # (n, 3): the pixels fitted
    products = (coarse[:, :, None] * coarse[:, None, :]).reshape(-1, 9)  # (n, 9)
    seen = valid[:, ::FIT_STRIDE, ::FIT_STRIDE].reshape(batch, -1)  # (B, n)
    sampled_m = depth_m[:, ::FIT_STRIDE, ::FIT_STRIDE].reshape(batch, -1)  # (B, n)
    weights = seen.double()  # (B, n): the pixels the next fit reads
    coefficients = torch.zeros(batch, 3, dtype=torch.float64)
    for _ in range(REFITS):
        normal = (weights @ products).reshape(batch, 3, 3) + 1e-9 * torch.eye(3).double()
        coefficients = torch.linalg.solve(normal, (weights / sampled_m) @ coarse)  # (B, 3)
        plane_m = 1.0 / (coefficients @ coarse.T).clamp(min=1e-6)  # (B, n)
        inliers = seen & ((plane_m - sampled_m).abs() < INLIER_M)
        weights = torch.where(inliers.sum(dim=1, keepdim=True) >= 3, inliers.double(), weights)
    fitted = (seen.sum(dim=1) >= 3)[:, None, None]  # (B, 1, 1)
    plane_m = 1.0 / torch.einsum("hwk,bk->bhw", basis, coefficients).clamp(min=1e-6)
    rise = torch.where(valid & fitted, plane_m - depth_m, 0.0).clamp(-RISE_MOST_M, RISE_MOST_M)
    return rise.to(depths_m.dtype)  # (B, H, W)


def checked_depths(depths_m: np.ndarray | None, shape: tuple[int, int, int]) -> Tensor:
    """Depth images (B, H, W) [m] a depth-reading model was given, as a tensor.

    Refused, in one line naming ``depths_m``, where they are missing or of another ``shape``.
    """
    if depths_m is None or np.shape(depths_m) != shape:
        raise InvalidInputError("depths_m", None if depths_m is None else
                                f"shape {np.shape(depths_m)}", f"depth images of shape "
                                f"{shape} [m], for a kqv model that reads depth (depth_input = "
                                f"true or readout = 'range')")
    return torch.as_tensor(np.asarray(depths_m, dtype=np.float32))
