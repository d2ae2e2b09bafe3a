"""What the gripper needs to close on a target, taken from what the model stated about it.

A model's :class:`~perception.interface.Target` may name the object type it believes it sees,
or an opening width. A type brings its catalog grasp: the opening, the pre-grasp distance and
the symmetric alternatives a planner may fall back on (a bottle taken from another side). An
opening alone sets the opening. A model that states neither gets :data:`DEFAULT_GRIP`: the
gripper fully open, backed off as far as every catalog grasp is, no alternatives; it suits
every object of the catalog, whose grasps all open fully (``benchmarks/bench_pick_variants.py``
measures it). Nothing here reads the simulator: a grip is what the robot knows before it moves.

The catalog states its grasps for the YuMi's hand (50 mm at most); every one of them opens it
fully, for the most room for a grasp off by a few millimetres or degrees. On a hand with a
wider stroke (the Panda's 80 mm) such a grasp opens that hand fully: a sponge grasp turned 40-50
degrees off misses with the Panda's fingers 50 mm apart and holds with them 80 mm apart
(docs/decisions/robots.md).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, replace
from typing import Any

from perception.interface import Target
from perception.objects.catalog import MAX_OPENING_M, ObjectSpec, catalog_names, get_object_spec
from perception.objects.grasps import symmetric_alternatives
from perception.poses import Pose
from sim.errors import InvalidInputError

DEFAULT_PREGRASP_DISTANCE_M = 0.08
"""Back-off of the default grip's pre-grasp [m]: every catalog grasp's."""


class GripSource(enum.Enum):
    """Where a grip's opening and pre-grasp came from."""

    OBJECT_TYPE = "object_type"  # the catalog grasp of the type the model named
    OPENING = "opening"  # the opening the model stated, the default pre-grasp
    DEFAULT = "default"  # the model stated nothing: :data:`DEFAULT_GRIP`


@dataclass(frozen=True)
class Grip:
    """How the gripper approaches and closes on one target.

    Args:
        opening_m: Finger gap to approach with [m].
        pregrasp_distance_m: How far back along the approach the pre-grasp lies [m].
        source: Where the values came from.
        spec: The catalog entry of the type the model named, None if it named none.

    """

    opening_m: float
    pregrasp_distance_m: float
    source: GripSource
    spec: ObjectSpec | None = None

    def alternatives(self, grasp: Pose) -> tuple[Pose, ...]:
        """Grasps equivalent to ``grasp`` by the named type's symmetry; none without a type."""
        return () if self.spec is None else symmetric_alternatives(self.spec, grasp)

    def to_record(self) -> dict[str, Any]:
        """The grip as a trial record keeps it."""
        return {"source": self.source.value, "object_type": self.spec.name if self.spec else
                None, "opening_m": self.opening_m,
                "pregrasp_distance_m": self.pregrasp_distance_m}


DEFAULT_GRIP = Grip(MAX_OPENING_M, DEFAULT_PREGRASP_DISTANCE_M, GripSource.DEFAULT)
"""The grip of a target the model says nothing about (see the module docstring)."""


def catalog_opening_m(catalog_m: float, max_opening_m: float) -> float:
    """A catalog opening on a hand opening ``max_opening_m`` at most [m] (the run's robot's).

    An opening at the catalog gripper's full stroke (the YuMi's, every catalog grasp's:
    :data:`perception.objects.object_spec.CATALOG_GRIPPER`) opens the hand fully; a narrower one
    keeps its width.
    """
    return max_opening_m if catalog_m >= MAX_OPENING_M else catalog_m


def grip_of(target: Target, max_opening_m: float) -> Grip:
    """The grip ``target`` asks for: its type's catalog grasp, its opening, or the default.

    A stated opening overrides the type's. ``max_opening_m``: the stroke of the hand that
    picks (the run's robot's ``max_opening_m``); a grip that opens fully opens it fully.

    Raises:
        InvalidInputError: The type is not in the catalog, or the opening is not within the
            gripper's stroke (the trial records it as the model's failure).

    """
    opening = target.opening_m
    if opening is not None and not (math.isfinite(opening) and 0.0 < opening <= max_opening_m):
        raise InvalidInputError("target opening_m", opening,
                                f"in (0, {max_opening_m}] m, the gripper's stroke")
    if target.object_type is None:
        if opening is None:
            return replace(DEFAULT_GRIP, opening_m=max_opening_m)  # fully open, as ever
        return Grip(opening, DEFAULT_PREGRASP_DISTANCE_M, GripSource.OPENING)
    if target.object_type not in catalog_names():
        raise InvalidInputError("target object_type", target.object_type,
                                f"one of {', '.join(catalog_names())} or None")
    spec = get_object_spec(target.object_type)
    return Grip(catalog_opening_m(spec.grasp.opening_m, max_opening_m) if opening is None
                else opening, spec.grasp.pregrasp_distance_m, GripSource.OBJECT_TYPE, spec)
