"""PickPlanner.replan: a new pick for the moving arm, its approach re-targeted mid-motion."""

import itertools

import numpy as np
import pinocchio as pin
import pytest
from tcp_poses import top_down

import control.planner as planner_module
from control.collision import Obstacle, ShapeKind
from control.errors import InvalidInputError
from control.pick import PickRequest, PlanStatus
from control.retarget import JointState, RetargetError, retarget, trajectory_state
from control.trajectory import SEAM_TOLERANCE
from robots import yumi

TABLE = Obstacle("table", ShapeKind.BOX, (1.5, 1.0, 0.05),
                 pin.SE3(np.eye(3), np.array([0.35, 0.0, -0.025])))


def moving_state(planner, home, grasp, fraction=0.5):
    """The robot halfway along the approach to ``grasp``: its full q and the arm's state."""
    plan = planner.plan(PickRequest(grasp, home, obstacles=(TABLE,))).plan
    approach = plan.segment("approach").trajectory
    k = int(fraction * (len(approach.times_s) - 1))
    state = trajectory_state(approach, k)
    q = home.copy()
    q[planner.robot.joint_indices(yumi.ARM_JOINTS[plan.arm])] = state.positions
    return plan, q, state


def test_a_moved_target_is_re_targeted_from_the_moving_state(yumi_planner, yumi_home):
    old, q_now, state = moving_state(yumi_planner, yumi_home, top_down(0.45, -0.10, 0.035))
    assert np.abs(state.velocities).max() > 0.1  # the arm is moving
    moved = top_down(0.50, -0.06, 0.035, yaw=1.2)
    result = yumi_planner.replan(PickRequest(moved, q_now, obstacles=(TABLE,)), state)
    assert result.status is PlanStatus.SUCCESS, result.reason
    plan = result.plan
    assert plan.arm == old.arm
    approach = plan.segment("approach").trajectory
    for field in ("positions", "velocities", "accelerations"):  # continuous at the switch
        np.testing.assert_allclose(getattr(approach, field)[0], getattr(state, field),
                                   atol=SEAM_TOLERANCE)
    np.testing.assert_array_equal(approach.velocities[-1], 0.0)  # at rest at the pre-grasp
    descend = plan.segment("descend").trajectory
    np.testing.assert_allclose(descend.positions[0], approach.positions[-1], atol=1e-9)
    reached = yumi_planner.robot.frame_pose(plan.q_grasp, yumi.TCP_FRAME[plan.arm])
    assert np.linalg.norm(reached.translation - moved.translation) < 5e-4


def test_the_moving_arm_keeps_the_pick_even_where_the_other_is_nearer(yumi_planner, yumi_home):
    old, q_now, state = moving_state(yumi_planner, yumi_home, top_down(0.45, -0.02, 0.035))
    across = top_down(0.45, 0.12, 0.035)  # now on the other arm's side
    assert yumi_planner.plan(PickRequest(across, q_now, obstacles=(TABLE,))).plan.arm != old.arm
    result = yumi_planner.replan(PickRequest(across, q_now, obstacles=(TABLE,)), state)
    assert result.ok, result.reason
    assert result.plan.arm == old.arm


def test_a_re_targeted_approach_carried_into_an_obstacle_is_refused(yumi_planner, yumi_home):
    """A box 10 samples ahead on the old approach: a plan from rest turns away from it, but the
    moving arm cannot: its re-targeted approach is refused, and the caller keeps or stops."""
    old, q_now, state = moving_state(yumi_planner, yumi_home, top_down(0.45, -0.10, 0.035), 0.7)
    approach = old.segment("approach").trajectory
    k = int(0.7 * (len(approach.times_s) - 1))
    ahead = yumi_home.copy()
    ahead[yumi_planner.robot.joint_indices(yumi.ARM_JOINTS[old.arm])] = approach.positions[k + 10]
    tcp = yumi_planner.robot.frame_pose(ahead, yumi.TCP_FRAME[old.arm]).translation
    wall = Obstacle("wall", ShapeKind.BOX, (0.03, 0.03, 0.03), pin.SE3(np.eye(3), tcp))
    asked = PickRequest(top_down(0.40, -0.25, 0.035), q_now, obstacles=(TABLE, wall))
    assert yumi_planner.plan(asked).ok  # from rest, the same pick is clear
    result = yumi_planner.replan(asked, state)
    assert (result.status, result.plan) == (PlanStatus.RETARGET_FAILED, None)
    assert result.reason.startswith(f"arm {old.arm}, grasp: re-targeted approach: collision at")
    assert "wall" in result.reason


