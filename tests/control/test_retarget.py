"""Re-targeting the YuMi's arms from moving states: continuity, limits, rest at the end, errors."""

from __future__ import annotations

import pickle
import re

import numpy as np
import pytest

from control.errors import InvalidInputError
from control.retarget import (
    JointState,
    RetargetError,
    retarget,
    splice,
    stop,
    trajectory_state,
)
from control.robot_model import RobotModel
from control.trajectory import JointLimits, JointTrajectory, plan_segment
from robots import yumi

DT_S = 1 / 240
CASES_PER_ARM = 200
# Tolerances as in test_trajectory.py: ruckig meets v and a limits up to round-off (measured
# here over 2000 random re-targets per arm: v within 6.7e-16, a within 2.3e-16 relative) and
# finite-difference jerk within 9.8e-11 relative (the short last step amplifies round-off of a).
POSITION_TOL = 1e-9  # [rad]
CONTINUITY_TOL = 1e-9  # first sample against the state: set exactly, so 0 in practice
RELATIVE_TOL = 1e-9  # of v_max and a_max
JERK_RELATIVE_TOL = 1e-6  # of j_max
# Consecutive samples lie at most v_max * step apart (what makes the per-sample collision check
# cover the curved path). Measured over 2000 re-targets and stops: 8.3e-14 relative, 1.1e-15 rad.
STEP_ABSOLUTE_TOL = 1e-12  # [rad], on top of RELATIVE_TOL
# ruckig's community edition ignores position limits, so a motion from a state too fast to turn
# before a limit is refused (RetargetError). Measured: 0 of 6000 random mid-segment states and
# goals on the right arm (2000 of them with goals within 1 mrad of the limits). Bound: 1 %.
MAX_REFUSED = CASES_PER_ARM // 100


def home(limits: JointLimits) -> np.ndarray:
    return np.array([yumi.HOME[name] for name in limits.joint_names])


def random_configuration(limits: JointLimits, rng: np.random.Generator) -> np.ndarray:
    return rng.uniform(limits.lower, limits.upper)


def moving(limits: JointLimits, rng: np.random.Generator) -> tuple[JointTrajectory, int]:
    """A random rest-to-rest segment and one of its inner samples: a reachable moving state."""
    executed = plan_segment(random_configuration(limits, rng), random_configuration(limits, rng),
                            limits, DT_S)
    return executed, int(rng.integers(1, executed.times_s.size - 1))


def assert_within_limits(trajectory: JointTrajectory, limits: JointLimits) -> None:
    assert np.all(trajectory.positions >= limits.lower - POSITION_TOL)
    assert np.all(trajectory.positions <= limits.upper + POSITION_TOL)
    assert np.all(np.abs(trajectory.velocities) <= limits.max_velocity * (1 + RELATIVE_TOL))
    assert np.all(np.abs(trajectory.accelerations) <= limits.max_acceleration * (1 + RELATIVE_TOL))
    steps_s = np.diff(trajectory.times_s)[:, None]
    jerk = np.diff(trajectory.accelerations, axis=0) / steps_s
    assert np.all(np.abs(jerk) <= limits.max_jerk * (1 + JERK_RELATIVE_TOL))
    moved = np.abs(np.diff(trajectory.positions, axis=0))
    assert np.all(moved <= limits.max_velocity * steps_s * (1 + RELATIVE_TOL) + STEP_ABSOLUTE_TOL)


def assert_starts_at(trajectory: JointTrajectory, state: JointState) -> None:
    assert trajectory.joint_names == state.joint_names
    for field in ("positions", "velocities", "accelerations"):
        first = getattr(trajectory, field)[0]
        np.testing.assert_allclose(first, getattr(state, field), rtol=0, atol=CONTINUITY_TOL)


def assert_sampled_every_dt(trajectory: JointTrajectory) -> None:
    steps = np.diff(trajectory.times_s)
    np.testing.assert_allclose(steps[:-1], DT_S, rtol=0, atol=1e-12)
    assert 1e-6 * DT_S <= steps[-1] <= (1 + 1e-6) * DT_S


def test_random_retargets_are_continuous_within_limits_and_end_at_rest(
    limits: JointLimits,
) -> None:
    rng = np.random.default_rng(36)
    refused = 0
    for _ in range(CASES_PER_ARM):
        executed, k = moving(limits, rng)
        state, goal = trajectory_state(executed, k), random_configuration(limits, rng)
        try:
            new = retarget(state, goal, limits, DT_S)
        except RetargetError as error:
            assert error.result == "ErrorPositionalLimits"
            refused += 1
            continue
        assert_starts_at(new, state)
        assert_within_limits(new, limits)
        assert_sampled_every_dt(new)
        np.testing.assert_array_equal(new.positions[-1], goal)
        np.testing.assert_array_equal(new.velocities[-1], 0.0)
        np.testing.assert_array_equal(new.accelerations[-1], 0.0)
    assert refused <= MAX_REFUSED


