"""Obstacles from a depth camera: what stands on the table, as height fields for the checker.

A robot that plans from its own camera has, instead of object shapes, the points its depth
image shows. :func:`depth_obstacles` keeps those above the table in the workspace, splits them
into objects (Euclidean clustering), sets apart the target (the clusters in the vertical column
through the open fingers' box at the predicted grasp: objects do not stand on one another, so
what is above or below the fingers is the target's, a part of it that the arm, in view, splits
off included; :class:`~control.pick.PickRequest`'s ``target_obstacles``) and
raises each part to a :class:`~control.collision.HeightField`, solid from the table up; hidden
space is free or occupied as :class:`OccludedSpace` says. Why a height field, clusters and free
hidden space: ``docs/decisions/depth-obstacles.md``.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from scipy import ndimage, sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from control.collision import HeightField
from control.errors import InvalidInputError

MAX_SHADOW_SAMPLES = 400
"""Most samples along one ray's hidden stretch (a 2 m shadow at 5 mm cells)."""


class OccludedSpace(enum.Enum):
    """How the planner treats space the camera's view of the scene hides."""

    FREE = "free"  # only what is seen (and the space below it) is occupied
    OCCUPIED = "occupied"  # the space behind each seen surface, down to the table, is too,
    # and every ray without a measurement through the workspace, top to table


@dataclass(frozen=True)
class FingerBox:
    """The open fingers of a parallel gripper as one box in the TCP frame.

    The fingers close along the TCP's x axis and reach along its z axis (the approach); the box
    spans both fingers at an opening, from the finger roots to the fingertips.

    Args:
        tip_beyond_tcp_m: How far the fingertips reach past the TCP along z [m].
        length_m: Finger length along z [m].
        half_width_m: Half a finger's width along y [m].
        thickness_m: One finger's thickness along x [m].

    """

    tip_beyond_tcp_m: float
    length_m: float
    half_width_m: float
    thickness_m: float

    def __post_init__(self) -> None:
        for name in ("length_m", "half_width_m", "thickness_m"):
            if not getattr(self, name) > 0.0:
                raise InvalidInputError(name, getattr(self, name), "a length > 0 m")

    def box(self, T_world_tcp: pin.SE3, opening_m: float, margin_m: float
            ) -> tuple[pin.SE3, np.ndarray]:
        """The box's pose in the world and its half extents (3,) [m], grown by ``margin_m``."""
        half = np.array([opening_m / 2 + self.thickness_m, self.half_width_m,
                         self.length_m / 2]) + margin_m
        centre = pin.SE3(np.eye(3), np.array([0.0, 0.0, self.tip_beyond_tcp_m -
                                              self.length_m / 2]))
        return T_world_tcp * centre, half


@dataclass(frozen=True)
class GraspRegion:
    """Where the fingers will close: the grasp's TCP pose and the opening they approach with."""

    T_world_tcp: pin.SE3
    opening_m: float


