"""Collision checking with Pinocchio's geometry model (coal).

The robot is checked against itself and against obstacles handed in as plain shapes (the
table, a box in the way) or as height fields (what a depth camera saw standing on the table,
see :mod:`control.depth_obstacles`).
"""

from __future__ import annotations

import contextlib
import enum
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

from control.errors import InvalidInputError
from control.robot_model import RobotModel


class ShapeKind(enum.Enum):
    """Primitive obstacle shapes."""

    BOX = "box"  # size = full edge lengths (x, y, z) [m]
    CYLINDER = "cylinder"  # size = (radius, length along the shape's z axis) [m]
    SPHERE = "sphere"  # size = (radius,) [m]


_SIZE_LENGTH = {ShapeKind.BOX: 3, ShapeKind.CYLINDER: 2, ShapeKind.SPHERE: 1}


@dataclass(frozen=True)
class Obstacle:
    """A rigid primitive in the world frame.

    Args:
        name: Shown in collision reports (``"table"``, ``"mug/wall_3"``).
        kind: The primitive.
        size: Dimensions in [m], as :class:`ShapeKind` documents.
        T_world_shape: Pose of the shape's centre in the world frame.

    """

    name: str
    kind: ShapeKind
    size: tuple[float, ...]
    T_world_shape: pin.SE3

    def __post_init__(self) -> None:
        if len(self.size) != _SIZE_LENGTH[self.kind] or min(self.size) <= 0.0:
            raise InvalidInputError(
                f"obstacle {self.name!r} size", self.size,
                f"{_SIZE_LENGTH[self.kind]} positive lengths in [m] for a {self.kind.value}",
            )

    def geometry(self) -> coal.ShapeBase:
        """The coal shape of this obstacle."""
        if self.kind is ShapeKind.BOX:
            return coal.Box(*self.size)
        if self.kind is ShapeKind.CYLINDER:
            return coal.Cylinder(*self.size)
        return coal.Sphere(self.size[0])


@dataclass(frozen=True, eq=False)
class HeightField:
    """Occupied space over a horizontal grid: each cell solid from ``base_z_m`` up to its height.

    A depth camera looking down at a table sees surfaces; a height field keeps them with the
    space below each one filled (objects stand on the table). Heights are given at the grid's
    vertices, so a cell is solid up to the surface through its four corners (coal's
    ``HeightFieldOBBRSS``).

    Args:
        name: Shown in collision reports (``"depth"``, ``"target"``).
        origin_xy_m: World (x, y) of vertex ``[0, 0]``, the grid's corner at the least x and y.
        cell_m: Distance between neighbouring vertices [m].
        heights_m: (ny, nx) vertex heights [m] above ``base_z_m``, row index along +y, column
            index along +x; at least 2 x 2.
        base_z_m: World height of the field's floor [m] (the table top).

    """

    name: str
    origin_xy_m: tuple[float, float]
    cell_m: float
    heights_m: np.ndarray  # (ny, nx)
    base_z_m: float = 0.0

    def __post_init__(self) -> None:
        heights = np.asarray(self.heights_m, dtype=float)
        if heights.ndim != 2 or min(heights.shape) < 2:
            raise InvalidInputError(f"height field {self.name!r} heights_m", heights.shape,
                                    "a 2-D array of at least 2 x 2 vertex heights")
        if not np.all(np.isfinite(heights)) or heights.min() < 0.0:
            raise InvalidInputError(f"height field {self.name!r} heights_m",
                                    "negative or non-finite values", "finite heights >= 0 m")
        if not self.cell_m > 0.0:
            raise InvalidInputError(f"height field {self.name!r} cell_m", self.cell_m, "> 0 m")
        object.__setattr__(self, "heights_m", heights)

    @property
    def size_m(self) -> tuple[float, float]:
        """Extent along x and y [m]."""
        ny, nx = self.heights_m.shape
        return (nx - 1) * self.cell_m, (ny - 1) * self.cell_m

    @property
    def T_world_shape(self) -> pin.SE3:
        """Pose of the grid's centre on its floor (coal centres a height field on its origin)."""
        x, y = self.origin_xy_m
        width_m, depth_m = self.size_m
        return pin.SE3(np.eye(3), np.array([x + width_m / 2, y + depth_m / 2, self.base_z_m]))

    def geometry(self) -> coal.HeightFieldOBBRSS:
        """The coal height field (coal's row 0 lies at +y, so the rows are flipped)."""
        width_m, depth_m = self.size_m
        heights = np.ascontiguousarray(self.heights_m[::-1])
        return coal.HeightFieldOBBRSS(width_m, depth_m, heights, 0.0)


