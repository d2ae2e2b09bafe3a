"""ruckig trajectories on the YuMi arms: limits, exact ends, straight paths, errors."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest
import ruckig

from control.errors import InvalidInputError
from control.robot_model import RobotModel
from control.trajectory import (
    JointLimits,
    JointTrajectory,
    TrajectoryError,
    plan_segment,
    plan_through,
)
from robots import yumi

DT_S = 1 / 240
# Tolerances of the limit checks. ruckig's profiles meet the limits up to round-off (measured:
# v and a within 2.3e-16 relative, finite-difference jerk within 3.6e-12 relative over 3000
# random segments). Jerk is |delta a / delta t| between consecutive samples, which by the mean
# value theorem is <= j_max exactly for ruckig's piecewise-constant jerk; the short last step
# (>= 1e-6 dt) amplifies the round-off of a, hence the looser relative tolerance.
POSITION_TOL = 1e-9  # [rad]
RELATIVE_TOL = 1e-9  # of v_max and a_max
JERK_RELATIVE_TOL = 1e-6  # of j_max
LINE_TOL = 1e-9  # [rad], distance of a sample from the start -> goal segment


def home(limits: JointLimits) -> np.ndarray:
    return np.array([yumi.HOME[name] for name in limits.joint_names])


def assert_within_limits(trajectory: JointTrajectory, limits: JointLimits) -> None:
    assert np.all(trajectory.positions >= limits.lower - POSITION_TOL)
    assert np.all(trajectory.positions <= limits.upper + POSITION_TOL)
    assert np.all(np.abs(trajectory.velocities) <= limits.max_velocity * (1 + RELATIVE_TOL))
    assert np.all(np.abs(trajectory.accelerations) <= limits.max_acceleration * (1 + RELATIVE_TOL))
    jerk = np.diff(trajectory.accelerations, axis=0) / np.diff(trajectory.times_s)[:, None]
    assert np.all(np.abs(jerk) <= limits.max_jerk * (1 + JERK_RELATIVE_TOL))


def assert_straight(trajectory: JointTrajectory, start: np.ndarray, goal: np.ndarray) -> None:
    """Every sample lies on the segment start -> goal, and the motion never turns back."""
    distance = goal - start
    along = (trajectory.positions - start) @ distance / (distance @ distance)  # (N,)
    off_line = trajectory.positions - start - along[:, None] * distance
    assert np.max(np.abs(off_line)) <= LINE_TOL
    assert along.min() >= -LINE_TOL and along.max() <= 1 + LINE_TOL
    assert np.all(np.diff(along) >= -LINE_TOL)


def assert_rest_to_rest(trajectory: JointTrajectory, start: np.ndarray, goal: np.ndarray) -> None:
    np.testing.assert_array_equal(trajectory.positions[0], start)
    np.testing.assert_array_equal(trajectory.positions[-1], goal)
    for state in (trajectory.velocities, trajectory.accelerations):
        np.testing.assert_array_equal(state[[0, -1]], 0.0)


def random_pairs(limits: JointLimits, rng: np.random.Generator, count: int):
    """Uniform pairs, pairs within 1 mrad of the limits or on them, long wrist moves."""
    lower, upper = limits.lower, limits.upper
    for _ in range(count):
        yield rng.uniform(lower, upper), rng.uniform(lower, upper)
    for _ in range(count // 2):
        near_lower = lower + rng.uniform(0, 1e-3, lower.size)
        near_upper = upper - rng.uniform(0, 1e-3, upper.size)
        near = np.where(rng.random(lower.size) < 0.5, near_lower, near_upper)
        yield near, rng.uniform(lower, upper)
        yield lower.copy(), upper.copy()
    wrist = 4
    assert limits.joint_names[wrist].startswith("yumi_joint_4_")  # the +-5.06 rad wrist joint
    for _ in range(count // 4):
        start, goal = rng.uniform(lower, upper), rng.uniform(lower, upper)
        start[wrist], goal[wrist] = -5.0, 5.0
        yield start, goal


def test_random_segments_are_within_limits_straight_and_rest_to_rest(limits: JointLimits) -> None:
    rng = np.random.default_rng(7)
    for start, goal in random_pairs(limits, rng, 500):
        trajectory = plan_segment(start, goal, limits, DT_S)
        assert_within_limits(trajectory, limits)
        assert_rest_to_rest(trajectory, start, goal)
        assert_straight(trajectory, start, goal)
        steps = np.diff(trajectory.times_s)
        np.testing.assert_allclose(steps[:-1], DT_S, rtol=0, atol=1e-12)
        assert 1e-6 * DT_S <= steps[-1] <= (1 + 1e-6) * DT_S


def test_limits_are_reached_so_the_limit_checks_are_tight(right: JointLimits) -> None:
    # A lone 10 rad wrist move reaches j_max, a_max and v_max: T = d/v + v/a + a/j.
    wrist = right.joint_names.index("yumi_joint_4_r")
    start, goal = home(right), home(right)
    start[wrist], goal[wrist] = -5.0, 5.0
    trajectory = plan_segment(start, goal, right)
    v, a, j = right.max_velocity[wrist], right.max_acceleration[wrist], right.max_jerk[wrist]
    assert trajectory.duration_s == pytest.approx(10.0 / v + v / a + a / j, rel=1e-12)
    assert np.max(np.abs(trajectory.velocities[:, wrist])) == pytest.approx(v, rel=1e-12)
    assert np.max(np.abs(trajectory.accelerations[:, wrist])) == pytest.approx(a, rel=1e-12)
    jerk = np.diff(trajectory.accelerations[:, wrist]) / np.diff(trajectory.times_s)
    assert np.max(np.abs(jerk)) == pytest.approx(j, rel=1e-9)


def test_velocity_scale_slows_the_motion(yumi_model: RobotModel, right: JointLimits) -> None:
    slow = JointLimits.from_robot(yumi_model, yumi.ARM_JOINTS["r"], yumi.MAX_ACCELERATION_RAD_S2,
                                  yumi.MAX_JERK_RAD_S3, velocity_scale=0.5)
    np.testing.assert_allclose(slow.max_velocity, 0.5 * right.max_velocity)
    start, goal = home(right), home(right)
    start[4], goal[4] = -5.0, 5.0
    fast_motion, slow_motion = plan_segment(start, goal, right), plan_segment(start, goal, slow)
    assert slow_motion.duration_s > fast_motion.duration_s
    assert np.max(np.abs(slow_motion.velocities[:, 4])) == pytest.approx(slow.max_velocity[4])


def test_straight_where_ruckig_phase_synchronization_falls_back_to_time(right: JointLimits) -> None:
    # For this pair ruckig's Phase-scaled profile breaks a limit, and ruckig silently returns a
    # Time-synchronized, curved path (checked here, so the case stays pinned). Ours stays straight.
    start = np.array([-0.29, 0.09, -1.58, -1.97, -0.97, -0.75, -3.27])
    goal = np.array([0.47, -1.53, 1.01, -1.45, 4.48, -0.1, -3.15])
    inp = ruckig.InputParameter(7)
    inp.current_position, inp.target_position = start.tolist(), goal.tolist()
    inp.max_velocity = right.max_velocity.tolist()
    inp.max_acceleration = right.max_acceleration.tolist()
    inp.max_jerk = right.max_jerk.tolist()
    inp.synchronization = ruckig.Synchronization.Phase
    raw = ruckig.Trajectory(7)
    assert ruckig.Ruckig(7).calculate(inp, raw) == ruckig.Result.Working
    quarter = np.array(raw.at_time(raw.duration / 4)[0])  # halfway, every joint is halfway
    along = (quarter - start) @ (goal - start) / ((goal - start) @ (goal - start))
    assert np.max(np.abs(quarter - start - along * (goal - start))) > 0.01

    trajectory = plan_segment(start, goal, right)
    assert_straight(trajectory, start, goal)
    assert_within_limits(trajectory, right)
    assert_rest_to_rest(trajectory, start, goal)
    assert raw.duration <= trajectory.duration_s <= 1.05 * raw.duration


def test_sampling_never_leaves_a_sliver_of_a_last_step() -> None:
    # One joint with v = a = j = 1 moving 2 rad takes d/v + v/a + a/j = 4 s. With dt_s a hair
    # under 4/8 s, a sample at 8 dt_s would leave a last step of ~8e-8 dt_s; it is left out.
    one = np.ones(1)
    unit = JointLimits(("a",), -3 * one, 3 * one, one, one, one)
    exact = plan_segment(-one, one, unit, dt_s=0.5)
    assert exact.duration_s == pytest.approx(4.0, rel=1e-12)
    np.testing.assert_allclose(exact.times_s, np.arange(9) * 0.5, rtol=0, atol=1e-12)
    dt_s = exact.duration_s / 8 * (1 - 1e-8)
    hair = plan_segment(-one, one, unit, dt_s=dt_s)
    assert hair.times_s.size == 9 and hair.dt_s == dt_s
    assert np.diff(hair.times_s)[-1] == pytest.approx(dt_s * (1 + 8e-8), rel=1e-12)


def test_zero_and_tiny_moves(right: JointLimits) -> None:
    q = home(right)
    still = plan_segment(q, q, right)
    assert still.times_s.tolist() == [0.0] and still.duration_s == 0.0 and still.dt_s == 0.0
    np.testing.assert_array_equal(still.positions, [q])
    goal = q.copy()
    goal[0] += 1e-12
    tiny = plan_segment(q, goal, right)
    assert_rest_to_rest(tiny, q, goal)
    assert 0 < tiny.duration_s < DT_S and tiny.times_s.size == 2


def test_plan_through_stops_exactly_at_every_waypoint(limits: JointLimits) -> None:
    rng = np.random.default_rng(3)
    for _ in range(10):
        waypoints = [home(limits)] + [rng.uniform(limits.lower, limits.upper) for _ in range(4)]
        waypoints.append(waypoints[-1].copy())  # a repeated waypoint adds nothing
        trajectory = plan_through(waypoints, limits)
        assert_within_limits(trajectory, limits)
        assert_rest_to_rest(trajectory, waypoints[0], waypoints[-1])
        durations = [plan_segment(a, b, limits).duration_s for a, b in pairwise(waypoints)]
        assert trajectory.duration_s == pytest.approx(sum(durations), rel=1e-12)
        for waypoint, t_s in zip(waypoints, np.cumsum([0.0, *durations]), strict=True):
            k = int(np.argmin(np.abs(trajectory.times_s - t_s)))
            assert trajectory.times_s[k] == pytest.approx(t_s, abs=1e-9)
            np.testing.assert_array_equal(trajectory.positions[k], waypoint)
            np.testing.assert_array_equal(trajectory.velocities[k], 0.0)
    one = plan_through([home(limits)], limits)
    assert one.times_s.size == 1


def test_then_is_continuous_and_shifts_time(right: JointLimits) -> None:
    q0, q1, q2 = home(right), home(right) + 0.3, home(right) - 0.2
    first, second = plan_segment(q0, q1, right), plan_segment(q1, q2, right)
    both = first.then(second)
    assert both.times_s.size == first.times_s.size + second.times_s.size - 1
    assert both.duration_s == pytest.approx(first.duration_s + second.duration_s, rel=1e-15)
    assert np.all(np.diff(both.times_s) > 0)
    assert_within_limits(both, right)  # includes the jerk across the seam
    np.testing.assert_array_equal(both.positions[first.times_s.size - 1], q1)
    np.testing.assert_array_equal(both.at(first.duration_s + 0.5), second.at(0.5))


def test_at_interpolates_and_clamps(right: JointLimits) -> None:
    start, goal = home(right), home(right) + 0.4
    trajectory = plan_segment(start, goal, right)
    np.testing.assert_array_equal(trajectory.at(-1.0), start)
    np.testing.assert_array_equal(trajectory.at(trajectory.duration_s + 1.0), goal)
    np.testing.assert_array_equal(trajectory.at(3 * DT_S), trajectory.positions[3])
    halfway = trajectory.at(3.5 * DT_S)
    np.testing.assert_allclose(halfway, (trajectory.positions[3] + trajectory.positions[4]) / 2)
    with pytest.raises(InvalidInputError, match=r"t_s = nan is not allowed: a finite time in"):
        trajectory.at(math.nan)


def test_arrays_are_read_only(right: JointLimits) -> None:
    trajectory = plan_segment(home(right), home(right) + 0.1, right)
    with pytest.raises(ValueError, match="read-only"):
        trajectory.positions[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        right.max_velocity[0] = 100.0


def test_out_of_limits_and_bad_shapes_name_the_joint(right: JointLimits) -> None:
    q = home(right)
    goal = q.copy()
    goal[1] = 1.2
    message = r"q_goal\[yumi_joint_2_r\] = 1.2 is not allowed: within \[-2.50455, 0.75922\]"
    with pytest.raises(InvalidInputError, match=message):
        plan_segment(q, goal, right)
    with pytest.raises(InvalidInputError, match=r"waypoints\[2\]\[yumi_joint_2_r\] = 1.2"):
        plan_through([q, q, goal], right)
    shape = r"q_start = 'array of shape \(6,\)' is not allowed: shape \(7,\), one value per joint"
    with pytest.raises(InvalidInputError, match=shape + " of yumi_joint_1_r, yumi_joint_2_r"):
        plan_segment(q[:6], q, right)
    nan = r"q_start\[yumi_joint_1_r\] = nan is not allowed: a finite number"
    with pytest.raises(InvalidInputError, match=nan):
        plan_segment(np.full(7, np.nan), q, right)
    with pytest.raises(InvalidInputError, match=r"dt_s = 0.0 is not allowed: a finite step > 0"):
        plan_segment(q, q, right, dt_s=0.0)
    with pytest.raises(InvalidInputError, match="waypoints = 'an empty sequence'"):
        plan_through([], right)


@pytest.mark.parametrize("scale", [0.0, 1.5, -0.5, math.nan])
def test_velocity_scale_outside_zero_one_is_an_error(yumi_model: RobotModel, scale: float) -> None:
    message = r"velocity_scale = .* is not allowed: within \(0, 1\]"
    with pytest.raises(InvalidInputError, match=message):
        JointLimits.from_robot(yumi_model, yumi.ARM_JOINTS["r"], yumi.MAX_ACCELERATION_RAD_S2,
                               yumi.MAX_JERK_RAD_S3, velocity_scale=scale)


def test_from_robot_rejects_unknown_joints_and_missing_limits(yumi_model: RobotModel) -> None:
    unknown = "joint = 'elbow' is not allowed: one of the model's joints"
    with pytest.raises(InvalidInputError, match=unknown):
        JointLimits.from_robot(yumi_model, ["elbow"], yumi.MAX_ACCELERATION_RAD_S2,
                               yumi.MAX_JERK_RAD_S3)
    missing = ("max_acceleration = 'no value for gripper_r_joint' is not allowed: "
               "a value for every joint in joint_names")
    with pytest.raises(InvalidInputError, match=missing):
        JointLimits.from_robot(yumi_model, ["yumi_joint_1_r", "gripper_r_joint"],
                               yumi.MAX_ACCELERATION_RAD_S2, yumi.MAX_JERK_RAD_S3)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("max_jerk", [60.0, 0.0], r"max_jerk\[b\] = 0.0 is not allowed: > 0"),
        ("max_velocity", [-1.0, 1.0], r"max_velocity\[a\] = -1.0 is not allowed: > 0"),
        ("max_acceleration", [1.0, math.inf], r"max_acceleration\[b\] = inf .*: a finite number"),
        ("lower", [1.0, -1.0], r"lower\[a\] = 1.0 is not allowed: < upper = 1.0"),
        ("upper", [1.0], r"upper = 'array of shape \(1,\)' is not allowed: shape \(2,\)"),
        ("joint_names", ("a", "a"), r"joint_names = \('a', 'a'\) is not allowed: a non-empty"),
    ],
)
def test_joint_limits_validate_every_field(field: str, value: object, message: str) -> None:
    fields: dict[str, object] = {
        "joint_names": ("a", "b"), "lower": [-1.0, -1.0], "upper": [1.0, 1.0],
        "max_velocity": [1.0, 1.0], "max_acceleration": [1.0, 1.0], "max_jerk": [1.0, 1.0],
    }
    fields[field] = value
    with pytest.raises(InvalidInputError, match=message):
        JointLimits(**fields)  # type: ignore[arg-type]


def test_then_rejects_other_joints_and_jumps(yumi_model: RobotModel, right: JointLimits) -> None:
    left = JointLimits.from_robot(yumi_model, yumi.ARM_JOINTS["l"], yumi.MAX_ACCELERATION_RAD_S2,
                                  yumi.MAX_JERK_RAD_S3)
    q_right, q_left = home(right), home(left)
    first = plan_segment(q_right, q_right + 0.1, right)
    names = r"other.joint_names = \('yumi_joint_1_l', .* the same joints in the same order"
    with pytest.raises(InvalidInputError, match=names):
        first.then(plan_segment(q_left, q_left + 0.1, left))
    jump = (r"other.positions\[0\]\[yumi_joint_1_r\] = 0.0 is not allowed: "
            r"equal to this trajectory's last sample 0.1 \(within 1e-09\)")
    with pytest.raises(InvalidInputError, match=jump):
        first.then(plan_segment(q_right, q_right - 0.1, right))


def test_ruckig_failure_is_a_trajectory_error() -> None:
    # Valid by our checks, but ruckig finds no profile for a 1e-30 rad/s velocity limit.
    one, crawling = np.ones(1), np.array([1e-30])
    crawl = JointLimits(("a",), -one, one, crawling, one, one)
    with pytest.raises(TrajectoryError, match=r"ruckig could not plan \[0.0\] -> \[0.5\]") as error:
        plan_segment(np.array([0.0]), np.array([0.5]), crawl)
    assert "error in step 1" in error.value.result
