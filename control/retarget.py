"""Re-targeting a moving arm online: jerk-limited motions from any moving state, for issue 36.

A closed-loop pick re-predicts the target while the arm approaches; when the target moved, the
arm switches at the current sample to a new motion that starts from its moving state (position,
velocity, acceleration) and ends at rest at the new goal, without stopping first. ruckig computes
that motion from the state, as its online ``update()`` does on the cycle a new target arrives;
:func:`splice` joins it to what was executed, and :func:`stop` is the safe fallback when a
re-target cannot be planned. The new motion is time-optimal and Time-synchronized, so it is in
general not the straight joint-space line of :func:`control.trajectory.plan_segment`: the planner
collision-checks it as it checks every trajectory, at every sample (``docs/decisions/control.md``).

Example:
    >>> executed = plan_segment(q_home, q_pregrasp, limits)
    >>> state = trajectory_state(executed, 120)  # half a second in, still moving
    >>> new = retarget(state, q_pregrasp_moved, limits)
    >>> record = splice(executed, 120, new)  # executed up to sample 120, then the new motion

"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
import ruckig

from control.errors import ControlError, InvalidInputError
from control.trajectory import (
    POSITION_TOLERANCE,
    JointLimits,
    JointTrajectory,
    _check_configuration,
    _check_dt,
    _joint_vector,
    _sample,
    plan_segment,
)

LIMIT_RELATIVE_TOLERANCE = 1e-9
"""Round-off allowed on a state's |velocity| and |acceleration| beyond its limits, relative."""

_STATE_FIELDS = ("positions", "velocities", "accelerations")


class RetargetError(ControlError):
    """No motion within the joints' limits from this moving state (to this goal, or to rest).

    ruckig's community edition ignores position limits (``min_position``/``max_position`` are
    Pro features), so a time-optimal motion from a fast state may overshoot a joint's limit on
    its way; that is reported here as ``result = "ErrorPositionalLimits"``, the Result ruckig Pro
    gives. Any error Result of ruckig (or its exception message) is reported the same way. The
    caller keeps its last good plan, or stops with :func:`stop`.

    Attributes:
        result: ruckig's Result name, e.g. ``"ErrorPositionalLimits"``, or its error message.
        state: The moving state the motion was to start from.
        goal: The goal positions (n,), or None for a stop.

    """

    def __init__(
        self, result: str, state: JointState, goal: np.ndarray | None, detail: str = ""
    ) -> None:
        self.result = result
        self.state = state
        self.goal = goal
        self.detail = detail
        towards = "rest" if goal is None else str(goal.tolist())
        super().__init__(
            f"ruckig could not plan from positions {state.positions.tolist()}, velocities "
            f"{state.velocities.tolist()}, accelerations {state.accelerations.tolist()} to "
            f"{towards}: {result}{f' ({detail})' if detail else ''}"
        )

    def __reduce__(self) -> tuple[type, tuple[str, JointState, np.ndarray | None, str]]:
        """Pickled by its fields: it may cross to and from worker processes."""
        return type(self), (self.result, self.state, self.goal, self.detail)


@dataclass(frozen=True)
class JointState:
    """The state of moving joints at one instant, all arrays read-only (n,).

    Attributes:
        joint_names: The joints, in the order of the arrays below.
        positions: In [rad] or [m].
        velocities: In [rad/s] or [m/s].
        accelerations: In [rad/s^2] or [m/s^2].

    """

    joint_names: tuple[str, ...]
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray

    def __post_init__(self) -> None:
        names = tuple(self.joint_names)
        if not names or not all(isinstance(name, str) for name in names):
            raise InvalidInputError("joint_names", names, "a non-empty tuple of joint names")
        object.__setattr__(self, "joint_names", names)
        for field in _STATE_FIELDS:
            object.__setattr__(self, field, _joint_vector(field, getattr(self, field), names))

    @classmethod
    def at_rest(cls, joint_names: tuple[str, ...], positions: np.ndarray) -> JointState:
        """The joints standing still at ``positions``."""
        zeros = np.zeros(len(joint_names))
        return cls(joint_names, positions, zeros, zeros)


def _check_index(field: str, k: object, trajectory: JointTrajectory) -> int:
    count = trajectory.times_s.size
    if isinstance(k, bool) or not isinstance(k, int | np.integer) or not 0 <= k < count:
        raise InvalidInputError(field, k, f"a sample index, an integer within [0, {count - 1}]")
    return int(k)


def trajectory_state(trajectory: JointTrajectory, k: int) -> JointState:
    """The state of ``trajectory`` at its sample ``k`` (0 <= k < number of samples)."""
    index = _check_index("k", k, trajectory)
    return JointState(trajectory.joint_names, *(getattr(trajectory, field)[index]
                                                 for field in _STATE_FIELDS))


