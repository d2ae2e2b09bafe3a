"""The rise above the table: what a depth-reading model sees of the objects' shapes."""

from __future__ import annotations

import numpy as np
import torch

from perception.models.rise import RISE_MOST_M, rise_above_table


def tilted_table(inverse_m: float = 1.6, height: int = 48, width: int = 64) -> np.ndarray:
    """Depth [m] of a plane seen at a slant: inverse depth linear in the pixel coordinates."""
    v, u = np.mgrid[0:height, 0:width]
    return (1.0 / (inverse_m + 0.004 * u + 0.006 * v)).astype(np.float32)


def test_the_table_reads_zero_and_a_box_its_rise_missing_depth_zero():
    depth = tilted_table()
    depth[10:20, 30:42] -= 0.05  # a box 5 cm nearer than the table behind it
    depth[30:34, 5:9] = 0.0  # a stereo shadow: no measurement
    depth[40:44, 50:54] = np.inf  # nothing within range
    rise = rise_above_table(torch.from_numpy(depth)[None])[0].numpy()
    box = np.zeros_like(depth, dtype=bool)
    box[10:20, 30:42] = True
    np.testing.assert_allclose(rise[box], 0.05, atol=1e-4)
    assert np.abs(rise[~box]).max() < 1e-4  # table, the shadow and the far pixels alike


def test_each_image_fits_its_own_table_and_an_image_without_depth_reads_flat():
    near, far = tilted_table(), tilted_table(1.2)  # two tables, two images
    far[5:15, 5:15] -= RISE_MOST_M + 0.1  # a stray block nearer than any object stands
    empty = np.zeros_like(near)
    rise = rise_above_table(torch.from_numpy(np.stack([near, far, empty]))).numpy()
    assert np.abs(rise[0]).max() < 1e-4
    assert rise[1, 5:15, 5:15].max() == np.float32(RISE_MOST_M)  # clipped
    assert np.abs(rise[1, 20:, 20:]).max() < 1e-4
    assert not rise[2].any()
