"""Torch pieces the learnable models share: coordinates, CoordConv, Softmax2D, MLP, label scaling.

Coordinates inside a model are normalised: ``x`` runs from -1 at the image's left edge to +1 at
its right edge, ``y`` from -1 at the top edge to +1 at the bottom edge, so a feature map of any
size covers the same [-1, 1]² square and a cell's coordinate is its centre. Pixel coordinates
follow :meth:`sim.world.head_camera.HeadCamera.project`: integers are pixel centres,
``image[v, u]``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import torch
from torch import Tensor, nn

from perception.interface import InvalidInputError

MIN_LABEL_SCALE_M = 0.01
"""Smallest half-range :class:`LabelScaler` divides by [m], so a constant label stays finite."""


def coordinate_grid(height: int, width: int, device: torch.device | str = "cpu") -> Tensor:
    """The (x, y) coordinate of each cell's centre, (2, height, width), in [-1, 1]."""
    y = (torch.arange(height, device=device, dtype=torch.float32) * 2 + 1) / height - 1  # (h,)
    x = (torch.arange(width, device=device, dtype=torch.float32) * 2 + 1) / width - 1  # (w,)
    grid_y, grid_x = torch.meshgrid(y, x, indexing="ij")  # (h, w) each
    return torch.stack([grid_x, grid_y])  # (2, h, w)


def normalised_to_pixels(points: Tensor, height_px: int, width_px: int) -> Tensor:
    """Maps normalised (x, y) in [-1, 1] (..., 2) to pixel (u, v) (..., 2) of an H x W image."""
    size = points.new_tensor([width_px, height_px])  # (2,)
    return (points + 1) * 0.5 * size - 0.5  # (..., 2)


def pixels_to_normalised(points_px: Tensor, height_px: int, width_px: int) -> Tensor:
    """The inverse of :func:`normalised_to_pixels`."""
    size = points_px.new_tensor([width_px, height_px])  # (2,)
    return (points_px + 0.5) / size * 2 - 1  # (..., 2)


def add_coordinates(features: Tensor) -> Tensor:
    """``features`` (B, C, h, w) with the x and y coordinate channels appended: (B, C + 2, h, w)."""
    batch, _, height, width = features.shape
    grid = coordinate_grid(height, width, features.device).expand(batch, -1, -1, -1)  # (B, 2, h, w)
    return torch.cat([features, grid], dim=1)  # (B, C + 2, h, w)


