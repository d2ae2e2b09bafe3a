"""Targets that move during a pick (issue 36): a task's ``[disturbance]`` and its seeded draws.

A pick is open-loop unless something re-looks: one image, one plan, executed blind. A task
with a disturbance moves the target while the arm approaches, so an open-loop and a
closed-loop pick can be compared on the same scenes::

    [disturbance]
    move_m = [0.03, 0.08]     # moved this far on the table, in a uniformly drawn direction
    turn_deg = [-45, 45]      # and turned this much about the vertical
    velocity_m_s = 0.0        # or (also) carried at this speed, conveyor-like, from the image on
    when = "approach"         # between the first image and the arm reaching its pre-grasp

:func:`scene_disturbance` draws what happens in one scene from a seed stream of its own,
``SeedSequence([seed, stream, index, DISTURBANCE_STREAM])``, beside the scene's and the
distractors' (:mod:`sim.tasks.scene_sampling`): a task with a disturbance presents exactly the
scenes of the task without it. The trial runner applies the draw (a separate step, still being
built) through :meth:`sim.world.yumi_world.World.move_object` (teleport and settle) and
:meth:`~sim.world.yumi_world.World.keep_sliding` (the steady slide).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.errors import InvalidInputError

MAX_MOVE_M = 0.15
"""Largest ``disturbance.move_m`` [m]. The ``yumi`` scene's workspace is ~0.15 m x 0.40 m
(x 0.40-0.55 m): a larger move takes the target out of it, beyond the camera's view of the
workspace or the arm's comfortable reach, and tests leaving the scene rather than re-looking."""
MAX_TURN_DEG = 180.0
"""``disturbance.turn_deg`` lies in [-180, 180] degrees: every heading once."""
MAX_VELOCITY_M_S = 0.1
"""Largest ``disturbance.velocity_m_s`` [m/s]. A 0.1 m/s slide over a ~2 s approach moves the
target 20 cm, more than the workspace is deep (0.15 m): faster would carry it off the scene."""
DISTURBANCE_STREAM = 3
"""The disturbances' own seed stream, beside the distractors' (1) and the balanced types' (2) of
:mod:`sim.tasks.scene_sampling`: ``SeedSequence([seed, stream, index, 3])``."""


class DisturbanceWhen(enum.Enum):
    """When in a pick the target is disturbed."""

    APPROACH = "approach"  # between the first image and the arm reaching its pre-grasp


@dataclass(frozen=True)
class Disturbance:
    """How a task's target moves during a pick (``[disturbance]``; see the module docstring).

    Args:
        move_m: ``(low, high)``: the distance the target is moved on the table, drawn uniformly
            in it [m], in a direction drawn uniformly in the plane; (0, 0): not moved.
        turn_deg: ``(low, high)``: its turn about the vertical, drawn uniformly [deg].
        velocity_m_s: A steady slide at this speed [m/s] from the first image on, in a
            direction drawn uniformly (conveyor-like); 0: none.
        when: When the move and turn happen (a moment drawn within that phase).

    Raises:
        InvalidInputError: A range that is not two finite numbers low <= high within its
            bounds, a speed out of [0, 0.1] m/s, or a disturbance that does nothing. The field
            is named ``disturbance.<key>``.

    """

    move_m: tuple[float, float] = (0.0, 0.0)
    turn_deg: tuple[float, float] = (0.0, 0.0)
    velocity_m_s: float = 0.0
    when: DisturbanceWhen = DisturbanceWhen.APPROACH

    def __post_init__(self) -> None:
        _check_range("move_m", self.move_m, 0.0, MAX_MOVE_M, "m")
        _check_range("turn_deg", self.turn_deg, -MAX_TURN_DEG, MAX_TURN_DEG, "deg")
        if not (_finite(self.velocity_m_s) and 0.0 <= self.velocity_m_s <= MAX_VELOCITY_M_S):
            raise InvalidInputError("disturbance.velocity_m_s", self.velocity_m_s,
                                    f"a speed in [0, {MAX_VELOCITY_M_S:g}] m/s (0: no slide)")
        if not isinstance(self.when, DisturbanceWhen):
            allowed = ", ".join(repr(w.value) for w in DisturbanceWhen)
            raise InvalidInputError("disturbance.when", self.when, f"one of {allowed}")
        if self.move_m == (0.0, 0.0) and self.turn_deg == (0.0, 0.0) and \
                self.velocity_m_s == 0.0:
            raise InvalidInputError("disturbance", self.to_json(), "a move_m, turn_deg or "
                                    "velocity_m_s that is not zero (this disturbance does "
                                    "nothing: leave the table out)")

    def to_json(self) -> dict[str, Any]:
        """The disturbance as JSON-able data, keyed as in a task file."""
        return {"move_m": list(self.move_m), "turn_deg": list(self.turn_deg),
                "velocity_m_s": self.velocity_m_s, "when": self.when.value}


