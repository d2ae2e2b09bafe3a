"""Jerk-limited joint trajectories: rest-to-rest segments planned offline with ruckig, sampled.

Every segment starts and ends at rest and follows the straight line in joint space from its start
to its goal, so a collision check over the samples checks the path that will be executed.
Segments chain through waypoints with :meth:`JointTrajectory.then` (ruckig's free edition plans
no intermediate waypoints offline: ``docs/decisions/control.md``).

Example:
    >>> limits = JointLimits.from_robot(robot, yumi.ARM_JOINTS["r"],
    ...     yumi.MAX_ACCELERATION_RAD_S2, yumi.MAX_JERK_RAD_S3)
    >>> trajectory = plan_through([q_home, q_pregrasp, q_grasp], limits)
    >>> trajectory.at(0.5)  # (7,) joint positions [rad] half a second in

"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import reduce
from itertools import chain, pairwise

import numpy as np
import ruckig

from control.errors import ControlError, InvalidInputError
from control.robot_model import RobotModel

POSITION_TOLERANCE = 1e-9
"""Round-off allowed on a start, goal or waypoint beyond its position limits, in [rad] or [m]."""

SEAM_TOLERANCE = 1e-9
"""Largest jump in position, velocity or acceleration :meth:`JointTrajectory.then` accepts."""

STRAIGHT_LINE_TOLERANCE = 1e-9
"""Largest distance of a Phase-synchronized sample from the straight line, in [rad] or [m]."""

_LIMIT_FIELDS = ("lower", "upper", "max_velocity", "max_acceleration", "max_jerk")


class TrajectoryError(ControlError):
    """ruckig returned an error Result (or raised) for input that passed validation.

    Input is validated before ruckig sees it, so this signals a bug (ours or ruckig's); the
    ``result`` field holds ruckig's Result name (e.g. ``"ErrorInvalidInput"``) or its message.
    """

    def __init__(self, result: str, q_start: np.ndarray, q_goal: np.ndarray) -> None:
        self.result = result
        self.q_start = q_start
        self.q_goal = q_goal
        super().__init__(
            f"ruckig could not plan {q_start.tolist()} -> {q_goal.tolist()}: {result}"
        )


def _frozen(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


def _joint_vector(field: str, value: object, joint_names: tuple[str, ...]) -> np.ndarray:
    """Return a read-only float (n,) copy of ``value``; errors name the field and the joint."""
    try:
        vector = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(field, value, "an array of numbers") from None
    if vector.shape != (len(joint_names),):
        raise InvalidInputError(
            field, f"array of shape {vector.shape}",
            f"shape ({len(joint_names)},), one value per joint of {', '.join(joint_names)}",
        )
    for name, item in zip(joint_names, vector, strict=True):
        if not math.isfinite(item):
            raise InvalidInputError(f"{field}[{name}]", float(item), "a finite number")
    return _frozen(vector)


@dataclass(frozen=True)
class JointLimits:
    """Limits of the joints a trajectory moves, in the order of ``joint_names``.

    Attributes:
        joint_names: Distinct joint names; every array below has one entry per name.
        lower: Lower position limits (n,), in [rad] (revolute) or [m] (prismatic).
        upper: Upper position limits (n,), each above its ``lower``.
        max_velocity: Velocity limits (n,) in [rad/s] or [m/s], > 0.
        max_acceleration: Acceleration limits (n,) in [rad/s^2] or [m/s^2], > 0.
        max_jerk: Jerk limits (n,) in [rad/s^3] or [m/s^3], > 0.

    """

    joint_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    max_velocity: np.ndarray
    max_acceleration: np.ndarray
    max_jerk: np.ndarray

    def __post_init__(self) -> None:
        names = tuple(self.joint_names)
        if not names or len(set(names)) != len(names) or not all(isinstance(n, str) for n in names):
            raise InvalidInputError("joint_names", names, "a non-empty tuple of distinct names")
        object.__setattr__(self, "joint_names", names)
        for field in _LIMIT_FIELDS:
            object.__setattr__(self, field, _joint_vector(field, getattr(self, field), names))
        for field in ("max_velocity", "max_acceleration", "max_jerk"):
            for name, value in zip(names, getattr(self, field), strict=True):
                if value <= 0.0:
                    raise InvalidInputError(f"{field}[{name}]", float(value), "> 0")
        for name, low, high in zip(names, self.lower, self.upper, strict=True):
            if not low < high:
                raise InvalidInputError(f"lower[{name}]", float(low), f"< upper = {float(high)!r}")

    @classmethod
    def from_robot(
        cls,
        robot: RobotModel,
        joint_names: Sequence[str],
        max_acceleration: Mapping[str, float],
        max_jerk: Mapping[str, float],
        velocity_scale: float = 1.0,
    ) -> JointLimits:
        """Position and velocity limits from the robot's URDF, acceleration and jerk as stated.

        Args:
            robot: The model whose URDF gives position limits and velocity limits.
            joint_names: The joints to plan for, in the order trajectories will use.
            max_acceleration: Limit per joint name in [rad/s^2] or [m/s^2]; extra names ignored.
            max_jerk: Limit per joint name in [rad/s^3] or [m/s^3]; extra names ignored.
            velocity_scale: Fraction of the URDF velocity limits to use, in (0, 1].

        """
        if not 0.0 < velocity_scale <= 1.0:  # also rejects NaN
            raise InvalidInputError("velocity_scale", velocity_scale, "within (0, 1]")
        names = tuple(joint_names)
        index = robot.joint_indices(names)  # unknown names raise, listing the robot's joints
        stated = {"max_acceleration": max_acceleration, "max_jerk": max_jerk}
        for field, mapping in stated.items():
            missing = [name for name in names if name not in mapping]
            if missing:
                raise InvalidInputError(field, f"no value for {', '.join(missing)}",
                                        "a value for every joint in joint_names")
        return cls(
            joint_names=names,
            lower=robot.lower_rad[index],
            upper=robot.upper_rad[index],
            max_velocity=robot.max_velocity[index] * velocity_scale,
            max_acceleration=np.array([max_acceleration[name] for name in names], dtype=float),
            max_jerk=np.array([max_jerk[name] for name in names], dtype=float),
        )


@dataclass(frozen=True)
class JointTrajectory:
    """Joint references sampled in time, all arrays read-only.

    Steps are the planner's ``dt_s`` except the last step of each planned segment, which ends
    exactly at the segment's goal and is 1e-6 to 1 + 1e-6 times ``dt_s`` long (or the whole
    segment, for a segment shorter than that).

    Attributes:
        joint_names: The joints, in the column order of the arrays below.
        times_s: Sample times (N,) in [s], starting at 0 and strictly increasing.
        positions: (N, n) in [rad] or [m].
        velocities: (N, n) in [rad/s] or [m/s].
        accelerations: (N, n) in [rad/s^2] or [m/s^2].

    """

    joint_names: tuple[str, ...]
    times_s: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        times = _frozen(np.array(self.times_s, dtype=float))
        if times.ndim != 1 or times.size == 0 or times[0] != 0.0 or np.any(np.diff(times) <= 0):
            raise InvalidInputError("times_s", times, "a (N,) array from 0, strictly increasing")
        object.__setattr__(self, "times_s", times)
        shape = (times.size, len(self.joint_names))
        for field in ("positions", "velocities", "accelerations"):
            array = _frozen(np.array(getattr(self, field), dtype=float))
            if array.shape != shape:
                raise InvalidInputError(field, f"array of shape {array.shape}", f"shape {shape}")
            object.__setattr__(self, field, array)

    @property
    def duration_s(self) -> float:
        """Time of the last sample in [s]."""
        return float(self.times_s[-1])

    @property
    def dt_s(self) -> float:
        """First sampling step in [s]: the planner's ``dt_s`` unless the motion is shorter.

        0 for a single sample.
        """
        return float(self.times_s[1]) if self.times_s.size > 1 else 0.0

    def then(self, other: JointTrajectory) -> JointTrajectory:
        """Append ``other``, which must start where this trajectory ends (same joints too).

        ``other`` is shifted by :attr:`duration_s`; its first sample (the seam) is dropped.
        """
        if other.joint_names != self.joint_names:
            raise InvalidInputError("other.joint_names", other.joint_names,
                                    f"the same joints in the same order: {self.joint_names}")
        for field in ("positions", "velocities", "accelerations"):
            end, start = getattr(self, field)[-1], getattr(other, field)[0]
            jumps = np.abs(start - end) > SEAM_TOLERANCE
            if np.any(jumps):
                j = int(np.argmax(jumps))  # the first joint that jumps
                raise InvalidInputError(
                    f"other.{field}[0][{self.joint_names[j]}]", float(start[j]),
                    f"equal to this trajectory's last sample {float(end[j])!r} "
                    f"(within {SEAM_TOLERANCE:g})",
                )
        return JointTrajectory(
            self.joint_names,
            np.concatenate([self.times_s, other.times_s[1:] + self.duration_s]),
            np.concatenate([self.positions, other.positions[1:]]),
            np.concatenate([self.velocities, other.velocities[1:]]),
            np.concatenate([self.accelerations, other.accelerations[1:]]),
        )

    def at(self, t_s: float) -> np.ndarray:
        """Positions (n,) at time ``t_s`` [s], linear between samples, clamped to the ends."""
        if not math.isfinite(t_s):
            raise InvalidInputError("t_s", t_s, "a finite time in [s]")
        if self.times_s.size == 1:
            return self.positions[0].copy()
        t = min(max(float(t_s), 0.0), self.duration_s)
        k = min(int(np.searchsorted(self.times_s, t, side="right")) - 1, self.times_s.size - 2)
        w = (t - self.times_s[k]) / (self.times_s[k + 1] - self.times_s[k])
        return np.asarray((1.0 - w) * self.positions[k] + w * self.positions[k + 1])


def _check_configuration(field: str, q: object, limits: JointLimits) -> np.ndarray:
    """Return ``q`` as a float (n,) array; errors name the joint, its value and its range."""
    vector = _joint_vector(field, q, limits.joint_names)
    lower, upper = limits.lower - POSITION_TOLERANCE, limits.upper + POSITION_TOLERANCE
    outside = (vector < lower) | (vector > upper)
    if np.any(outside):
        j = int(np.argmax(outside))
        raise InvalidInputError(
            f"{field}[{limits.joint_names[j]}]", float(vector[j]),
            f"within [{float(limits.lower[j])!r}, {float(limits.upper[j])!r}]",
        )
    return vector


def _check_dt(dt_s: float) -> float:
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise InvalidInputError("dt_s", dt_s, "a finite step > 0 in [s]")
    return float(dt_s)


def _calculate(
    start: np.ndarray, goal: np.ndarray, v_max: np.ndarray, a_max: np.ndarray, j_max: np.ndarray
) -> ruckig.Trajectory:
    """Plan ruckig's time-optimal rest-to-rest trajectory with Phase synchronization."""
    dofs = start.size
    inp = ruckig.InputParameter(dofs)
    inp.current_position, inp.target_position = start.tolist(), goal.tolist()
    inp.max_velocity, inp.max_acceleration = v_max.tolist(), a_max.tolist()
    inp.max_jerk = j_max.tolist()
    inp.synchronization = ruckig.Synchronization.Phase
    trajectory = ruckig.Trajectory(dofs)
    try:
        result = ruckig.Ruckig(dofs).calculate(inp, trajectory)
    except ruckig.RuckigError as error:
        raise TrajectoryError(str(error), start, goal) from None
    if result != ruckig.Result.Working:
        raise TrajectoryError(result.name, start, goal)
    return trajectory