@dataclass(frozen=True)
class DepthObstacleConfig:
    """How depth points become obstacles; see the module docstring.

    Args:
        fingers: The gripper's fingers (they mark the target's columns).
        x_range_m: The workspace along the world x axis [m]; points outside are dropped.
        y_range_m: The workspace along y [m].
        table_z_m: Height of the table top [m].
        min_height_m: Points lower than this above the table are the table [m]; thinner
            objects are invisible to the planner (a D435 at half a metre is good to a few mm).
        max_height_m: Points higher than this above the table are dropped [m].
        cell_m: Grid spacing [m]: about one pixel's footprint on the workspace; outlines are
            kept to half of it.
        cluster_m: Points closer than this belong to one object [m]: more than the points'
            spacing on a steep face or across an overhang, less than the gap between objects.
        target_margin_m: Grows the fingers' box whose points mark the target's clusters [m].
        occluded: How hidden space is treated.
        padding_m: Grows the obstacles' (not the target's) outlines by this much [m], rounded
            to whole cells: what the depth image's outline may fall short of the surface by
            (a pixel's footprint, the camera's calibration error), which the checker's margin
            alone does not cover.

    """

    fingers: FingerBox
    x_range_m: tuple[float, float]
    y_range_m: tuple[float, float]
    table_z_m: float = 0.0
    min_height_m: float = 0.01
    max_height_m: float = 0.5
    cell_m: float = 0.005
    cluster_m: float = 0.02
    target_margin_m: float = 0.005
    occluded: OccludedSpace = OccludedSpace.FREE
    padding_m: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x_range_m", "y_range_m"):
            low, high = getattr(self, name)
            if not (math.isfinite(low) and math.isfinite(high) and low < high):
                raise InvalidInputError(name, getattr(self, name), "(low, high) finite, low < high")
        if not 0.0 < self.min_height_m < self.max_height_m:
            raise InvalidInputError("min_height_m/max_height_m",
                                    (self.min_height_m, self.max_height_m), "0 < min < max")
        if not 0.0 < self.cell_m <= 0.1:
            raise InvalidInputError("cell_m", self.cell_m, "in (0, 0.1] m")
        if not self.cluster_m > 0.0:
            raise InvalidInputError("cluster_m", self.cluster_m, "> 0 m")
        for name in ("target_margin_m", "padding_m"):
            if not getattr(self, name) >= 0.0:
                raise InvalidInputError(name, getattr(self, name), ">= 0 m")
        if not isinstance(self.occluded, OccludedSpace):
            allowed = ", ".join(f"OccludedSpace.{member.name}" for member in OccludedSpace)
            raise InvalidInputError("occluded", self.occluded, f"one of {allowed}")


@dataclass(frozen=True)
class DepthObstacles:
    """The planner's view of a scene from one depth image.

    Args:
        obstacles: The height field of everything but the target (none if nothing is seen).
        target_obstacles: The target's clusters (none if the fingers close on no point).
        points: Depth points above the table inside the workspace.
        hidden_points: Samples added along rays behind seen surfaces and along rays without
            a measurement (``OCCUPIED`` only).
        unknown_rays: Rays without a measurement (pixels of depth 0) the caller gave.
        obstacle_cells: Grid vertices of ``obstacles`` above the table.
        target_cells: Grid vertices of ``target_obstacles`` above the table.
        obstacle_image: (H, W, 3): each pixel's point where it is an obstacle's (in the
            workspace, not the target's), NaN elsewhere: what a later frame that cannot see
            there remembers (``depth_obstacles``' ``remembered``).
        remembered_points: Points remembered from an earlier frame among ``obstacles``.

    """

    obstacles: tuple[HeightField, ...]
    target_obstacles: tuple[HeightField, ...]
    points: int
    hidden_points: int
    unknown_rays: int
    obstacle_cells: int
    target_cells: int
    obstacle_image: np.ndarray
    remembered_points: int = 0

    def to_record(self) -> dict[str, Any]:
        """The counts, for a trial record (``remembered_points`` where there were any)."""
        return {"points": self.points, "hidden_points": self.hidden_points,
                "unknown_rays": self.unknown_rays,
                "obstacle_cells": self.obstacle_cells, "target_cells": self.target_cells,
                **({"remembered_points": self.remembered_points}
                   if self.remembered_points else {})}