class CoordConv(nn.Module):
    """A convolution (+ ReLU) whose output gets the coordinate channels appended (Liu et al. 2018).

    Concatenating the coordinates after the layer, as the paper does after each of FCN1's three
    layers, lets the next layer, and the dot product with a Query, know where a feature lies.
    """

    def __init__(self, in_channels: int, out_channels: int, kernel_size: int, stride: int,
                 activation: bool = True, dilation: int = 1) -> None:
        super().__init__()
        self.conv = nn.Conv2d(in_channels, out_channels, kernel_size, stride,
                              dilation * (kernel_size // 2), dilation)
        self.activation = activation

    def forward(self, x: Tensor) -> Tensor:
        """(B, in, H, W) -> (B, out + 2, h, w)."""
        return add_coordinates(self.features(x))

    def features(self, x: Tensor, coordinates_in: bool = False) -> Tensor:
        """The layer's output before its coordinates are appended: (B, out, h, w).

        ``coordinates_in``: ``x`` (B, in - 2, H, W) lacks the two coordinate channels its last
        weights read (a :class:`CoordConvStack`'s layer after the first). The convolution is
        linear, so their share is the coordinates convolved once, (1, out, h, w), added to
        every image's: the same sum as over the concatenated input (zero padding alike), without
        copying a batch of (B, in, H, W) maps to concatenate them.
        """
        conv = self.conv
        if not coordinates_in:
            out = conv(x)
        else:
            weight = conv.weight  # (out, in, k, k), the coordinates' two input channels last
            grid = coordinate_grid(x.shape[-2], x.shape[-1], x.device)[None].to(x.dtype)
            out = nn.functional.conv2d(x, weight[:, :-2], conv.bias, conv.stride, conv.padding,
                                       conv.dilation) + nn.functional.conv2d(
                grid, weight[:, -2:], None, conv.stride, conv.padding, conv.dilation)
        return torch.relu(out) if self.activation else out


class CoordConvStack(nn.Sequential):
    """:class:`CoordConv` layers in a row, each reading the one before with its coordinates.

    The same function (and parameters, named as in an ``nn.Sequential``) as running the layers
    one by one, but a layer's coordinate channels reach the next as a share of its output
    (:meth:`CoordConv.features`) rather than as channels concatenated to every map: a profile
    of a ``kqv`` training step on one CPU thread put a sixth of it in those concatenations and
    the copies back to channels-last after them (``docs/decisions/speed.md``;
    ``benchmarks/bench_train.py`` times the step both ways).
    """

    def forward(self, x: Tensor) -> Tensor:
        """(B, in, H, W) -> (B, out + 2, h, w): the last layer's output with its coordinates."""
        for number, layer in enumerate(self):
            x = cast(CoordConv, layer).features(x, coordinates_in=number > 0)
        return add_coordinates(x)


def unit(x: Tensor, dim: int) -> Tensor:
    """``x`` scaled to unit length along ``dim`` (as ``F.normalize``, eps 1e-12).

    Written as a reciprocal square root of the summed squares: along the channels of a Key map
    it is faster on the CPU, forward and backward, than ``F.normalize``'s vector norm
    (``benchmarks/bench_train.py`` times both), and the Keys are normalised at every step.
    """
    return x * torch.rsqrt(x.square().sum(dim, keepdim=True).clamp_min(1e-24))


def softmax2d(logits: Tensor, temperature: float = 1.0) -> Tensor:
    """Softmax over each map's h·w cells, (B, q, h, w) -> (B, q, h, w); each map sums to 1."""
    batch, heads, height, width = logits.shape
    flat = (logits / temperature).reshape(batch, heads, height * width)  # (B, q, h*w)
    return torch.softmax(flat, dim=-1).reshape(batch, heads, height, width)  # (B, q, h, w)


def focus(heatmaps: Tensor, box_cells: int, window_cells: int) -> Tensor:
    """Each heatmap kept inside a window around its densest part, renormalised: (B, q, h, w).

    The densest part is the cell whose ``box_cells``-wide square (odd; clipped at the border)
    holds the most of the map's mass; the window is the square of half-width ``window_cells``
    around it. A map whose mass is split between two objects keeps the one holding more.
    """
    batch, heads, height, width = heatmaps.shape
    maps = heatmaps.reshape(batch * heads, 1, height, width)
    box = box_cells | 1
    mass = nn.functional.avg_pool2d(maps, box, 1, box // 2, count_include_pad=False) \
        if box > 1 else maps  # (B q, 1, h, w)
    densest = mass.flatten(1).argmax(dim=1)  # (B q,)
    rows = torch.arange(height, device=heatmaps.device).view(1, height, 1)
    cols = torch.arange(width, device=heatmaps.device).view(1, 1, width)
    reach = max(window_cells, box // 2)  # the window holds the densest square's mass
    inside = ((rows - (densest // width).view(-1, 1, 1)).abs() <= reach) & \
        ((cols - (densest % width).view(-1, 1, 1)).abs() <= reach)  # (B q, h, w)
    kept = maps.squeeze(1) * inside
    kept = kept / kept.sum(dim=(-2, -1), keepdim=True)
    return kept.reshape(batch, heads, height, width)


def spatial_expectation(heatmaps: Tensor, values: Tensor) -> Tensor:
    """Σ_uv M(u, v) V(u, v), the expectation of values under each heatmap.

    Heatmaps (B, q, h, w), values (B, C, h, w) or (C, h, w) shared by the batch -> (B, q, C).
    """
    if values.dim() == 3:
        return torch.einsum("bqhw,chw->bqc", heatmaps, values)  # (B, q, C)
    return torch.einsum("bqhw,bchw->bqc", heatmaps, values)  # (B, q, C)


class MLP(nn.Sequential):
    """Linear layers with ELU between them, ``sizes = (in, hidden..., out)``; a linear output."""

    def __init__(self, sizes: tuple[int, ...]) -> None:
        layers: list[nn.Module] = []
        for index, (size_in, size_out) in enumerate(itertools.pairwise(sizes)):
            layers.append(nn.Linear(size_in, size_out))
            if index < len(sizes) - 2:
                layers.append(nn.ELU())
        super().__init__(*layers)


def images_to_tensor(images: np.ndarray, device: torch.device | str = "cpu") -> Tensor:
    """uint8 images (B, H, W, 3) RGB -> float32 (B, 3, H, W) in [0, 1]; models normalise further."""
    images = np.ascontiguousarray(images)
    if not images.flags.writeable:  # a served frame's buffer: torch wants memory it may write
        images = images.copy()
    tensor = torch.from_numpy(images).to(device)  # (B, H, W, 3) uint8
    return tensor.permute(0, 3, 1, 2).float().div_(255.0)  # (B, 3, H, W)


def normalise_images(images: Tensor, per_image: bool = False) -> Tensor:
    """Images (B, 3, H, W) in [0, 1] -> roughly zero mean and unit spread per channel.

    Fixed: ``(images - 0.5) / 0.25`` for every image alike. ``per_image``: each image's channels
    standardised by their own mean and spread, so a scene under dimmer or brighter light (every
    pixel scaled alike, as PyBullet's renderer scales them) reads the same.
    """
    if not per_image:
        return (images - 0.5) / 0.25
    mean = images.mean(dim=(-2, -1), keepdim=True)  # (B, 3, 1, 1)
    centred = images - mean  # (B, 3, H, W)
    # The sample standard deviation, as Tensor.std, written as its two passes: on images
    # channels-last in memory (as images_to_tensor gives them) half the time of Tensor.std.
    cells = images.shape[-2] * images.shape[-1]
    spread = (centred.square().sum(dim=(-2, -1), keepdim=True) / max(cells - 1, 1)).sqrt()
    return centred / spread.clamp(min=1e-3)  # (B, 3, H, W)


@dataclass(frozen=True)
class LabelScaler:
    """Maps positions [m] to the network's scale and back: ``(p - centre_m) / scale_m``.

    The centre is the middle of the training labels' range per axis; the scale is the largest
    half-range over the three axes, so every training position lands in [-1, 1] (the label
    scaled to the workspace) while the loss stays proportional to the Euclidean error in metres,
    the quantity the paper reports. Kept in a checkpoint's ``config.json``.
    """

    centre_m: tuple[float, float, float]
    scale_m: float

    def __post_init__(self) -> None:
        if len(self.centre_m) != 3 or not all(math.isfinite(c) for c in self.centre_m):
            raise InvalidInputError("centre_m", self.centre_m, "3 finite values [m]")
        if not (math.isfinite(self.scale_m) and self.scale_m >= MIN_LABEL_SCALE_M):
            raise InvalidInputError("scale_m", self.scale_m, f"a finite value >= "
                                    f"{MIN_LABEL_SCALE_M} m")

    @classmethod
    def fit(cls, positions_m: np.ndarray) -> LabelScaler:
        """The scaler of training positions (..., 3) [m]."""
        flat = np.asarray(positions_m, dtype=np.float64).reshape(-1, 3)  # (N, 3)
        low, high = flat.min(axis=0), flat.max(axis=0)  # (3,)
        half = float(max((high - low).max() / 2, MIN_LABEL_SCALE_M))
        return cls(tuple(float(c) for c in (low + high) / 2), half)  # type: ignore[arg-type]

    def normalise(self, positions_m: Tensor) -> Tensor:
        """Positions (..., 3) [m] -> network scale (..., 3)."""
        return (positions_m - positions_m.new_tensor(self.centre_m)) / self.scale_m

    def denormalise(self, scaled: Tensor) -> Tensor:
        """Network scale (..., 3) -> positions (..., 3) [m]."""
        return scaled * self.scale_m + scaled.new_tensor(self.centre_m)

    def to_json(self) -> dict[str, Any]:
        """The scaler as JSON-able data."""
        return {"centre_m": list(self.centre_m), "scale_m": self.scale_m}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> LabelScaler:
        """The scaler :meth:`to_json` wrote."""
        return cls(tuple(float(c) for c in data["centre_m"]),  # type: ignore[arg-type]
                   float(data["scale_m"]))
