"""A simulated robot: joints by name, position-controlled arms, force-limited grips."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pybullet

from perception.poses import Pose
from robots.description import GripperDescription, RobotDescription
from sim.errors import InvalidInputError


@dataclass(frozen=True)
class RobotConfig:
    """Joint controllers and finger contact of the simulated robot.

    Attributes:
        position_gain: PyBullet's ``positionGain`` for the arm motors: the share of a position
            error the motor removes per step (within its force limit). With the velocity fed
            forward, :meth:`SimRobot.track` follows a trajectory to ~5e-5 rad at 1 rad/s;
            0.5 removes a disturbance within a few steps without ringing.
        velocity_gain: PyBullet's ``velocityGain`` for the arm motors.
        finger_max_force_n: Grip force limit of each finger [N]; None: the gripper's rated
            force (:class:`~robots.description.GripperDescription`; the YuMi's 20 N).
        finger_max_speed_m_s: Speed limit of each finger [m/s]; None: the gripper's rated speed
            (the YuMi's 25 mm/s).
        finger_lateral_friction: Coulomb coefficient of the finger pads (rubber-like).
        finger_spinning_friction_m: Torsional friction of the pads [m]; keeps a pinched object
            from swinging about the closing axis.

    """

    position_gain: float = 0.5
    velocity_gain: float = 1.0
    finger_max_force_n: float | None = None
    finger_max_speed_m_s: float | None = None
    finger_lateral_friction: float = 1.0
    finger_spinning_friction_m: float = 0.003

    def __post_init__(self) -> None:
        for field, value, upper in (
            ("position_gain", self.position_gain, 1.0),
            ("velocity_gain", self.velocity_gain, 1.0),
        ):
            if not 0.0 < value <= upper:
                raise InvalidInputError(field, value, f"in (0, {upper}]")
        for name, rating in (("finger_max_force_n", self.finger_max_force_n),
                             ("finger_max_speed_m_s", self.finger_max_speed_m_s)):
            if rating is not None and rating <= 0.0:
                raise InvalidInputError(name, rating, "> 0, or None for the gripper's rating")
        if self.finger_lateral_friction <= 0.0:
            raise InvalidInputError("finger_lateral_friction", self.finger_lateral_friction, "> 0")
        if self.finger_spinning_friction_m < 0.0:
            raise InvalidInputError(
                "finger_spinning_friction_m", self.finger_spinning_friction_m, ">= 0 m"
            )


@dataclass(frozen=True)
class TrackingReport:
    """How closely :meth:`SimRobot.track` followed a joint trajectory.

    Attributes:
        steps: Physics steps taken (one per trajectory row, fewer if stopped early).
        max_error_rad: Largest |q - q_ref| over all steps and joints [rad].
        max_error_joint: The joint where it occurred.
        final_error_rad: Largest |q - q_ref| after the last step [rad].
        stopped_early: Whether the per-step callback stopped the motion.

    """

    steps: int
    max_error_rad: float
    max_error_joint: str
    final_error_rad: float
    stopped_early: bool


@dataclass(frozen=True)
class GripperContacts:
    """Bodies (other than the robot) that each finger of one gripper touches."""

    by_finger: tuple[frozenset[int], frozenset[int]]

    @property
    def touched(self) -> frozenset[int]:
        """Bodies touched by either finger."""
        return self.by_finger[0] | self.by_finger[1]

    @property
    def held(self) -> frozenset[int]:
        """Bodies touched by both fingers: pinched between them."""
        return self.by_finger[0] & self.by_finger[1]


StepCallback = Callable[[int], bool | None]
"""Called after each tracking step with the step index; returning True stops the motion."""


class SimRobot:
    """A robot's body in one PyBullet world, addressed by joint and link names.

    Its arms and grippers go by the names its :class:`~robots.description.RobotDescription`
    gives them.

    Args:
        client: The world's ``BulletClient``.
        body_id: The loaded robot's body id.
        config: Controller and finger settings.
        step: Advances the physics one step and must call :meth:`before_step` first (the world's
            ``step``, which also keeps the clock); when None the robot steps the client itself.
        robot: What the body is (required: the caller's robot): its grippers and home pose.

    """

    def __init__(
        self, client: Any, body_id: int, config: RobotConfig | None = None,
        step: Callable[[], None] | None = None, *, robot: RobotDescription,
    ) -> None:
        self.client = client
        self.body_id = body_id
        self.description = robot
        self.config = RobotConfig() if config is None else config
        self._grippers = {arm.name: arm.gripper for arm in robot.arms}
        # Each finger's force and speed: the config's, else the gripper's rating (per arm).
        self._finger_force_n = {arm: self.config.finger_max_force_n or g.max_force_n
                                for arm, g in self._grippers.items()}
        self._finger_speed_m_s = {arm: self.config.finger_max_speed_m_s or g.max_speed_m_s
                                  for arm, g in self._grippers.items()}
        self._step = self._step_alone if step is None else step
        self._time_step_s = float(client.getPhysicsEngineParameters()["fixedTimeStep"])
        # Per side, each finger's position [m]: where the last command sends it, and the motor
        # target that ramps there at the rated speed.
        self._finger_goal_m: dict[str, float] = {}
        self._finger_target_m: dict[str, float] = {}
        self._joint: dict[str, int] = {}
        self._link: dict[str, int] = {client.getBodyInfo(body_id)[0].decode(): -1}
        self._effort: dict[str, float] = {}
        self._limits: dict[str, tuple[float, float]] = {}
        for index in range(client.getNumJoints(body_id)):
            info = client.getJointInfo(body_id, index)
            self._link[info[12].decode()] = index
            if info[2] != pybullet.JOINT_FIXED:
                self._joint[info[1].decode()] = index
                self._effort[info[1].decode()] = float(info[10])
                self._limits[info[1].decode()] = (float(info[8]), float(info[9]))
        self.joint_names: tuple[str, ...] = tuple(self._joint)
        self._fingers = {name for g in self._grippers.values() for name in g.finger_joints}
        for name in self._fingers:
            client.changeDynamics(
                body_id, self._joint[name],
                lateralFriction=self.config.finger_lateral_friction,
                spinningFriction=self.config.finger_spinning_friction_m,
            )
        self.reset(dict(robot.home))

    def joint_index(self, name: str) -> int:
        """PyBullet index of a movable joint."""
        try:
            return self._joint[name]
        except KeyError:
            allowed = f"one of {', '.join(self.joint_names)}"
            raise InvalidInputError("joint", name, allowed) from None

    def link_index(self, name: str) -> int:
        """PyBullet index of a link (-1 for the base link)."""
        try:
            return self._link[name]
        except KeyError:
            raise InvalidInputError("link", name, f"one of {', '.join(self._link)}") from None

    def reset(self, q_by_name: Mapping[str, float]) -> None:
        """Teleport joints to ``q_by_name`` at rest; every motor then holds where it is."""
        indices = [self.joint_index(name) for name in q_by_name]
        for index, value in zip(indices, q_by_name.values(), strict=True):
            self.client.resetJointState(self.body_id, index, float(value), 0.0)
        arm = [n for n in self.joint_names if n not in self._fingers]
        current = self.joint_positions()
        self.command(arm, np.array([current[n] for n in arm]))
        for side, gripper in self._grippers.items():
            fingers = gripper.finger_joints
            self._finger_target_m[side] = sum(current[f] for f in fingers) / len(fingers)
            self._finger_goal_m[side] = self._finger_target_m[side]
            self._set_finger_motors(side)

    def joint_positions(self, names: Sequence[str] | None = None) -> dict[str, float]:
        """Joint positions [rad] or [m], keyed by name (all movable joints by default)."""
        chosen = self.joint_names if names is None else names
        states = self.client.getJointStates(self.body_id, [self.joint_index(n) for n in chosen])
        return {name: float(state[0]) for name, state in zip(chosen, states, strict=True)}

    def command(
        self, joint_names: Sequence[str], positions: np.ndarray,
        velocities: np.ndarray | None = None,
    ) -> None:
        """Set arm motor targets, held until the next command.

        Args:
            joint_names: Arm joints to drive (n of them).
            positions: Position targets (n,) [rad].
            velocities: Velocity targets (n,) [rad/s]; zero when None (hold still).

        """
        fingers = self._fingers.intersection(joint_names)
        if fingers:
            allowed = "arm joints (the fingers move with open_gripper/close_gripper)"
            raise InvalidInputError("joint_names", sorted(fingers), allowed)
        targets = np.asarray(positions, dtype=float)
        speeds = np.zeros_like(targets) if velocities is None else np.asarray(velocities, float)
        if targets.shape != (len(joint_names),) or speeds.shape != targets.shape:
            raise InvalidInputError(
                "positions/velocities", (targets.shape, speeds.shape),
                f"shape ({len(joint_names)},) each"
            )
        self.client.setJointMotorControlArray(
            self.body_id, [self.joint_index(n) for n in joint_names], pybullet.POSITION_CONTROL,
            targetPositions=targets.tolist(), targetVelocities=speeds.tolist(),
            forces=[self._effort[n] for n in joint_names],
            positionGains=[self.config.position_gain] * len(joint_names),
            velocityGains=[self.config.velocity_gain] * len(joint_names),
        )

    def track(
        self, joint_names: Sequence[str], positions: np.ndarray, velocities: np.ndarray,
        on_step: StepCallback | None = None,
    ) -> TrackingReport:
        """Follow a trajectory sampled at the physics rate: one step per row of (N, n) arrays."""
        positions, velocities = np.asarray(positions, float), np.asarray(velocities, float)
        if positions.ndim != 2 or positions.shape[1] != len(joint_names):
            raise InvalidInputError("positions", positions.shape, f"shape (N, {len(joint_names)})")
        if velocities.shape != positions.shape:
            raise InvalidInputError("velocities", velocities.shape, f"shape {positions.shape}")
        indices = [self.joint_index(n) for n in joint_names]
        lower, upper = np.array([self._limits[n] for n in joint_names]).T  # (n,) each
        outside = (positions < lower - 1e-9) | (positions > upper + 1e-9)  # (N, n)
        if outside.any():
            row, col = np.argwhere(outside)[0]
            raise InvalidInputError(
                f"positions[{row}] of {joint_names[col]}", float(positions[row, col]),
                f"within the joint limits [{lower[col]}, {upper[col]}] rad",
            )
        # Row k is the state wanted at the end of step k. PyBullet's motor moves q by
        # kp (target - q) + v dt in a step, so the position target is the row minus v dt.
        targets = positions - velocities * self._time_step_s
        worst, worst_joint, error, steps, stopped = 0.0, joint_names[0], np.zeros(0), 0, False
        for row in range(positions.shape[0]):
            self.command(joint_names, targets[row], velocities[row])
            self._step()
            states = self.client.getJointStates(self.body_id, indices)
            error = np.abs(np.array([s[0] for s in states]) - positions[row])  # (n,)
            steps = row + 1
            if float(error.max()) > worst:
                worst, worst_joint = float(error.max()), joint_names[int(error.argmax())]
            if on_step is not None and on_step(row):
                stopped = True
                break
        final = float(error.max()) if error.size else 0.0
        return TrackingReport(steps, worst, worst_joint, final, stopped)

    def link_pose(self, name: str) -> Pose:
        """World pose of a link's URDF frame, e.g. an arm's ``tcp_frame``."""
        index = self.link_index(name)
        if index == -1:
            position, quaternion = self.client.getBasePositionAndOrientation(self.body_id)
            inertial = np.array(self.client.getDynamicsInfo(self.body_id, -1)[3])
            rotation = _matrix(self.client, quaternion)
            return Pose(np.array(position) - rotation @ inertial, rotation)
        state = self.client.getLinkState(self.body_id, index, computeForwardKinematics=True)
        return Pose(np.array(state[4], dtype=float), _matrix(self.client, state[5]))

    def open_gripper(self, side: str, opening_m: float | None = None) -> None:
        """Drive the fingers of arm ``side`` apart to a gap of ``opening_m`` [m].

        None opens them fully, to the gripper's ``max_opening_m``.
        """
        widest = self._gripper(side).max_opening_m
        opening_m = widest if opening_m is None else opening_m
        if not 0.0 <= opening_m <= widest:
            raise InvalidInputError("opening_m", opening_m, f"in [0, {widest}] m")
        self._drive_fingers(side, opening_m)

    def close_gripper(self, side: str) -> None:
        """Close the fingers of ``side``; each then squeezes what it meets with its force limit."""
        self._drive_fingers(side, 0.0)

    def gripper_opening_m(self, side: str) -> float:
        """Gap between the finger faces of ``side`` [m]."""
        return sum(self.joint_positions(self._finger_joints(side)).values())

    def gripper_done(self, side: str) -> bool:
        """Tell whether the last open/close of ``side`` has run its course.

        The fingers may have stopped earlier on an object; they then squeeze it.
        """
        self._finger_joints(side)  # checks the name
        return self._finger_target_m[side] == self._finger_goal_m[side]

    def gripper_contacts(self, side: str) -> GripperContacts:
        """Which bodies each finger of ``side`` touches now (after the last step)."""
        found = []
        for joint in self._finger_joints(side):
            points = self.client.getContactPoints(bodyA=self.body_id, linkIndexA=self._joint[joint])
            found.append(frozenset(int(p[2]) for p in points if p[2] != self.body_id))
        return GripperContacts((found[0], found[1]))

    def _gripper(self, side: str) -> GripperDescription:
        if side not in self._grippers:
            raise InvalidInputError("side", side, f"one of {', '.join(map(repr, self._grippers))}")
        return self._grippers[side]

    def _finger_joints(self, side: str) -> tuple[str, ...]:
        return self._gripper(side).finger_joints

    def before_step(self) -> None:
        """Move the finger targets on by one step; called before every physics step."""
        for side in self._grippers:
            goal = self._finger_goal_m[side]
            target = self._finger_target_m[side]
            if target != goal:
                reach = self._finger_speed_m_s[side] * self._time_step_s
                self._finger_target_m[side] = min(max(goal, target - reach), target + reach)
                self._set_finger_motors(side)

    def _step_alone(self) -> None:
        self.before_step()
        self.client.stepSimulation()

    def _drive_fingers(self, side: str, opening_m: float) -> None:
        self._finger_joints(side)  # checks the name
        self._finger_goal_m[side] = opening_m / 2

    def _set_finger_motors(self, side: str) -> None:
        # The target ramps at the rated speed and the motor lands on it each step (kp = 1). Once
        # an object stops the fingers, the target runs on into it and the motor pushes with its
        # force limit (the YuMi's: a 20 N squeeze). (PyBullet's own maxVelocity clamp would cap
        # the push far below it: its solver adds only about 0.04 N per iteration to a 7.5 g
        # finger.)
        for joint in self._finger_joints(side):
            self.client.setJointMotorControl2(
                self.body_id, self._joint[joint], pybullet.POSITION_CONTROL,
                targetPosition=self._finger_target_m[side], targetVelocity=0.0,
                force=self._finger_force_n[side], positionGain=1.0, velocityGain=1.0,
            )


def _matrix(client: Any, quaternion: Sequence[float]) -> np.ndarray:
    return np.array(client.getMatrixFromQuaternion(quaternion), dtype=float).reshape(3, 3)