def _check_within(
    field: str, vector: np.ndarray, bound: np.ndarray, names: tuple[str, ...]
) -> None:
    """Raise naming the first joint whose |value| is above its bound (beyond round-off)."""
    above = np.abs(vector) > bound * (1.0 + LIMIT_RELATIVE_TOLERANCE)
    if np.any(above):
        j = int(np.argmax(above))
        raise InvalidInputError(f"{field}[{names[j]}]", float(vector[j]),
                                f"within [-{float(bound[j])!r}, {float(bound[j])!r}]")


def _check_state(state: JointState, limits: JointLimits) -> JointState:
    if not isinstance(state, JointState):
        kind = f"an object of type {type(state).__name__}"
        raise InvalidInputError("state", kind, "a JointState")
    if state.joint_names != limits.joint_names:
        raise InvalidInputError("state.joint_names", state.joint_names,
                                f"the joints of limits, in order: {limits.joint_names}")
    _check_configuration("state.positions", state.positions, limits)
    _check_within("state.velocities", state.velocities, limits.max_velocity, state.joint_names)
    _check_within("state.accelerations", state.accelerations, limits.max_acceleration,
                  state.joint_names)
    return state


def _limit_excess(lowest: np.ndarray, highest: np.ndarray, limits: JointLimits) -> str:
    """Describe the first joint whose range [lowest, highest] leaves its limits; '' if none."""
    outside = (lowest < limits.lower - POSITION_TOLERANCE) | (
        highest > limits.upper + POSITION_TOLERANCE)
    if not np.any(outside):
        return ""
    j = int(np.argmax(outside))
    return (f"{limits.joint_names[j]} would reach [{float(lowest[j])!r}, {float(highest[j])!r}], "
            f"beyond its limits [{float(limits.lower[j])!r}, {float(limits.upper[j])!r}]")


def _motion(
    state: JointState, goal: np.ndarray | None, limits: JointLimits, dt_s: float,
    goal_velocity: np.ndarray | None = None,
) -> JointTrajectory:
    """The time-optimal jerk-limited motion (ruckig) from ``state`` to rest, sampled.

    At rest at ``goal`` (position interface), or anywhere (velocity interface, ``goal`` None);
    passing ``goal`` at ``goal_velocity`` instead of resting there, if given. The first sample
    is ``state`` exactly, the last ``goal`` exactly (if given) at its velocity.
    """
    dofs = len(limits.joint_names)
    inp = ruckig.InputParameter(dofs)
    for field, name in zip(_STATE_FIELDS, ("position", "velocity", "acceleration"), strict=True):
        setattr(inp, f"current_{name}", getattr(state, field).tolist())
    for name in ("max_velocity", "max_acceleration", "max_jerk"):
        setattr(inp, name, getattr(limits, name).tolist())
    # Honoured by ruckig Pro only; the community edition ignores them, hence the checks below.
    inp.min_position = (limits.lower - POSITION_TOLERANCE).tolist()
    inp.max_position = (limits.upper + POSITION_TOLERANCE).tolist()
    # Target acceleration stays ruckig's default 0, the velocity too unless passing a via.
    if goal_velocity is not None:
        inp.target_velocity = goal_velocity.tolist()
    if goal is None:  # every joint brakes as hard as it may: the shortest way to rest
        inp.control_interface = ruckig.ControlInterface.Velocity
        inp.synchronization = ruckig.Synchronization.No
    else:  # ruckig's default Time: Phase generally has no solution from a moving state
        inp.target_position = goal.tolist()
    trajectory = ruckig.Trajectory(dofs)
    try:
        result = ruckig.Ruckig(dofs).calculate(inp, trajectory).name
    except ruckig.RuckigError as error:
        result = str(error)
    if result != "Working":
        raise RetargetError(result, state, goal)
    extrema = trajectory.position_extrema  # exact over the continuous motion, not just samples
    excess = _limit_excess(np.array([e.min for e in extrema]), np.array([e.max for e in extrema]),
                           limits)
    if excess:
        raise RetargetError("ErrorPositionalLimits", state, goal, excess)
    start = np.stack([getattr(state, field) for field in _STATE_FIELDS])  # (3, n)
    if trajectory.duration > 0.0:
        times, states = _sample(trajectory, dt_s)  # (N,), (N, 3, n)
    else:  # at rest at the goal already
        times, states = np.zeros(1), start[None].copy()
    states[-1, 1:] = 0.0  # exactly at rest (or the via's velocity) at the end, not round-off
    if goal_velocity is not None:
        states[-1, 1] = goal_velocity
    if goal is not None:
        states[-1, 0] = goal
    states[0] = start  # exact start: continuous with what the arm is doing
    positions = states[:, 0]
    excess = _limit_excess(positions.min(axis=0), positions.max(axis=0), limits)
    if excess:
        raise RetargetError("ErrorPositionalLimits", state, goal, f"sampled: {excess}")
    return JointTrajectory(limits.joint_names, times, positions, states[:, 1], states[:, 2])


