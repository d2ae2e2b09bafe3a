"""The IK candidates of one pick: an arm's pre-grasp, grasp and lift configurations for a grasp.

Before the planner times and checks any motion it solves IK for the three poses a pick stops
at, for the grasp and its half turn about the approach axis (the parallel gripper grasps the
same either way), from the configuration now and from random restarts; grasp and lift follow
the pre-grasp's solution without jumping branch. The candidates come cheapest first.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from control.ik import ArmIk, IkResult
from control.robot_model import RobotModel


@dataclass
class Candidate:
    """One arm's IK solutions of pre-grasp, grasp and lift for one grasp; ``cost``: joint motion."""

    arm: str
    T_grasp: pin.SE3
    q_pre: np.ndarray
    q_grasp: np.ndarray
    q_lift: np.ndarray
    cost: float
    notes: list[str] = field(default_factory=list)


FLIP = pin.SE3(pin.utils.rotate("z", np.pi), np.zeros(3))
GRIPPER_TURNS = 2  # ik_candidates solves each attempt for the grasp and its half turn (FLIP)


def ik_candidates(
    robot: RobotModel, ik: ArmIk, index: np.ndarray, arm: str, T_grasp: pin.SE3,
    q0: np.ndarray, pregrasp_m: float, lift_height_m: float, max_jump_rad: float,
    rng: np.random.Generator, attempts: range,
) -> list[Candidate]:
    """``arm``'s candidates for ``T_grasp``, cheapest (least joint motion from ``q0``) first.

    ``index`` is the arm's joints in the robot's configuration; attempt 0 starts IK from
    ``q0``, every later one from a random in-limit configuration of the arm.
    """
    lift = pin.SE3(np.eye(3), np.array([0.0, 0.0, lift_height_m]))
    back_off = pin.SE3(np.eye(3), np.array([0.0, 0.0, -pregrasp_m]))
    found: list[Candidate] = []
    for T_g in (T_grasp, T_grasp * FLIP):
        T_pre, T_lift = T_g * back_off, lift * T_g
        for attempt in attempts:
            q_init = q0.copy()
            if attempt > 0:
                lower, upper = robot.lower_rad[index], robot.upper_rad[index]
                q_init[index] = rng.uniform(lower, upper)
            pre = ik.solve(T_pre, q_init, rng=rng)
            if not pre.solved:
                continue
            grasp = follow(ik, T_g, pre.q, max_jump_rad)
            lifted = follow(ik, T_lift, grasp.q, max_jump_rad) if grasp is not None else None
            if grasp is None or lifted is None:
                continue
            if any(np.max(np.abs(c.q_pre[index] - pre.q[index])) < 1e-3 for c in found):
                continue  # the same solution again
            cost = float(np.sum(np.abs(pre.q[index] - q0[index])))
            found.append(Candidate(arm, T_g, pre.q, grasp.q, lifted.q, cost))
    return sorted(found, key=lambda c: c.cost)


def follow(ik: ArmIk, T_target: pin.SE3, q_previous: np.ndarray, max_jump_rad: float
           ) -> IkResult | None:
    """IK seeded from a neighbouring solution; None if it fails or jumps branch."""
    result = ik.solve(T_target, q_previous)
    if not result.solved:
        return None
    if np.max(np.abs(result.q - q_previous)) > max_jump_rad:
        return None
    return result
