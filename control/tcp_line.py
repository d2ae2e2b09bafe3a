"""How far a joint-space move's tool centre point strays from the straight line it should follow.

The planner's descend and lift must move the TCP along a line (into the grasp along the approach
axis, straight up after it); a straight line in joint space bends in Cartesian space, so the
planner measures the bend and bisects the move where it is too large.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from control.robot_model import RobotModel
from control.trajectory import JointTrajectory

SAMPLES = 20
"""About how many of a trajectory's samples are measured (evenly spaced)."""


def tcp_deviation_m(robot: RobotModel, joint_index: np.ndarray, tcp_frame: str,
                    q_base: np.ndarray, trajectory: JointTrajectory, start: pin.SE3,
                    goal: pin.SE3) -> float:
    """The largest distance [m] of the TCP from the segment start -> goal over ``trajectory``.

    ``trajectory`` moves the joints ``joint_index`` of ``q_base`` (the rest stay as they are).
    """
    a, b = start.translation, goal.translation
    direction = b - a
    length_sq = float(direction @ direction) or 1.0
    q = q_base.copy()
    worst = 0.0
    for positions in trajectory.positions[:: max(1, len(trajectory.positions) // SAMPLES)]:
        q[joint_index] = positions
        p = robot.frame_pose(q, tcp_frame).translation
        s = np.clip((p - a) @ direction / length_sq, 0.0, 1.0)
        worst = max(worst, float(np.linalg.norm(p - (a + s * direction))))
    return worst
