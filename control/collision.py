"""Collision checking with Pinocchio's geometry model (coal).

The robot is checked against itself and against obstacles handed in as plain shapes (the
table, the objects that are not the target).
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
        self.obstacles: tuple[Obstacle, ...] = ()
        self._rebuild()

    def set_obstacles(self, obstacles: Iterable[Obstacle]) -> None:
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
        """Checks one configuration."""
        self.robot.check_shape(q)
        hit = pin.computeCollisions(
            self.robot.model, self._data, self._geom, self._geom_data, q, stop_at_first
        )
        if not hit:
            return FREE
        pairs = []
        for pair, result in zip(self._geom.collisionPairs, self._geom_data.collisionResults,
                                strict=True):
            if result.isCollision():
                pairs.append((self._names[pair.first], self._names[pair.second]))
                if stop_at_first:
                    break
        return CollisionReport(in_collision=True, pairs=tuple(pairs))

    def check_path(self, configurations: Sequence[np.ndarray] | np.ndarray) -> CollisionReport:
        """Checks every configuration of a sampled path; reports the first colliding sample."""
        for index, q in enumerate(configurations):
            report = self.check(np.asarray(q))
            if report.in_collision:
                return CollisionReport(True, report.pairs, sample_index=index)
        return FREE

    def clearance_m(self, q: np.ndarray) -> tuple[float, tuple[str, str]]:
        """Smallest distance between any checked pair [m] and that pair (negative: penetration)."""
        self.robot.check_shape(q)
        pin.computeDistances(self.robot.model, self._data, self._geom, self._geom_data, q)
        distances = [r.min_distance for r in self._geom_data.distanceResults]
        best = int(np.argmin(distances))
        pair = self._geom.collisionPairs[best]
        return float(distances[best]), (self._names[pair.first], self._names[pair.second])