@dataclass(frozen=True)
class DisturbanceDraw:
    """What happens in one scene: a move and turn at a moment of the approach, and a slide.

    Args:
        time_fraction: When, in [0, 1): the fraction of the approach (from the first image to
            the arm reaching its pre-grasp) after which the move happens; the runner multiplies
            it by the approach's duration.
        dx_m, dy_m: The move on the table, world x and y [m].
        dyaw_rad: The turn about the vertical [rad].
        velocity_xy_m_s: The slide's world x and y velocity from the first image on [m/s];
            (0, 0): none.

    """

    time_fraction: float
    dx_m: float
    dy_m: float
    dyaw_rad: float
    velocity_xy_m_s: tuple[float, float]

    @property
    def moves(self) -> bool:
        """Whether there is a move or turn to apply (else only, perhaps, a slide)."""
        return (self.dx_m, self.dy_m, self.dyaw_rad) != (0.0, 0.0, 0.0)

    @property
    def slides(self) -> bool:
        """Whether the target slides."""
        return self.velocity_xy_m_s != (0.0, 0.0)


def draw_disturbance(disturbance: Disturbance, rng: np.random.Generator) -> DisturbanceDraw:
    """One scene's disturbance, each quantity drawn uniformly in its range from ``rng``.

    Always five draws in the same order (moment, distance, direction, turn, slide direction),
    whichever are zero, so a changed range leaves the others' draws as they were.
    """
    time_fraction = float(rng.uniform(0.0, 1.0))
    distance = float(rng.uniform(*disturbance.move_m))
    direction = float(rng.uniform(-math.pi, math.pi))
    turn = math.radians(float(rng.uniform(*disturbance.turn_deg)))
    heading = float(rng.uniform(-math.pi, math.pi))
    speed = disturbance.velocity_m_s
    return DisturbanceDraw(
        time_fraction=time_fraction,
        dx_m=distance * math.cos(direction), dy_m=distance * math.sin(direction),
        dyaw_rad=turn,
        velocity_xy_m_s=(speed * math.cos(heading), speed * math.sin(heading)) if speed else
        (0.0, 0.0))


def disturbance_rng(seed: int, index: int, stream: int = 1) -> np.random.Generator:
    """The generator of scene ``index``'s disturbance: its own stream (:data:`DISTURBANCE_STREAM`).

    ``stream`` is the scene's :class:`~sim.tasks.scene_sampling.SeedStream` (1: TEST, where
    trials draw their scenes; 0: TRAIN).
    """
    if seed < 0 or index < 0:
        raise InvalidInputError("seed/index", (seed, index), "non-negative integers")
    return np.random.default_rng(np.random.SeedSequence(
        [seed, int(stream), index, DISTURBANCE_STREAM]))


def scene_disturbance(disturbance: Disturbance | None, seed: int, index: int,
                      stream: int = 1) -> DisturbanceDraw | None:
    """What ``disturbance`` (a task's) does in scene ``index`` of ``stream`` (default TEST).

    None where the task has none. The scene itself (``sample_scene`` with the same seed,
    stream and index) is unchanged by it: the draw comes from the disturbances' own stream.
    """
    if disturbance is None:
        return None
    return draw_disturbance(disturbance, disturbance_rng(seed, index, stream))


def disturbance_from_table(table: dict[str, Any], where: str) -> Disturbance:
    """A ``Disturbance`` from a task file's parsed values; errors are prefixed with ``where``."""
    try:
        return Disturbance(**table)
    except InvalidInputError as error:
        raise InvalidInputError(f"{where}: {error.field}", error.value, error.allowed) from None


def _check_range(key: str, value: Any, lowest: float, highest: float, unit: str) -> None:
    allowed = f"[low, high], two finite numbers with {lowest:g} <= low <= high <= {highest:g} " \
              f"[{unit}]"
    shown = list(value) if isinstance(value, tuple | list) else value
    if not (isinstance(value, tuple) and len(value) == 2 and _finite(*value)
            and lowest <= value[0] <= value[1] <= highest):
        raise InvalidInputError(f"disturbance.{key}", shown, allowed)


def _finite(*values: Any) -> bool:
    """Whether every value is an int or float (no bool), finite, and within a float's range."""
    try:
        return all(not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)
                   for v in values)
    except OverflowError:  # an int beyond the float range
        return False