def depth_obstacles(points_world: np.ndarray, camera_position_m: np.ndarray,
                    config: DepthObstacleConfig, grasp: GraspRegion | None = None,
                    unknown_rays_world: np.ndarray | None = None,
                    remembered: np.ndarray | None = None) -> DepthObstacles:
    """Obstacles from a depth image's points (H, W, 3) in the world (NaN: no depth).

    With ``grasp``, the clusters its fingers close on are the target's; without, all is
    obstacle. ``camera_position_m`` is the optical centre the image was taken from.
    ``unknown_rays_world`` (K, 3): directions of the pixels without a measurement (a stereo
    shadow, too near): no point comes from them; with hidden space ``FREE`` they are free like
    all unseen space, with ``OCCUPIED`` their stretch through the workspace is an obstacle
    (never the target's: nothing says what is there). ``remembered`` (M, 3): obstacle points an
    earlier frame saw where this one has no depth (the arm in view hides them; an earlier
    :attr:`DepthObstacles.obstacle_image`): they stay obstacles, never the target's, as an
    occupancy map keeps what its sensor cannot see now.
    """
    points = np.asarray(points_world, dtype=float)
    if points.ndim != 3 or points.shape[2] != 3:
        raise InvalidInputError("points_world", f"shape {points.shape}", "shape (H, W, 3)")
    camera = np.asarray(camera_position_m, dtype=float)
    if camera.shape != (3,) or not np.all(np.isfinite(camera)):
        raise InvalidInputError("camera_position_m", camera_position_m, "three finite numbers")
    kept = _in_workspace(points, config)  # (H, W)
    seen = points[kept]  # (n, 3)
    memory = np.zeros((0, 3)) if remembered is None else np.asarray(remembered, dtype=float)
    if memory.ndim != 2 or memory.shape[1] != 3 or not np.all(np.isfinite(memory)):
        raise InvalidInputError("remembered", f"shape {memory.shape}",
                                "finite points of shape (M, 3)")
    labels = _clusters(seen, config.cluster_m)  # (n,)
    unknown = np.zeros((0, 3)) if unknown_rays_world is None else np.asarray(
        unknown_rays_world, dtype=float)
    if unknown.ndim != 2 or unknown.shape[1] != 3 or not np.all(np.isfinite(unknown)):
        raise InvalidInputError("unknown_rays_world", f"shape {unknown.shape}",
                                "finite directions of shape (K, 3)")
    hidden, hidden_labels = np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    if config.occluded is OccludedSpace.OCCUPIED:
        hidden, owners = _hidden_samples(seen, camera, config)
        hidden_labels = labels[owners]
        dark = _unknown_samples(unknown, camera, config)
        hidden = np.concatenate([hidden, dark])
        hidden_labels = np.concatenate([hidden_labels, np.full(len(dark), -1)])
    solid = np.concatenate([seen, hidden, memory])  # (n + m + M, 3)
    target = np.zeros(len(solid), dtype=bool)
    if grasp is not None:
        pose, half = config.fingers.box(grasp.T_world_tcp, grasp.opening_m, config.target_margin_m)
        level = seen.copy()  # each point brought to the box's height: the column through it
        level[:, 2] = pose.translation[2]
        inside = np.all(np.abs((level - pose.translation) @ pose.rotation) <= half, axis=1)
        target[:len(seen) + len(hidden)] = np.isin(np.concatenate([labels, hidden_labels]),
                                                   labels[inside])
    image = np.full(points.shape, np.nan)
    image[kept] = np.where(target[:len(seen), None], np.nan, seen)
    others, own = (_height_field(name, solid[mask], config, padding_m)
                   for name, mask, padding_m in (("depth", ~target, config.padding_m),
                                                 ("target", target, 0.0)))
    return DepthObstacles(
        obstacles=() if others is None else (others,),
        target_obstacles=() if own is None else (own,),
        points=len(seen), hidden_points=len(hidden), unknown_rays=len(unknown),
        obstacle_cells=_occupied(others), target_cells=_occupied(own),
        obstacle_image=image, remembered_points=len(memory),
    )


def _clusters(points: np.ndarray, distance_m: float) -> np.ndarray:
    """A cluster label per point (N,).

    Points closer than ``distance_m`` to each other, directly or through others, share one.
    """
    pairs = cKDTree(points).query_pairs(distance_m, output_type="ndarray")  # (P, 2)
    graph = sparse.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                              shape=(len(points), len(points)))
    return csgraph.connected_components(graph, directed=False)[1]


def _in_workspace(points: np.ndarray, config: DepthObstacleConfig) -> np.ndarray:
    """Whether each point (..., 3) lies in the workspace, above the table, below the limit."""
    (x0, x1), (y0, y1) = config.x_range_m, config.y_range_m
    x, y, height = points[..., 0], points[..., 1], points[..., 2] - config.table_z_m
    with np.errstate(invalid="ignore"):  # NaN (no depth) compares False: not kept
        return ((x >= x0) & (x <= x1) & (y >= y0) & (y <= y1) &
                (height > config.min_height_m) & (height < config.max_height_m))