def test_vias_are_passed_moving_and_the_motion_ends_at_rest(limits: JointLimits) -> None:
    # A re-plan goes over an obstacle by via poses it cannot wait at: each is a sample of the
    # motion, reached at the pace of the straight move to the next, never at rest. Vias in the
    # middle half of each joint's range, as raised pre-grasps lie: none refused (measured, 200
    # per arm); passed that fast near a limit, a joint may overshoot it (RetargetError).
    rng = np.random.default_rng(37)
    for _ in range(40):
        executed, k = moving(limits, rng)
        state = trajectory_state(executed, k)
        vias = [limits.lower + (limits.upper - limits.lower) * rng.uniform(0.25, 0.75, 7)
                for _ in range(2)]
        goal = random_configuration(limits, rng)
        new = retarget(state, goal, limits, DT_S, vias)
        assert_starts_at(new, state)
        assert_within_limits(new, limits)
        for via, after in zip(vias, [*vias[1:], goal], strict=True):
            at = int(np.argmin(np.max(np.abs(new.positions - via), axis=1)))
            np.testing.assert_array_equal(new.positions[at], via)
            pace = plan_segment(via, after, limits, DT_S).duration_s
            np.testing.assert_allclose(new.velocities[at], (after - via) / pace, atol=1e-12)
            assert np.any(new.velocities[at] != 0.0)
        np.testing.assert_array_equal(new.positions[-1], goal)
        np.testing.assert_array_equal(new.velocities[-1], 0.0)


def test_from_rest_retarget_is_at_most_as_long_as_the_straight_segment(right: JointLimits) -> None:
    # Both are time-optimal; the straight line is one more constraint than Time synchronization.
    rng = np.random.default_rng(1)
    for _ in range(20):
        start, goal = random_configuration(right, rng), random_configuration(right, rng)
        free = retarget(JointState.at_rest(right.joint_names, start), goal, right, DT_S)
        assert free.duration_s <= plan_segment(start, goal, right, DT_S).duration_s + 1e-9


def test_goal_equal_to_a_state_at_rest_gives_one_sample(limits: JointLimits) -> None:
    q = home(limits)
    trajectory = retarget(JointState.at_rest(limits.joint_names, q), q, limits)
    assert trajectory.times_s.tolist() == [0.0]
    np.testing.assert_array_equal(trajectory.positions, q[None])
    np.testing.assert_array_equal(trajectory.velocities, 0.0)
    assert stop(JointState.at_rest(limits.joint_names, q), limits).times_s.tolist() == [0.0]


def test_trajectory_state_is_the_sample(right: JointLimits) -> None:
    executed = plan_segment(home(right), np.zeros(7), right)
    state = trajectory_state(executed, np.int64(10))  # type: ignore[arg-type]
    np.testing.assert_array_equal(state.positions, executed.positions[10])
    np.testing.assert_array_equal(state.velocities, executed.velocities[10])
    np.testing.assert_array_equal(state.accelerations, executed.accelerations[10])
    assert not state.positions.flags.writeable
    for k in (-1, executed.times_s.size, 1.0, True):
        message = re.escape(f"k = {k!r} is not allowed: a sample index")
        with pytest.raises(InvalidInputError, match=message):
            trajectory_state(executed, k)  # type: ignore[arg-type]


def test_splice_is_continuous_at_the_seam(limits: JointLimits) -> None:
    rng = np.random.default_rng(2)
    for _ in range(20):
        executed, k = moving(limits, rng)
        new = retarget(trajectory_state(executed, k), random_configuration(limits, rng), limits)
        record = splice(executed, k, new)
        assert record.times_s.size == k + new.times_s.size
        assert record.duration_s == pytest.approx(executed.times_s[k] + new.duration_s, abs=1e-12)
        for field in ("times_s", "positions", "velocities", "accelerations"):
            np.testing.assert_array_equal(getattr(record, field)[: k + 1],
                                          getattr(executed, field)[: k + 1])
        np.testing.assert_array_equal(record.positions[k:], new.positions)
        assert_within_limits(record, limits)  # jerk across the seam included
        assert_sampled_every_dt(record)


def test_splice_refuses_a_new_that_does_not_start_at_the_sample(
    right: JointLimits, yumi_model: RobotModel
) -> None:
    executed = plan_segment(home(right), np.zeros(7), right)
    elsewhere = retarget(trajectory_state(executed, 20), np.zeros(7), right)
    seam = r"new\.positions\[0\]\[yumi_joint_\d_r\] = .* is not allowed: equal to executed\[10\]"
    with pytest.raises(InvalidInputError, match=seam):
        splice(executed, 10, elsewhere)
    left = JointLimits.from_robot(yumi_model, yumi.ARM_JOINTS["l"], yumi.MAX_ACCELERATION_RAD_S2,
                                  yumi.MAX_JERK_RAD_S3)
    other_arm = plan_segment(home(left), home(left), left)
    with pytest.raises(InvalidInputError, match=r"new\.joint_names = .* the same joints"):
        splice(executed, 10, other_arm)
    with pytest.raises(InvalidInputError, match=r"at_index = 9999 is not allowed: a sample index"):
        splice(executed, 9999, elsewhere)


