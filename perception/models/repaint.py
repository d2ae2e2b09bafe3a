"""Objects repainted with random patterns in the images a kqv model's Value map reads in training.

In a world of many prints, a model that learned an object's turn from its print's edges (the
stripes of its training sponges) reads a print never seen as a turn. Painting every object in
a random pattern (domain randomisation of textures: Tobin et al., IROS 2017) leaves its outline
as the one cue that holds. Objects are found by their rise above the table
(:mod:`perception.models.rise`), so no mask is needed. Only the Value map's copy of an image is
repainted (``KqvConfig.repaint``): the Key still sees the colours that tell a target from its
unfinished-wood twin, and the heads learn to read a pose from the shape.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import Tensor

from perception.models.rise import rise_above_table

OBJECT_RISE_M = 0.01
"""A pixel rising this far above the table is an object's [m]: above the D435's depth noise
(a few millimetres at 0.5-0.8 m) and below the flattest object (the 3.5 cm sponge)."""
NOISE_CELLS = (4, 16)
"""A noise pattern is random colours on a grid of this many cells a side, drawn per image,
smoothly interpolated: blotches from a quarter of the image to a few pixels across."""
STRIPE_PERIOD_PX = (3.0, 16.0)
"""A stripe pattern's period [px], drawn per image, at a random angle."""


class Repaint:
    """Repaints the objects of a random share of each batch; its own seeded generator.

    Args:
        probability: The share of images repainted, in (0, 1].
        seed: Seeds the choice of images and patterns (training stays reproducible).

    """

    def __init__(self, probability: float, seed: int) -> None:
        self.probability = probability
        self.generator = torch.Generator().manual_seed(seed)

    def __call__(self, images: Tensor, depths_m: Tensor) -> Tensor:
        """Images (B, 3, H, W) in [0, 1] with their depth (B, H, W) -> repainted copies."""
        batch, _, height, width = images.shape
        chosen = torch.rand(batch, generator=self.generator) < self.probability  # (B,)
        if not chosen.any():
            return images
        objects = rise_above_table(depths_m) > OBJECT_RISE_M  # (B, H, W)
        mask = (objects & chosen[:, None, None].to(objects.device))[:, None]  # (B, 1, H, W)
        patterns = torch.where(torch.rand(batch, 1, 1, 1, generator=self.generator) < 0.5,
                               self._noise(batch, height, width),
                               self._stripes(batch, height, width)).to(images)
        return torch.where(mask, patterns, images)

    def _noise(self, batch: int, height: int, width: int) -> Tensor:
        """Smooth random colour blotches (B, 3, H, W), a grid size drawn per image."""
        low, high = NOISE_CELLS
        out = torch.empty(batch, 3, height, width)
        for b, cells in enumerate(torch.randint(low, high + 1, (batch,),
                                                generator=self.generator).tolist()):
            grid = torch.rand(1, 3, cells, cells, generator=self.generator)
            out[b] = F.interpolate(grid, size=(height, width), mode="bilinear",
                                   align_corners=False)[0]
        return out

    def _stripes(self, batch: int, height: int, width: int) -> Tensor:
        """Stripes of two random colours (B, 3, H, W), at a random period and angle each."""
        low, high = STRIPE_PERIOD_PX
        period = low + (high - low) * torch.rand(batch, generator=self.generator)  # (B,)
        angle = math.pi * torch.rand(batch, generator=self.generator)  # (B,)
        v, u = torch.meshgrid(torch.arange(height, dtype=torch.float32),
                              torch.arange(width, dtype=torch.float32), indexing="ij")
        along = (u[None] * torch.cos(angle)[:, None, None] +
                 v[None] * torch.sin(angle)[:, None, None])  # (B, H, W) [px]
        share = (torch.sin(2 * math.pi * along / period[:, None, None]) > 0).float()[:, None]
        first, second = (torch.rand(batch, 3, 1, 1, generator=self.generator) for _ in range(2))
        return share * first + (1 - share) * second  # (B, 3, H, W)