def _hidden_samples(points: np.ndarray, camera: np.ndarray, config: DepthObstacleConfig
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Samples (M, 3) every half cell along each ray past its point, down to the table.

    Also the index of the point each sample came from (M,).
    """
    rise = camera[2] - points[:, 2]  # (n,); a point level with the camera hides nothing below
    source = np.flatnonzero(rise > 1e-6)
    beyond = (points[source, 2] - config.table_z_m) / rise[source]  # ray parameter to the table
    length_m = beyond * np.linalg.norm(points[source, :2] - camera[:2], axis=1)  # horizontal
    counts = np.clip(np.ceil(length_m / (config.cell_m / 2)), 1, MAX_SHADOW_SAMPLES).astype(int)
    owner = np.repeat(np.arange(len(source)), counts)  # (M,)
    step = np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts) + 1  # 1..k
    fraction = beyond[owner] * step / counts[owner]  # (M,)
    start = points[source[owner]]  # (M, 3)
    samples = start + fraction[:, None] * (start - camera)  # (M, 3)
    keep = _in_workspace(samples, config)
    return samples[keep], source[owner][keep]


def _unknown_samples(rays: np.ndarray, camera: np.ndarray, config: DepthObstacleConfig
                     ) -> np.ndarray:
    """Samples (M, 3) every half cell along each ray, from the workspace's top to the table."""
    down = rays[:, 2] < -1e-9  # a ray that never falls to the table crosses no workspace
    rays = rays[down]
    top, bottom = (config.table_z_m + config.max_height_m - camera[2],
                   config.table_z_m - camera[2])
    start = np.clip(top / rays[:, 2], 0.0, None)  # ray parameters (K,): the top, the table
    stop = bottom / rays[:, 2]
    length_m = (stop - start) * np.linalg.norm(rays, axis=1)
    counts = np.clip(np.ceil(length_m / (config.cell_m / 2)), 1, MAX_SHADOW_SAMPLES).astype(int)
    owner = np.repeat(np.arange(len(rays)), counts)  # (M,)
    step = np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts)  # 0..k-1
    fraction = start[owner] + (stop - start)[owner] * (step + 0.5) / counts[owner]
    samples = camera + fraction[:, None] * rays[owner]  # (M, 3)
    return samples[_in_workspace(samples, config)]


def _height_field(name: str, points: np.ndarray, config: DepthObstacleConfig,
                  padding_m: float = 0.0) -> HeightField | None:
    """The height field of points (N, 3), or None for no points.

    Each point raises the grid vertex nearest it to its height, so an outline stays within half
    a cell of the points; a grey closing over 3 x 3 vertices then fills the vertices a surface's
    points fell between (they lie up to a cell apart) without growing its outline; a grey
    dilation over a disc of ``padding_m`` (in whole cells) then grows it by that much.
    """
    if not len(points):
        return None
    pad = round(padding_m / config.cell_m)  # vertices
    nearest = np.rint(points[:, :2] / config.cell_m).astype(np.int64)  # (N, 2) as (x, y)
    first = nearest.min(axis=0) - 2 - pad  # empty vertices around, for the closing and padding
    index = nearest - first
    nx, ny = index.max(axis=0) + 3 + pad
    heights = np.zeros((ny, nx))  # (ny, nx) vertices, row = y
    np.maximum.at(heights, (index[:, 1], index[:, 0]), points[:, 2] - config.table_z_m)
    heights = ndimage.grey_closing(heights, size=(3, 3), mode="constant", cval=0.0)
    if pad:
        y, x = np.mgrid[-pad:pad + 1, -pad:pad + 1]
        heights = ndimage.grey_dilation(heights, footprint=x**2 + y**2 <= (pad + 0.5) ** 2,
                                        mode="constant", cval=0.0)
    origin = first * config.cell_m
    return HeightField(name, (float(origin[0]), float(origin[1])), config.cell_m, heights,
                       config.table_z_m)


def _occupied(field: HeightField | None) -> int:
    """How many of a field's vertices stand above the table."""
    return 0 if field is None else int(np.count_nonzero(field.heights_m))