def test_stop_ends_at_rest_within_limits(limits: JointLimits) -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        executed, k = moving(limits, rng)
        state = trajectory_state(executed, k)
        halt = stop(state, limits, DT_S)
        assert_starts_at(halt, state)
        assert_within_limits(halt, limits)
        assert_sampled_every_dt(halt)
        np.testing.assert_array_equal(halt.velocities[-1], 0.0)
        np.testing.assert_array_equal(halt.accelerations[-1], 0.0)
        # Each joint brakes as hard as it may, so it stops no later than a re-target would.
        assert halt.duration_s <= retarget(state, executed.positions[-1], limits).duration_s + 1e-9


def test_a_state_too_fast_to_turn_before_a_limit_is_refused(right: JointLimits) -> None:
    # Joint 1 runs at full speed 0.05 rad below its upper limit: braking takes ~0.9 rad.
    positions, velocities = home(right), np.zeros(7)
    positions[0], velocities[0] = right.upper[0] - 0.05, right.max_velocity[0]
    state = JointState(right.joint_names, positions, velocities, np.zeros(7))
    for plan in (lambda: retarget(state, home(right), right), lambda: stop(state, right)):
        with pytest.raises(RetargetError, match=f"ErrorPositionalLimits.*{right.joint_names[0]}"):
            plan()
    try:
        retarget(state, home(right), right)
    except RetargetError as error:
        copy = pickle.loads(pickle.dumps(error))
        assert str(copy) == str(error) and copy.result == "ErrorPositionalLimits"


def bad_inputs(limits: JointLimits) -> list[tuple[dict[str, object], str]]:
    """Keyword overrides of a valid retarget call, and the message each must raise."""
    names, q = limits.joint_names, home(limits)
    zeros, j0, j3 = np.zeros(7), re.escape(names[0]), re.escape(names[3])
    too_fast, too_hard, beyond = zeros.copy(), zeros.copy(), q.copy()
    too_fast[3] = -1.01 * limits.max_velocity[3]
    too_hard[0] = 1.01 * limits.max_acceleration[0]
    beyond[0] = limits.upper[0] + 1e-6
    state = JointState.at_rest(names, q)
    return [
        ({"state": JointState(names[::-1], q, zeros, zeros)},
         r"state\.joint_names = .* is not allowed: the joints of limits, in order"),
        ({"state": JointState.at_rest(names, beyond)},
         rf"state\.positions\[{j0}\] = 2\.94088\d* is not allowed: within \[-2\.94088, 2\.94088\]"),
        ({"state": JointState(names, q, too_fast, zeros)},
         rf"state\.velocities\[{j3}\] = -3\.17\d* is not allowed: within \[-3\.14159, 3\.14159\]"),
        ({"state": JointState(names, q, zeros, too_hard)},
         rf"state\.accelerations\[{j0}\] = 6\.06\d* is not allowed: within \[-6\.0, 6\.0\]"),
        ({"state": q}, r"state = 'an object of type ndarray' is not allowed: a JointState"),
        ({"q_goal": beyond}, rf"q_goal\[{j0}\] = 2\.94088\d* is not allowed: within \[-2\.94"),
        ({"q_goal": q[:6]}, r"q_goal = 'array of shape \(6,\)' is not allowed: shape \(7,\)"),
        ({"vias": [q, beyond]}, rf"vias\[1\]\[{j0}\] = 2\.94088\d* is not allowed: within"),
        ({"q_goal": q, "state": state, "dt_s": 0.0},
         r"dt_s = 0\.0 is not allowed: a finite step > 0 in \[s\]"),
    ]


def test_bad_input_names_the_field_the_value_and_what_is_allowed(right: JointLimits) -> None:
    for override, message in bad_inputs(right):
        call = {"state": JointState.at_rest(right.joint_names, home(right)),
                "q_goal": np.zeros(7), "limits": right, **override}
        with pytest.raises(InvalidInputError, match=message):
            retarget(**call)  # type: ignore[arg-type]
    velocities = np.zeros(7)
    velocities[2] = np.nan
    with pytest.raises(InvalidInputError, match=re.escape(
            f"velocities[{right.joint_names[2]}] = nan is not allowed: a finite number")):
        JointState(right.joint_names, home(right), velocities, np.zeros(7))


def test_a_state_at_its_limits_within_round_off_is_accepted(right: JointLimits) -> None:
    positions = home(right)
    positions[0] = right.upper[0] + 1e-10
    at_limit = JointState.at_rest(right.joint_names, positions)
    np.testing.assert_array_equal(retarget(at_limit, home(right), right).positions[-1], home(right))
    wrist = right.joint_names.index("yumi_joint_4_r")
    velocities, accelerations = np.zeros(7), np.zeros(7)
    velocities[wrist] = right.max_velocity[wrist] * (1 + 1e-12)
    accelerations[wrist] = -right.max_acceleration[wrist]
    fast = JointState(right.joint_names, np.zeros(7), velocities, accelerations)
    assert_starts_at(retarget(fast, np.zeros(7), right), fast)
