"""The planning budget (issue 65): a hopeless search stops early, a plannable pick is unchanged."""

import numpy as np
import pinocchio as pin
import pytest
from tcp_poses import top_down

from control.collision import Obstacle, ShapeKind
from control.errors import InvalidInputError
from control.pick import PickPlannerConfig, PickRequest, PlanBudget, PlanStatus
from control.planner import PickPlanner
from sim.trials.planner_setup import PLANNER_IK_OPTIONS

TABLE = Obstacle("table", ShapeKind.BOX, (1.5, 1.0, 0.05),
                 pin.SE3(np.eye(3), np.array([0.35, 0.0, -0.025])))
CRATE = Obstacle("crate", ShapeKind.BOX, (0.12, 0.12, 0.20),
                 pin.SE3(np.eye(3), np.array([0.42, -0.10, 0.10])))


def planner_with(base: PickPlanner, budget: PlanBudget | None) -> PickPlanner:
    """A planner like ``base`` (its robot and checker shared) under ``budget``."""
    return PickPlanner(base.robot, base.checker, base.arms, PickPlannerConfig(budget=budget),
                       PLANNER_IK_OPTIONS)


def turned(grasp: pin.SE3, count: int) -> tuple[pin.SE3, ...]:
    """``count`` alternatives of ``grasp``, turned about the vertical through its point by
    20-degree steps, as a bottle's are."""
    return tuple(pin.SE3(np.eye(3), grasp.translation)
                 * pin.SE3(pin.utils.rotate("z", np.radians(20.0 * k)), np.zeros(3))
                 * pin.SE3(np.eye(3), -grasp.translation) * grasp for k in range(1, count + 1))


def test_the_budget_stops_an_unreachable_search_early_and_says_why(yumi_planner, yumi_home):
    far = top_down(1.2, 0.0, 0.035)
    asked = PickRequest(far, yumi_home, obstacles=(TABLE,), alternatives=turned(far, 3))
    full = planner_with(yumi_planner, None).plan(asked)
    assert (full.status, full.ik_attempts) == (PlanStatus.UNREACHABLE, 4 * 2 * 2 * 8)
    cut = planner_with(yumi_planner, PlanBudget(max_ik_attempts=16)).plan(asked)
    assert (cut.status, cut.plan, cut.ik_attempts) == (PlanStatus.UNREACHABLE, None, 16)
    assert cut.reason.startswith("planning budget spent: 16 IK attempts (PlanBudget(")
    assert "arm r, grasp: no in-limit IK solution for pre-grasp (8 cm back)" in cut.reason
    assert "alternative 1" not in cut.reason  # never reached


def test_the_budget_stops_a_blocked_search_as_a_collision(yumi_planner, yumi_home):
    inside = top_down(0.42, -0.10, 0.035)  # in the crate: every candidate collides
    asked = PickRequest(inside, yumi_home, obstacles=(TABLE, CRATE))
    assert planner_with(yumi_planner, None).plan(asked).candidates_tried > 5
    cut = planner_with(yumi_planner, PlanBudget(max_candidates=5)).plan(asked)
    assert (cut.status, cut.plan, cut.candidates_tried) == (PlanStatus.COLLISION, None, 5)
    assert cut.reason.startswith("planning budget spent: 5 candidate plans (PlanBudget(")
    assert "crate" in cut.reason


def test_a_pick_planned_within_the_budget_is_planned_exactly_as_without_one(yumi_planner,
                                                                           yumi_home):
    """The grasp in the crate fails on every candidate; its alternative, clear of it, plans.

    With no budget, the default and a budget of exactly the work the plan took, the plan is
    the same to the sample; one candidate less and the search stops without it.
    """
    inside = top_down(0.42, -0.10, 0.035)
    asked = PickRequest(inside, yumi_home, obstacles=(TABLE, CRATE),
                        alternatives=(top_down(0.42, 0.10, 0.035),))
    free = planner_with(yumi_planner, None).plan(asked)
    assert free.ok and free.candidates_tried > 1 and free.reason == "arm l, alternative 1"
    exact = PlanBudget(max_candidates=free.candidates_tried, max_ik_attempts=free.ik_attempts)
    for budget in (PlanBudget(), exact):
        result = planner_with(yumi_planner, budget).plan(asked)
        assert (result.status, result.reason, result.candidates_tried, result.ik_attempts) == (
            free.status, free.reason, free.candidates_tried, free.ik_attempts)
        assert result.plan.arm == free.plan.arm
        np.testing.assert_array_equal(result.plan.q_grasp, free.plan.q_grasp)
        np.testing.assert_array_equal(result.plan.T_world_grasp.homogeneous,
                                      free.plan.T_world_grasp.homogeneous)
        for ours, theirs in zip(result.plan.segments, free.plan.segments, strict=True):
            assert (ours.name, ours.gripper_before) == (theirs.name, theirs.gripper_before)
            np.testing.assert_array_equal(ours.trajectory.positions, theirs.trajectory.positions)
            np.testing.assert_array_equal(ours.trajectory.times_s, theirs.trajectory.times_s)
    short = PlanBudget(max_candidates=free.candidates_tried - 1)
    cut = planner_with(yumi_planner, short).plan(asked)
    assert cut.status is PlanStatus.COLLISION and cut.reason.startswith("planning budget spent")


def test_the_default_planner_has_the_default_budget(yumi_planner):
    assert yumi_planner.config.budget == PlanBudget() == PickPlannerConfig().budget


@pytest.mark.parametrize(("field", "value"), [("max_candidates", 0), ("max_ik_attempts", -1),
                                              ("max_candidates", 2.5),
                                              ("max_ik_attempts", True)])
def test_a_bad_budget_is_refused_naming_field_value_and_what_is_allowed(field, value):
    with pytest.raises(InvalidInputError, match=rf"{field} = {value} is not allowed: an "
                                                r"integer >= 1"):
        PlanBudget(**{field: value})
    with pytest.raises(InvalidInputError, match=r"budget = 64 is not allowed: a PlanBudget or "
                                                r"None"):
        PickPlannerConfig(budget=64)
