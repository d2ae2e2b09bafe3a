"""Inverse kinematics of one arm's tool frame to a full 6-D pose, within joint limits.

Works for any fixed-base robot that :class:`RobotModel` loads (the YuMi arms, a Panda, ...):
damped least squares on the moving joints alone, joint limits kept by bounded steps, random
restarts drawn from the caller's generator. How and why: ``docs/decisions/control.md``.

Example::

    ik = ArmIk(robot, yumi.ARM_JOINTS["r"], yumi.TCP_FRAME["r"])
    result = ik.solve(T_world_target, q_home)  # q_home: (robot.nq,)
    if result.solved:
        q_grasp = result.q  # (robot.nq,), only the right arm's joints changed

"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from control.errors import InvalidInputError
from control.robot_model import RobotModel

# Keeps the normal equations invertible at a solution, where the error-scaled damping vanishes
# and a 7-joint arm's J^T J has rank 6; in [m^2], far below J^T J's ~0.1 m^2 entries.
_DAMPING_FLOOR = 1e-6


class IkStatus(enum.Enum):
    """How an IK solve ended."""

    SOLVED = "solved"  # within both tolerances and the joint limits
    NOT_CONVERGED = "not_converged"  # no attempt reached the tolerances; the best one is kept


@dataclass(frozen=True)
class IkOptions:
    """Tolerances and effort of :class:`ArmIk`.

    Attributes:
        position_tolerance_m: Largest accepted distance of the frame from the target in [m].
        rotation_tolerance_rad: Largest accepted rotation angle to the target in [rad].
        max_iterations: Iterations of one attempt before it gives up.
        max_restarts: Random restarts after the attempt from ``q_init``; 0 tries ``q_init`` only.
        damping: Levenberg-Marquardt damping per squared weighted error (unitless): the step
            solves (J^T J + damping * |e|^2 I) dq = J^T e, a Gauss-Newton step near the target and
            a short gradient step far from it.
        rotation_weight_m: Length that turns a rotation error in [rad] into [m] where the two
            are weighed together; about a third of the arm's reach balances them.
        limit_gain: Fraction of the distance to a joint limit that one step may cover, in
            (0, 1]; below 1 a joint slows down as it nears a limit instead of sticking to it
            (measured in ``docs/decisions/control.md``).
        stall_iterations: An attempt gives up once its error has not fallen by 2 % in this many
            iterations.

    """

    position_tolerance_m: float = 1e-4
    rotation_tolerance_rad: float = 1e-3
    max_iterations: int = 100
    max_restarts: int = 20
    damping: float = 1e-3
    rotation_weight_m: float = 0.2
    limit_gain: float = 0.3
    stall_iterations: int = 10

    def __post_init__(self) -> None:
        for name in ("position_tolerance_m", "rotation_tolerance_rad", "damping",
                     "rotation_weight_m"):
            value = getattr(self, name)
            if not (_is_number(value) and math.isfinite(value) and value > 0):
                raise InvalidInputError(name, value, "a finite number > 0")
        if not (_is_number(self.limit_gain) and 0 < self.limit_gain <= 1):
            raise InvalidInputError("limit_gain", self.limit_gain, "a number in (0, 1]")
        for name, smallest in (("max_iterations", 1), ("max_restarts", 0), ("stall_iterations", 1)):
            value = getattr(self, name)
            if not (isinstance(value, int) and not isinstance(value, bool) and value >= smallest):
                raise InvalidInputError(name, value, f"an integer >= {smallest}")


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


@dataclass(frozen=True)
class IkResult:
    """The outcome of one :meth:`ArmIk.solve`.

    Attributes:
        status: SOLVED or NOT_CONVERGED.
        q: Full configuration (robot.nq,): the arm joints solved (or the best attempt's values),
            every other joint as in ``q_init``. The arm joints are always within their limits.
        position_error_m: Distance of the frame from the target in [m].
        rotation_error_rad: Angle of the rotation from the frame to the target in [rad].
        iterations: Iterations over all attempts.
        restarts: Random restarts used (0 when the attempt from ``q_init`` succeeded).

    """

    status: IkStatus
    q: np.ndarray  # (nq,)
    position_error_m: float
    rotation_error_rad: float
    iterations: int
    restarts: int

    @property
    def solved(self) -> bool:
        """Whether the target was reached within the tolerances."""
        return self.status is IkStatus.SOLVED


@dataclass(frozen=True)
class _Attempt:
    q: np.ndarray  # (n,) reduced configuration
    cost: float  # squared weighted error [m^2]
    position_error_m: float
    rotation_error_rad: float
    iterations: int


class ArmIk:
    """IK of ``frame`` moving only ``joints``, built once and solved many times.

    One instance keeps Pinocchio work buffers: give each thread its own.

    Args:
        robot: The robot.
        joints: Names of the joints that move, all on the chain from the root to ``frame``.
        frame: Name of the frame to place, e.g. an arm's tool frame.
        options: Tolerances and effort; ``IkOptions()`` when None.

    """

    def __init__(
        self,
        robot: RobotModel,
        joints: Sequence[str],
        frame: str,
        options: IkOptions | None = None,
    ) -> None:
        self.robot = robot
        self.frame = frame
        self.options = IkOptions() if options is None else options
        self.joints: tuple[str, ...] = tuple(joints)
        model = robot.model
        frame_joint = model.frames[robot.frame_id(frame)].parentJoint
        chain = [model.names[j] for j in model.supports[frame_joint]]  # universe, root .. frame
        if not self.joints or len(set(self.joints)) != len(self.joints):
            raise InvalidInputError("joints", list(joints), "a non-empty list of distinct names")
        for name in self.joints:
            robot.joint_index(name)  # an unknown name raises here, listing the known ones
            if name not in chain:
                raise InvalidInputError(
                    "joints", name, f"a joint that moves {frame}: {', '.join(chain[1:])}"
                )
        # Joints off the chain cannot move the frame, so any value does to lock them; chain
        # joints the caller holds still are locked at q_init's values, rebuilt when those change.
        self._held = robot.joint_indices(n for n in chain[1:] if n not in self.joints)
        self._locked = [j for j in range(1, model.njoints) if model.names[j] not in self.joints]
        self._build(pin.neutral(model))

    def _build(self, q_reference: np.ndarray) -> None:
        self._held_values = q_reference[self._held].copy()
        self._model = pin.buildReducedModel(self.robot.model, self._locked, q_reference)
        self._data = self._model.createData()
        self._frame_id = self._model.getFrameId(self.frame)
        names = [self._model.names[j] for j in range(1, self._model.njoints)]
        self._full_index = self.robot.joint_indices(names)  # (n,) reduced q -> full q
        self._lower = np.array(self._model.lowerPositionLimit)  # (n,)
        self._upper = np.array(self._model.upperPositionLimit)  # (n,)

    def solve(
        self,
        T_world_target: pin.SE3,
        q_init: np.ndarray,
        rng: np.random.Generator | None = None,
    ) -> IkResult:
        """Find a configuration that puts the frame at ``T_world_target``.

        The first attempt starts from ``q_init`` (its arm joints projected onto the limits), so
        the answer tends to be the solution nearest to it: call again with another ``q_init`` for
        an alternative. Restarts draw arm configurations from ``rng``; when it is None a
        generator seeded with 0 is used, so the same call always gives the same answer.

        Args:
            T_world_target: Target pose of the frame in the world frame.
            q_init: Full start configuration (robot.nq,); joints outside the arm keep their values.
            rng: Source of the random restarts.

        Returns:
            The solution, or the best attempt with status NOT_CONVERGED: an unreachable target
            is an outcome, never an exception.

        """
        if not isinstance(T_world_target, pin.SE3):
            raise InvalidInputError(
                "T_world_target", type(T_world_target).__name__, "a pinocchio.SE3"
            )
        rotation = T_world_target.rotation
        if not (np.all(np.isfinite(T_world_target.homogeneous))
                and np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-6)
                and np.linalg.det(rotation) > 0):
            raise InvalidInputError(
                "T_world_target",
                np.round(T_world_target.homogeneous, 6).tolist(),
                "a finite rigid transform (orthonormal rotation with determinant +1)",
            )
        if np.shape(q_init) != (self.robot.nq,):
            raise InvalidInputError(
                "q_init", f"array of shape {np.shape(q_init)}", f"shape ({self.robot.nq},)"
            )
        q_init = np.array(q_init, dtype=float)
        if not np.all(np.isfinite(q_init)):
            raise InvalidInputError("q_init", q_init.tolist(), "finite joint values")
        if not np.array_equal(q_init[self._held], self._held_values):
            self._build(q_init)
        if rng is not None and not isinstance(rng, np.random.Generator):
            raise InvalidInputError("rng", rng, "a numpy.random.Generator or None")
        opts = self.options
        q = np.minimum(np.maximum(q_init[self._full_index], self._lower), self._upper)  # (n,)
        best = self._attempt(T_world_target, q)
        iterations, restart = best.iterations, 0
        while not self._reached(best) and restart < opts.max_restarts:
            restart += 1
            if rng is None:  # made only when needed: a new generator costs ~10 us
                rng = np.random.default_rng(0)
            attempt = self._attempt(T_world_target, rng.uniform(self._lower, self._upper))
            iterations += attempt.iterations
            if self._reached(attempt) or attempt.cost < best.cost:
                best = attempt
        status = IkStatus.SOLVED if self._reached(best) else IkStatus.NOT_CONVERGED
        q_full = q_init.copy()
        q_full[self._full_index] = best.q
        return IkResult(
            status, q_full, best.position_error_m, best.rotation_error_rad, iterations, restart
        )

    def _reached(self, attempt: _Attempt) -> bool:
        return (attempt.position_error_m <= self.options.position_tolerance_m
                and attempt.rotation_error_rad <= self.options.rotation_tolerance_rad)

    def _attempt(self, T_world_target: pin.SE3, q: np.ndarray) -> _Attempt:
        """One Levenberg-Marquardt descent from the reduced configuration ``q`` (n,).

        A failed plan runs thousands of these: the norms are written as the square root of a
        dot and the free joints' block is taken by boolean indexing, the same operations as
        ``np.linalg.norm`` and ``np.ix_`` with fewer temporaries, so the same bits.
        """
        opts, model, data, frame_id = self.options, self._model, self._data, self._frame_id
        weight = np.array([1.0, 1.0, 1.0] + [opts.rotation_weight_m] * 3)  # (6,) -> [m]
        eye = np.eye(model.nq)
        gain = opts.limit_gain
        best_cost, since_best, iteration = math.inf, 0, 0
        while True:
            pin.computeJointJacobians(model, data, q)  # includes the forward kinematics
            T_frame_target = pin.updateFramePlacement(model, data, frame_id).actInv(T_world_target)
            twist = pin.log6(T_frame_target).vector  # (6,) body twist to the target
            translation, rotation = T_frame_target.translation, twist[3:]
            # np.linalg.norm of a vector is the square root of its dot with itself
            position_error_m = math.sqrt(translation.dot(translation))
            rotation_error_rad = math.sqrt(rotation.dot(rotation))
            error = weight * twist  # (6,) [m]
            cost = float(error @ error)
            if cost < 0.98 * best_cost:
                best_cost, since_best = cost, 0
            else:
                since_best += 1
            if ((position_error_m <= opts.position_tolerance_m
                    and rotation_error_rad <= opts.rotation_tolerance_rad)
                    or iteration >= opts.max_iterations or since_best >= opts.stall_iterations):
                return _Attempt(q, cost, position_error_m, rotation_error_rad, iteration)
            J_local = pin.getFrameJacobian(model, data, frame_id, pin.LOCAL)  # (6, n)
            J = weight[:, None] * (pin.Jlog6(T_frame_target.inverse()) @ J_local)  # (6, n)
            step_low, step_high = gain * (self._lower - q), gain * (self._upper - q)  # (n,)
            hessian = J.T @ J + (opts.damping * cost + _DAMPING_FLOOR) * eye  # (n, n)
            gradient = J.T @ error  # (n,)
            step = np.linalg.solve(hessian, gradient)
            # Joints that would pass their bound are pinned to it and the rest re-solved for
            # what remains, so one joint at a limit does not cut short the whole step.
            outside = (step < step_low) | (step > step_high)
            free = np.ones(len(q), dtype=bool)
            while outside.any():
                step = np.minimum(np.maximum(step, step_low), step_high)
                free &= ~outside
                if not free.any():
                    break
                pinned_step = np.where(free, 0.0, step)
                step[free] = np.linalg.solve(
                    hessian[free][:, free], (gradient - hessian @ pinned_step)[free]
                )
                outside = (step < step_low) | (step > step_high)
            q = np.minimum(np.maximum(q + step, self._lower), self._upper)  # rounding only
            iteration += 1