AnyObstacle = Obstacle | HeightField
"""What a :class:`CollisionChecker` checks the robot against."""


@dataclass(frozen=True)
class CollisionReport:
    """The outcome of a collision query.

    Args:
        in_collision: Whether any checked pair overlaps (closer than the margin).
        pairs: The colliding pairs as (link or obstacle name, link or obstacle name); with
            ``stop_at_first`` only the first found.
        sample_index: For path checks, the first colliding sample; None otherwise.

    """

    in_collision: bool
    pairs: tuple[tuple[str, str], ...] = ()
    sample_index: int | None = None

    def describe(self) -> str:
        """One line for logs and trial records."""
        if not self.in_collision:
            return "collision-free"
        where = f" at sample {self.sample_index}" if self.sample_index is not None else ""
        return "collision" + where + ": " + "; ".join(f"{a} vs {b}" for a, b in self.pairs)


FREE = CollisionReport(in_collision=False)


class CollisionChecker:
    """Checks configurations and sampled paths of a robot for collisions.

    Robot-robot pairs are all pairs of the URDF's collision geometry minus those an SRDF
    disables. Every moving link is checked against every obstacle; links fixed to the root
    (the YuMi's body, which stands on the table) are not.

    Args:
        robot: The kinematic model (its joint order defines ``q``).
        urdf_path: The URDF the collision geometry is read from.
        srdf_path: Optional SRDF with ``disable_collisions`` entries.
        margin_m: Security margin in [m]: shapes closer than this count as colliding.

    """

    def __init__(
        self,
        robot: RobotModel,
        urdf_path: str | Path,
        srdf_path: str | Path | None = None,
        margin_m: float = 0.002,
    ) -> None:
        if margin_m < 0.0:
            raise InvalidInputError("margin_m", margin_m, "a margin >= 0 m")
        self.robot = robot
        self.margin_m = margin_m
        self._robot_geom = pin.buildGeomFromUrdf(
            robot.model, str(urdf_path), pin.GeometryType.COLLISION
        )
        for geometry_object in self._robot_geom.geometryObjects:
            # A mesh becomes its convex hull: coal collides no mesh with a depth height field,
            # and a hull is what PyBullet collides the same mesh as. (The YuMi has none.)
            shape = geometry_object.geometry
            if type(shape).__name__.startswith("BVHModel"):
                shape.buildConvexRepresentation(False)
                geometry_object.geometry = shape.convex
        self._robot_geom.addAllCollisionPairs()
        if srdf_path is not None:
            pin.removeCollisionPairs(robot.model, self._robot_geom, str(srdf_path))
        self._self_pairs = [
            (p.first, p.second) for p in self._robot_geom.collisionPairs
        ]
        self._link_names = [
            robot.model.frames[g.parentFrame].name for g in self._robot_geom.geometryObjects
        ]
        self._moving = [
            i for i, g in enumerate(self._robot_geom.geometryObjects) if g.parentJoint != 0
        ]
        self.obstacles: tuple[AnyObstacle, ...] = ()
        self._rebuild()

    def set_obstacles(self, obstacles: Iterable[AnyObstacle]) -> None:
        """Replaces the obstacles checked against the robot's moving links."""
        self.obstacles = tuple(obstacles)
        names = [o.name for o in self.obstacles]
        if len(set(names)) != len(names):
            raise InvalidInputError("obstacle names", names, "unique names")
        self._rebuild()

    def _rebuild(self) -> None:
        geom = self._robot_geom.copy()
        geom.removeAllCollisionPairs()
        for first, second in self._self_pairs:
            geom.addCollisionPair(pin.CollisionPair(first, second))
        for obstacle in self.obstacles:
            index = geom.addGeometryObject(
                pin.GeometryObject(
                    f"obstacle:{obstacle.name}", 0, 0, obstacle.T_world_shape, obstacle.geometry()
                )
            )
            for link_geometry in self._moving:
                geom.addCollisionPair(pin.CollisionPair(link_geometry, index))
        self._geom = geom
        self._geom_data = pin.GeometryData(geom)
        for request in self._geom_data.collisionRequests:
            request.security_margin = self.margin_m
        self._names = self._link_names + [o.name for o in self.obstacles]
        self._data = self.robot.model.createData()
        # A dynamic AABB tree culls the pairs whose boxes are apart before the narrow phase;
        # it answers as the pair-by-pair check does (the margin, the SRDF's and ignoring()'s
        # inactive pairs included; docs/control.md), about three times faster.
        self._broadphase = pin.BroadPhaseManager_DynamicAABBTreeCollisionManager(
            self.robot.model, geom, self._geom_data)

    @contextlib.contextmanager
    def ignoring(self, obstacle_names: Iterable[str]) -> Iterator[None]:
        """Checks inside the block skip the pairs that involve the named obstacles.

        E.g. the pick's target, which the fingers close around once the hand descends.
        """
        names = set(obstacle_names)
        unknown = names - {o.name for o in self.obstacles}
        if unknown:
            raise InvalidInputError("obstacle_names", sorted(unknown),
                                    "names of obstacles set with set_obstacles")
        skipped = [i for i, pair in enumerate(self._geom.collisionPairs)
                   if self._names[pair.second] in names and pair.second >= len(self._link_names)]
        for index in skipped:
            self._geom_data.deactivateCollisionPair(index)
        try:
            yield
        finally:
            for index in skipped:
                self._geom_data.activateCollisionPair(index)

    @property
    def pair_count(self) -> int:
        """Number of pairs each query checks."""
        return len(self._geom.collisionPairs)

    def check(self, q: np.ndarray, stop_at_first: bool = True) -> CollisionReport:
        """Checks one configuration.

        The broad phase clears a free configuration; where it finds a collision, the
        pair-by-pair check confirms it and names the pairs (the broad phase leaves the pairs it
        culled unwritten).
        """
        self.robot.check_shape(q)
        if not pin.computeCollisions(self.robot.model, self._data, self._broadphase, q, True) \
                or not pin.computeCollisions(self.robot.model, self._data, self._geom,
                                             self._geom_data, q, stop_at_first):
            return FREE
        pairs = []
        for pair, result in zip(self._geom.collisionPairs, self._geom_data.collisionResults,
                                strict=True):
            if result.isCollision():
                pairs.append((self._names[pair.first], self._names[pair.second]))
                if stop_at_first:
                    break
        return CollisionReport(in_collision=True, pairs=tuple(pairs))

    def check_path(self, configurations: Sequence[np.ndarray] | np.ndarray,
                   step_rad: float | None = None) -> CollisionReport:
        """Checks a sampled path; reports the first colliding sample (its index in the path).

        Every configuration, or with ``step_rad`` those :func:`thinned_samples` keeps: no joint
        moves more than ``step_rad`` between two checked ones.
        """
        path = np.asarray(configurations, dtype=float)
        index = np.arange(len(path)) if step_rad is None or len(path) < 2 else thinned_samples(
            path, step_rad)
        for k in index:
            report = self.check(path[k])
            if report.in_collision:
                return CollisionReport(True, report.pairs, sample_index=int(k))
        return FREE

    def clearance_m(self, q: np.ndarray) -> tuple[float, tuple[str, str]]:
        """Smallest distance between any checked pair [m] and that pair (negative: penetration)."""
        self.robot.check_shape(q)
        pin.computeDistances(self.robot.model, self._data, self._geom, self._geom_data, q)
        distances = [r.min_distance for r in self._geom_data.distanceResults]
        best = int(np.argmin(distances))
        pair = self._geom.collisionPairs[best]
        return float(distances[best]), (self._names[pair.first], self._names[pair.second])


def thinned_samples(positions: np.ndarray, step_rad: float) -> np.ndarray:
    """Indices of the samples (N, n) to check, no joint moving ``step_rad`` between them.

    The first, every sample after which the summed largest joint change since the last checked
    one would pass ``step_rad``, and the last; a single step longer than ``step_rad`` keeps
    both its samples (every sample is checked there, as without thinning).
    """
    moved = np.max(np.abs(np.diff(positions, axis=0)), axis=1)  # (N - 1,)
    keep, travelled = [0], 0.0
    for k, step in enumerate(moved, start=1):
        travelled += float(step)
        if travelled > step_rad:  # sample k - 1 is the last within the step
            if keep[-1] != k - 1:
                keep.append(k - 1)
            travelled = float(step)
    last = len(positions) - 1
    return np.array(keep + ([last] if keep[-1] != last else []), dtype=int)