def retarget(
    state: JointState, q_goal: np.ndarray, limits: JointLimits, dt_s: float = 1 / 240,
    vias: Sequence[np.ndarray] = (),
) -> JointTrajectory:
    """The time-optimal jerk-limited motion from the moving ``state`` to ``q_goal`` at rest.

    This is the motion ruckig's online ``update()`` computes on the cycle a new target arrives
    (current position, velocity and acceleration as they are, target velocity and acceleration
    0), computed once and sampled like :func:`control.trajectory.plan_segment`: every ``dt_s``
    and exactly at the end. The first sample is ``state`` exactly, the last ``q_goal`` at rest.
    Every joint ends at the same time (ruckig's Time synchronization), so the path is in general
    curved in joint space; the planner collision-checks it at every sample, which covers it as
    consecutive samples lie at most max_velocity * dt_s apart (YuMi at 1/240 s: 0.0131 rad on
    joints 1, 2, 7 and 3, 0.0291 rad on 4, 5 and 6). A goal equal to a state at rest gives a
    one-sample trajectory.

    ``vias`` are passed on the way, in order, without stopping at any: each is reached moving
    towards the next at the mean velocity of the rest-to-rest straight move between the two
    (within every joint's velocity limit), as ruckig reaches a target state with a target
    velocity. A planner that cannot wait at a via (the arm is moving) goes over an obstacle
    this way, where a plan from rest stops at its via poses.

    When this raises :class:`RetargetError`, the caller falls back to its last good plan (the
    executed trajectory, which stays valid) or stops with :func:`stop`.

    Args:
        state: The joints' moving state, e.g. :func:`trajectory_state` of the executed plan,
            within position, velocity and acceleration limits.
        q_goal: Goal positions (n,) in [rad] or [m], within the position limits.
        limits: The joints' limits, in the order of ``state.joint_names``.
        dt_s: Sampling step in [s].
        vias: Configurations (n,) passed on the way, within the position limits.

    Raises:
        InvalidInputError: Other joints than ``limits``', a state beyond its limits, a goal
            or a via outside the position limits (naming the field, the joint, its value and
            its range), or a ``dt_s`` that is not > 0.
        RetargetError: ruckig returned an error Result, or the motion would leave the position
            limits (``result = "ErrorPositionalLimits"``: too fast to turn within them).

    """
    dt = _check_dt(dt_s)
    goal = _check_configuration("q_goal", q_goal, limits)
    points = [_check_configuration(f"vias[{k}]", q, limits) for k, q in enumerate(vias)]
    points.append(goal)
    motion: JointTrajectory | None = None
    current = _check_state(state, limits)
    for via, after in pairwise(points):
        pace = plan_segment(via, after, limits, dt).duration_s
        velocity = (after - via) / pace if pace > 0.0 else np.zeros_like(via)
        part = _motion(current, via, limits, dt, velocity)
        motion = part if motion is None else motion.then(part)
        current = trajectory_state(part, part.times_s.size - 1)
    last = _motion(current, goal, limits, dt)
    return last if motion is None else motion.then(last)


def stop(state: JointState, limits: JointLimits, dt_s: float = 1 / 240) -> JointTrajectory:
    """The time-optimal jerk-limited stop from the moving ``state``, sampled like :func:`retarget`.

    ruckig's velocity interface with target velocity 0: the safe fallback when a re-target
    fails. It ends at rest wherever the stop takes the joints; the first sample is ``state``.

    Raises:
        InvalidInputError: As :func:`retarget`.
        RetargetError: The stop would leave the position limits, or ruckig returned an error.

    """
    dt = _check_dt(dt_s)
    return _motion(_check_state(state, limits), None, limits, dt)


def splice(executed: JointTrajectory, at_index: int, new: JointTrajectory) -> JointTrajectory:
    """``executed``'s samples 0 to ``at_index``, then ``new``: the record of a re-targeted motion.

    ``new`` must start at sample ``at_index`` of ``executed`` (position, velocity and
    acceleration within ``control.trajectory.SEAM_TOLERANCE``), as :func:`retarget` from
    :func:`trajectory_state` ``(executed, at_index)`` does; its first sample is dropped.
    """
    end = _check_index("at_index", at_index, executed) + 1
    prefix = JointTrajectory(executed.joint_names, executed.times_s[:end],
                             *(getattr(executed, field)[:end] for field in _STATE_FIELDS))
    try:
        return prefix.then(new)
    except InvalidInputError as error:  # name the arguments of this function
        raise InvalidInputError(
            error.field.replace("other", "new", 1), error.value,
            error.allowed.replace("this trajectory's last sample", f"executed[{at_index}]"),
        ) from None