def _sample(trajectory: ruckig.Trajectory, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Sample every ``dt_s`` and at the exact end: times (N,) and states (N, 3, dofs)."""
    duration = trajectory.duration
    count = max(1, math.ceil(duration / dt_s - 1e-6))  # keeps the last step >= 1e-6 dt_s
    times = np.append(np.arange(count) * dt_s, duration)
    dofs = trajectory.degrees_of_freedom
    # at_time gives (p, v, a) lists; flattening them through fromiter is ~2x faster than np.array
    flat = chain.from_iterable(chain.from_iterable(map(trajectory.at_time, times.tolist())))
    return times, np.fromiter(flat, float, count=times.size * 3 * dofs).reshape(-1, 3, dofs)


def _plan(start: np.ndarray, goal: np.ndarray, limits: JointLimits, dt_s: float) -> JointTrajectory:
    distance = goal - start  # (n,)
    if not np.any(distance):
        zeros = np.zeros((1, start.size))
        return JointTrajectory(limits.joint_names, np.zeros(1), start[None], zeros, zeros)
    trajectory = _calculate(
        start, goal, limits.max_velocity, limits.max_acceleration, limits.max_jerk
    )
    times, states = _sample(trajectory, dt_s)
    positions, velocities, accelerations = states[:, 0], states[:, 1], states[:, 2]
    along = (positions - start) @ distance / (distance @ distance)  # (N,)
    if np.max(np.abs(positions - start - along[:, None] * distance)) > STRAIGHT_LINE_TOLERANCE:
        # ruckig found the Phase-scaled profile beyond some joint's limits and silently fell back
        # to Time synchronization (a curved path). Plan the path parameter s in [0, 1] instead,
        # under the tightest limit over the joints: the time-optimal motion along the line.
        moving = np.abs(distance) > 0.0
        s_limits = [np.array([np.min(lim[moving] / np.abs(distance[moving]))])
                    for lim in (limits.max_velocity, limits.max_acceleration, limits.max_jerk)]
        s_trajectory = _calculate(np.zeros(1), np.ones(1), *s_limits)
        times, s_states = _sample(s_trajectory, dt_s)  # (N, 3, 1)
        positions = start + s_states[:, 0] * distance
        velocities, accelerations = s_states[:, 1] * distance, s_states[:, 2] * distance
    positions[0], positions[-1] = start, goal  # exact ends, not ruckig's round-off of them
    velocities[[0, -1]] = 0.0
    accelerations[[0, -1]] = 0.0
    return JointTrajectory(limits.joint_names, times, positions, velocities, accelerations)


def plan_segment(
    q_start: np.ndarray, q_goal: np.ndarray, limits: JointLimits, dt_s: float = 1 / 240
) -> JointTrajectory:
    """Plan the time-optimal rest-to-rest motion along the straight joint-space line.

    The path is the straight line even where ruckig would bend it to keep a joint's limits
    (``docs/decisions/control.md``). Samples lie every ``dt_s`` and at the exact end, which is
    ``q_goal`` with zero velocity and acceleration. A zero-length move gives one sample.

    Args:
        q_start: Start positions (n,) in [rad] or [m], in ``limits.joint_names`` order.
        q_goal: Goal positions (n,), like ``q_start``.
        limits: The joints' limits; both ends must lie within the position limits.
        dt_s: Sampling step in [s].

    Raises:
        InvalidInputError: A bad shape, a non-finite value, an end outside the position limits
            (naming the joint, its value and its range), or a ``dt_s`` that is not > 0.
        TrajectoryError: ruckig returned an error Result despite valid input.

    """
    dt = _check_dt(dt_s)
    start = _check_configuration("q_start", q_start, limits)
    return _plan(start, _check_configuration("q_goal", q_goal, limits), limits, dt)


def plan_through(
    waypoints: Sequence[np.ndarray], limits: JointLimits, dt_s: float = 1 / 240
) -> JointTrajectory:
    """Rest-to-rest straight segments through every waypoint, chained with :meth:`then`.

    The robot stops at each waypoint, which is a sample of the result. One waypoint gives a
    one-sample trajectory. Raises like :func:`plan_segment`, naming ``waypoints[k]``.
    """
    dt = _check_dt(dt_s)
    if len(waypoints) == 0:
        raise InvalidInputError("waypoints", "an empty sequence", "at least one configuration")
    points = [_check_configuration(f"waypoints[{k}]", q, limits) for k, q in enumerate(waypoints)]
    segments = [_plan(points[0], points[0], limits, dt)]
    segments += [_plan(a, b, limits, dt) for a, b in pairwise(points)]
    return reduce(JointTrajectory.then, segments)
