"""The pick planner: grasp pose -> arm -> IK -> timed, collision-checked joint trajectories.

A pick is four segments, each a jerk-limited ruckig trajectory of one arm's joints:

    approach   start -> pre-grasp (the grasp backed off along its approach axis), gripper open
    descend    pre-grasp -> grasp, straight along the approach axis, slowly
    lift       grasp -> grasp raised by ``lift_height_m``, after the gripper closes
    retreat    lift -> the arm's start configuration, carrying the object

The planner tries the nearer arm first, both 180-degree-equivalent grasps of the parallel
gripper, and several IK solutions of each; every segment is checked densely (each sample at the
execution rate) against self-collision and the obstacles. It returns a plan, or a
:class:`PlanStatus` that says why not. No simulator in here.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping
from dataclasses import replace

import numpy as np
import pinocchio as pin

from control.collision import CollisionChecker, CollisionReport
from control.errors import InvalidInputError
from control.ik import ArmIk, IkOptions
from control.ik_candidates import GRIPPER_TURNS, Candidate, follow, ik_candidates
from control.pick import (
    ArmSpec,
    GripperCommand,
    PickPlan,
    PickPlannerConfig,
    PickRequest,
    PlanResult,
    PlanSegment,
    PlanStatus,
)
from control.retarget import JointState, RetargetError, retarget
from control.robot_model import RobotModel
from control.tcp_line import tcp_deviation_m
from control.trajectory import JointLimits, JointTrajectory, plan_segment, plan_through

REPLAN_CHECK_STEP_RAD = 0.01
"""A re-plan (mid-motion, where time is short) checks a trajectory's samples so that no joint
moves more than this between two checked ones [rad]: finer than a full-speed transit's 240 Hz
samples are apart (0.013 rad on the YuMi's joints 1-3 and 7, 0.029 rad on 4-6), while the
slow descend and lift, sampled every 0.005 rad, are checked at about every other sample."""

SHOWN_REASONS = 4
"""A failed plan's reason names the first this many candidates' failures (and a spent budget)."""


class PickPlanner:
    """Plans picks for a multi-arm robot; see the module docstring for the segments."""

    def __init__(
        self,
        robot: RobotModel,
        checker: CollisionChecker,
        arms: Mapping[str, ArmSpec],
        config: PickPlannerConfig | None = None,
        ik_options: IkOptions | None = None,
    ) -> None:
        if not arms:
            raise InvalidInputError("arms", dict(arms), "at least one arm")
        self.robot, self.checker, self.arms = robot, checker, dict(arms)
        self._target_names: list[str] = []
        self._check_step_rad: float | None = None  # set while a re-plan checks thinned
        self._moving_vias = True  # a re-plan's first pass tries no via poses
        self.config = config or PickPlannerConfig()
        options = ik_options or IkOptions()
        self._ik = {name: ArmIk(robot, spec.joints, spec.tcp_frame, options)
                    for name, spec in self.arms.items()}
        self._indices = {name: robot.joint_indices(spec.joints) for name, spec in self.arms.items()}
        self._limits = {
            (name, scale): JointLimits.from_robot(
                robot, spec.joints, spec.max_acceleration, spec.max_jerk, velocity_scale=scale
            )
            for name, spec in self.arms.items()
            for scale in (self.config.transit_velocity_scale, self.config.straight_velocity_scale)
        }

    def plan(self, request: PickRequest) -> PlanResult:
        """Plans one pick; never raises for an unreachable or blocked grasp."""
        return self._plan(request, None)

    def _plan(self, request: PickRequest, moving: JointState | None) -> PlanResult:
        started = time.perf_counter()
        self.robot.check_shape(request.q_start)
        if not isinstance(request.T_world_grasp, pin.SE3):
            kind = type(request.T_world_grasp).__name__
            raise InvalidInputError("T_world_grasp", kind, "pin.SE3")
        unknown = [arm for arm in request.arms if arm not in self.arms]
        if unknown:
            raise InvalidInputError("arms", request.arms, f"names among {', '.join(self.arms)}")
        q0 = self._start(request)
        self.checker.set_obstacles(request.obstacles + request.target_obstacles)
        self._target_names = [o.name for o in request.target_obstacles]
        start_report = self.checker.check(q0)
        if start_report.in_collision:
            return PlanResult(PlanStatus.START_IN_COLLISION, start_report.describe(),
                              planning_time_s=time.perf_counter() - started)
        pregrasp = request.pregrasp_distance_m or self.config.pregrasp_distance_m
        rng = np.random.default_rng(self.config.seed)
        budget = self.config.budget
        reasons: list[str] = []
        tried = attempted = 0
        any_ik = False
        spent = ""  # what ran out, once the budget stops the search
        for arm, grasp_name, T_grasp, distance_m in self._options(request, q0, pregrasp):
            found = False
            for attempts in self._attempt_stages(moving):
                if budget is not None and attempted >= budget.max_ik_attempts:
                    spent = f"{attempted} IK attempts"
                    break
                candidates = ik_candidates(
                    self.robot, self._ik[arm], self._indices[arm], arm, T_grasp, q0, distance_m,
                    self.config.lift_height_m, self.config.max_joint_jump_rad, rng, attempts)
                attempted += GRIPPER_TURNS * len(attempts)
                found = found or bool(candidates)
                for candidate in candidates:
                    if budget is not None and tried >= budget.max_candidates:
                        spent = f"{tried} candidate plans"
                        break
                    tried += 1
                    if len(reasons) >= SHOWN_REASONS and self._ends_collide(candidate):
                        continue  # fails wherever its motions are planned; its why unshown
                    plan, report = self._timed_plan(candidate, q0, moving)
                    if plan is not None:
                        return PlanResult(PlanStatus.SUCCESS, f"arm {arm}, {grasp_name}", plan,
                                          time.perf_counter() - started, tried, attempted)
                    reasons.append(f"arm {arm}, {grasp_name}: {report}")
                if spent:
                    break
            if not found and not spent:
                reasons.append(f"arm {arm}, {grasp_name}: no in-limit IK solution for pre-grasp "
                               f"({100 * distance_m:.0f} cm back), grasp and lift")
            any_ik = any_ik or found
            if spent:
                reasons.insert(0, f"planning budget spent: {spent} ({budget})")
                break
        status = PlanStatus.COLLISION if any_ik else PlanStatus.UNREACHABLE
        if any_ik and moving is not None:
            status = PlanStatus.RETARGET_FAILED
        return PlanResult(status, "; ".join(reasons[:SHOWN_REASONS + bool(spent)]), None,
                          time.perf_counter() - started, tried, attempted)

    def _options(self, request: PickRequest, q0: np.ndarray, pregrasp_m: float
                 ) -> Iterator[tuple[str, str, pin.SE3, float]]:
        """What the search tries, in order: arm, grasp's name, grasp, pre-grasp back-off [m].

        The grasp first, then each alternative; for each, the nearer arm first; for each, the
        back-offs of ``pregrasp_scales`` in order.
        """
        for number, T_grasp in enumerate((request.T_world_grasp, *request.alternatives)):
            grasp_name = "grasp" if number == 0 else f"alternative {number}"
            for arm in self._arms_by_distance(q0, T_grasp.translation, request.arms):
                for scale in self.config.pregrasp_scales:
                    yield arm, grasp_name, T_grasp, scale * pregrasp_m

    def replan(self, request: PickRequest, moving: JointState) -> PlanResult:
        """A new pick for the arm in motion, its approach re-targeted from its moving state.

        Plans as :meth:`plan` from ``request.q_start`` (the robot's configuration now), for the
        moving arm only, each candidate's approach the jerk-limited motion from ``moving`` to
        its pre-grasp (:func:`control.retarget.retarget`) instead of a move from rest, checked
        at every sample as every segment is; a candidate whose motion collides or leaves a
        limit gives way to the next. Every candidate's direct motion is tried before any passes
        via poses (a second pass, only if none serves: vias cost six checked paths a candidate).
        The approach's first sample is ``moving``: the switch is continuous. No plan
        (``RETARGET_FAILED`` where IK found candidates, ``UNREACHABLE`` where not) tells the
        caller to keep the plan it follows, or to stop.

        Raises:
            InvalidInputError: ``moving`` is not the joints of one arm, in order.

        """
        arm = next((name for name, spec in self.arms.items()
                    if spec.joints == moving.joint_names), None)
        if arm is None:
            raise InvalidInputError("moving.joint_names", moving.joint_names, "one arm's joints: "
                                    + "; ".join(f"{a}: {s.joints}" for a, s in self.arms.items()))
        self._check_step_rad, self._moving_vias = REPLAN_CHECK_STEP_RAD, False
        try:
            result = self._plan(replace(request, arms=(arm,)), moving)
            if result.status is PlanStatus.RETARGET_FAILED:
                self._moving_vias = True
                result = self._plan(replace(request, arms=(arm,)), moving)
            return result
        finally:
            self._check_step_rad, self._moving_vias = None, True

    def _start(self, request: PickRequest) -> np.ndarray:
        """The start configuration: ``q_start`` within limits, every gripper open as asked.

        The fingers' measured values are not checked: they are replaced (a hand opened wider
        than the URDF's finger limit for a wide grip, mid-approach, is no error).
        """
        self.robot.check_shape(request.q_start)
        fingers = [self.robot.joint_index(f) for s in self.arms.values() for f in s.finger_joints]
        q = np.array(request.q_start, dtype=float)
        q[fingers] = self.robot.lower_rad[fingers]
        q0 = self.robot.clip_to_limits(q, "q_start")
        opening = request.finger_opening_m
        q0[fingers] = self.robot.upper_rad[fingers] if opening is None else opening
        return q0

    def transit_limits(self, arm: str) -> JointLimits:
        """The joint limits ``arm``'s approach and retreat are planned under."""
        return self._limits[(arm, self.config.transit_velocity_scale)]

    def _arms_by_distance(self, q: np.ndarray, target: np.ndarray,
                          allowed: tuple[str, ...] = ()) -> list[str]:
        def distance(arm: str) -> float:
            shoulder = self.robot.frame_pose(q, self.arms[arm].shoulder_frame).translation
            return float(np.linalg.norm(shoulder - target))

        return sorted((arm for arm in self.arms if not allowed or arm in allowed), key=distance)

    def _attempt_stages(self, moving: JointState | None) -> tuple[range, ...]:
        """The IK attempts tried together, in order.

        All at once from rest; mid-motion (a re-plan, where time is short) the one seeded from
        the configuration now first, which usually serves, the random restarts only if not.
        """
        every = range(self.config.ik_solutions_per_grasp)
        return (every,) if moving is None else (every[:1], every[1:])

    def _ends_collide(self, c: Candidate) -> bool:
        """Whether a segment of ``c`` must end in collision, so no plan of it can pass.

        Every checked segment's last sample is its end exactly (:func:`plan_segment`,
        :func:`retarget`; thinning keeps the last sample too): the approach ends at the
        pre-grasp, checked against the target; descend and lift at the grasp and the lift,
        checked ignoring it. Three configuration checks instead of timing and checking the
        motions: a garbage grasp inside the table or a neighbour (an untrained model's) gives
        a hundred such candidates, each costing tens of milliseconds to plan before it fails.
        """
        with self.checker.ignoring(self._target_names):
            if self.checker.check(c.q_grasp).in_collision \
                    or self.checker.check(c.q_lift).in_collision:
                return True
        return self.checker.check(c.q_pre).in_collision

    def _timed_plan(self, c: Candidate, q0: np.ndarray, moving: JointState | None
                    ) -> tuple[PickPlan | None, str]:
        approach, blocked = self._transit(c.arm, q0, c.q_pre, self.transit_limits(c.arm),
                                          moving=moving)
        if approach is None:
            return None, f"{'re-targeted ' * (moving is not None)}approach: {blocked}"
        with self.checker.ignoring(self._target_names):  # from here the hand holds the target
            return self._timed_rest(c, q0, approach)

    def _timed_rest(
        self, c: Candidate, q0: np.ndarray, approach: JointTrajectory
    ) -> tuple[PickPlan | None, str]:
        arm = c.arm
        fast = self._limits[(arm, self.config.transit_velocity_scale)]
        slow = self._limits[(arm, self.config.straight_velocity_scale)]
        descend = self._straight(arm, c.q_pre, c.q_grasp, slow)
        if descend is None:
            return None, "descend leaves the straight line and IK cannot follow it"
        lift = self._straight(arm, c.q_grasp, c.q_lift, slow)
        if lift is None:
            return None, "lift leaves the straight line and IK cannot follow it"
        retreat, blocked = self._transit(arm, q0, c.q_lift, fast, reverse=True)
        if retreat is None:
            return None, f"retreat: {blocked}"
        segments = (
            PlanSegment("approach", approach, GripperCommand.OPEN),
            PlanSegment("descend", descend),
            PlanSegment("lift", lift, GripperCommand.CLOSE),
            PlanSegment("retreat", retreat),
        )
        for segment in segments[1:3]:  # approach and retreat were checked when planned
            report = self._check(arm, q0, segment.trajectory)
            if report.in_collision:
                return None, f"{segment.name}: {report.describe()}"
        return PickPlan(arm, segments, c.q_grasp, c.T_grasp), ""

    def _transit(
        self, arm: str, q0: np.ndarray, q_far: np.ndarray, limits: JointLimits,
        reverse: bool = False, moving: JointState | None = None,
    ) -> tuple[JointTrajectory | None, str]:
        """A checked move between the start and ``q_far``: direct, else through via poses.

        Returns the trajectory, or None and why the direct move (and every via option) failed.

        A straight joint-space line from the start can swing the hand through the robot's own
        body or through the target. The via poses lift the TCP straight up, at the far end, at
        the start, or at both (start first), tried in that order for each height in
        ``via_heights_m``; the first option whose whole path is clear wins. From rest the arm
        stops at each via (:func:`plan_through`); from a ``moving`` state (a re-plan, towards
        ``q_far``) it cannot wait, and passes them moving (:func:`retarget`'s ``vias``).
        """
        index = self._indices[arm]
        ends = (q_far, q0) if reverse else (q0, q_far)

        def move(vias: list[np.ndarray]) -> JointTrajectory:
            if moving is not None:
                return retarget(moving, q_far[index], limits, self.config.dt_s, vias)
            if not vias:  # the direct move: one straight segment, as every plan from rest has
                return plan_segment(ends[0][index], ends[1][index], limits, self.config.dt_s)
            return plan_through([ends[0][index], *vias, ends[1][index]], limits,
                                self.config.dt_s)

        try:
            direct = move([])
            report = self._check(arm, q0, direct)
            if not report.in_collision:
                return direct, ""
            why = report.describe()
        except RetargetError as error:  # e.g. a joint overshooting its limit on the way
            why = f"{error.result} ({error.detail or error})"
        if moving is not None and not self._moving_vias:
            return None, why
        far = q0.copy()
        far[index] = q_far[index]
        if self.checker.check(far).in_collision:  # every via option ends (or starts) there
            return None, f"{why}, and no via pose clears it"
        for height_m in self.config.via_heights_m:
            near_via = self._raised(arm, q0, height_m)
            far_via = self._raised(arm, q_far, height_m)
            for vias in ([far_via], [near_via], [near_via, far_via]):
                if any(v is None for v in vias):
                    continue
                middle = [v[index] for v in vias if v is not None]
                try:
                    path = move(middle[::-1] if reverse else middle)
                except RetargetError:
                    continue  # no motion passes these vias from this state: the next option
                if not self._check(arm, q0, path).in_collision:
                    return path, ""
        return None, f"{why}, and no via pose clears it"

    def _raised(self, arm: str, q: np.ndarray, height_m: float) -> np.ndarray | None:
        """The configuration with the TCP ``height_m`` straight above where ``q`` puts it."""
        T_tcp = self.robot.frame_pose(q, self.arms[arm].tcp_frame)
        raised = pin.SE3(np.eye(3), np.array([0.0, 0.0, height_m])) * T_tcp
        via = self._ik[arm].solve(raised, q)  # no jump limit: the path to it is checked
        return via.q if via.solved else None

    def check_ahead(self, arm: str, q_now: np.ndarray, trajectory: JointTrajectory
                    ) -> CollisionReport:
        """``arm``'s ``trajectory`` from ``q_now`` against the last plan's or re-plan's obstacles.

        A closed loop whose re-plan failed asks whether the plan it follows still runs clear of
        what that re-plan's frame shows, the target where it is now among it; if not, it stops.
        """
        return self._check(arm, q_now, trajectory)

    def _check(self, arm: str, q0: np.ndarray, trajectory: JointTrajectory) -> CollisionReport:
        """Checks the trajectory's samples (in a re-plan, every ``REPLAN_CHECK_STEP_RAD``)."""
        full = np.repeat(q0[None, :], len(trajectory.times_s), axis=0)  # (N, nq)
        full[:, self._indices[arm]] = trajectory.positions
        return self.checker.check_path(full, self._check_step_rad)

    def _straight(
        self, arm: str, q_from: np.ndarray, q_to: np.ndarray, limits: JointLimits
    ) -> JointTrajectory | None:
        """A segment whose TCP runs along the line between the two poses, within tolerance.

        A straight joint-space move is tried first; where its TCP strays from the line, the
        move is bisected at the line's midpoint (IK seeded from the nearer end), recursively.
        """
        index, frame = self._indices[arm], self.arms[arm].tcp_frame
        waypoints = self._bisect(arm, q_from, q_to, self.robot.frame_pose(q_from, frame),
                                 self.robot.frame_pose(q_to, frame), limits, depth=0)
        if waypoints is None:
            return None
        return plan_through([q_from[index], *[q[index] for q in waypoints]], limits,
                            self.config.dt_s)

    def _bisect(
        self, arm: str, q_a: np.ndarray, q_b: np.ndarray, T_a: pin.SE3, T_b: pin.SE3,
        limits: JointLimits, depth: int,
    ) -> list[np.ndarray] | None:
        """Waypoints after ``q_a`` up to ``q_b`` whose joint-space lines stay on the line."""
        index = self._indices[arm]
        direct = plan_segment(q_a[index], q_b[index], limits, self.config.dt_s)
        bend_m = tcp_deviation_m(self.robot, index, self.arms[arm].tcp_frame, q_a, direct, T_a, T_b)
        if bend_m <= self.config.max_straight_deviation_m:
            return [q_b]
        if depth >= 4:
            return None
        T_mid = pin.SE3.Interpolate(T_a, T_b, 0.5)
        middle = follow(self._ik[arm], T_mid, q_a, self.config.max_joint_jump_rad)
        if middle is None:
            return None
        first = self._bisect(arm, q_a, middle.q, T_a, T_mid, limits, depth + 1)
        second = self._bisect(arm, middle.q, q_b, T_mid, T_b, limits, depth + 1)
        if first is None or second is None:
            return None
        return first + second