def test_replan_names_a_state_that_is_not_one_arm(yumi_planner, yumi_home):
    joints = yumi.ARM_JOINTS["r"][:3]
    state = JointState.at_rest(joints, np.zeros(3))
    with pytest.raises(InvalidInputError, match=r"moving.joint_names .* one arm's joints"):
        yumi_planner.replan(PickRequest(top_down(0.45, 0.0, 0.035), yumi_home), state)
    with pytest.raises(InvalidInputError, match=r"arms = \('x',\) is not allowed: names among"):
        yumi_planner.plan(PickRequest(top_down(0.45, 0.0, 0.035), yumi_home, arms=("x",)))


def test_thinned_checks_keep_every_joint_within_the_step():
    from control.collision import thinned_samples

    rng = np.random.default_rng(0)
    positions = np.cumsum(rng.uniform(-0.004, 0.004, size=(500, 7)), axis=0)
    positions[200:210] += np.linspace(0, 0.2, 10)[:, None]  # a fast stretch: 0.022 rad a step
    kept = thinned_samples(positions, 0.01)
    assert kept[0] == 0 and kept[-1] == 499 and np.all(np.diff(kept) > 0)
    for a, b in itertools.pairwise(kept):
        travel = np.abs(np.diff(positions[a:b + 1], axis=0)).max(axis=1).sum()
        assert travel <= 0.01 + 1e-12 or b == a + 1  # within the step, or one long step
    assert len(kept) < 0.6 * len(positions)  # most slow samples are skipped
    assert set(range(200, 210)) <= set(kept)  # the fast stretch is checked at every sample


def test_vias_are_tried_only_once_every_direct_re_target_is_refused(yumi_planner, yumi_home,
                                                                    monkeypatch):
    """A re-plan tries each candidate's direct motion first (cheap); only where every one is
    refused does a second pass go over the planner's raised via poses, passing them moving."""
    _, q_now, state = moving_state(yumi_planner, yumi_home, top_down(0.45, -0.10, 0.035), 0.6)
    asked = PickRequest(top_down(0.45, -0.24, 0.035), q_now, obstacles=(TABLE,))
    calls: list[int] = []

    def spy(state, q_goal, limits, dt_s=1 / 240, vias=()):
        calls.append(len(vias))
        return retarget(state, q_goal, limits, dt_s, vias)

    monkeypatch.setattr(planner_module, "retarget", spy)
    assert yumi_planner.replan(asked, state).ok
    assert calls and set(calls) == {0}  # a direct re-target served: no via was tried

    def refuse_direct(state, q_goal, limits, dt_s=1 / 240, vias=()):
        calls.append(len(vias))
        if not vias:
            raise RetargetError("ErrorExecutionTimeCalculation", state, q_goal)
        return retarget(state, q_goal, limits, dt_s, vias)

    calls.clear()
    monkeypatch.setattr(planner_module, "retarget", refuse_direct)
    result = yumi_planner.replan(asked, state)
    assert result.ok, result.reason
    first_via = calls.index(next(n for n in calls if n))
    assert first_via > 0 and not any(calls[:first_via])  # every direct one first
    approach = result.plan.segment("approach").trajectory
    speeds = np.abs(approach.velocities[1:-1]).max(axis=1)
    assert speeds.min() > 0.0  # never at rest before the pre-grasp
