"""Load the YuMi and solve inverse kinematics for a top-down grasp pose with the right arm.

Run:
    python examples/01_load_yumi_and_solve_ik.py
"""

from __future__ import annotations

import math
import time

import numpy as np
import pinocchio as pin

from control.ik import ArmIk
from control.robot_model import RobotModel
from robots import yumi

SIDE = "r"  # the robot's right arm, mounted at -y
TARGET_POSITION_M = np.array([0.40, -0.10, 0.10])  # in front of the robot, 10 cm above the table
# Top-down: the TCP z axis (the approach direction) points down, its x axis forward.
R_WORLD_TARGET = np.array([
    [1.0, 0.0, 0.0],
    [0.0, -1.0, 0.0],
    [0.0, 0.0, -1.0],
])


def describe(T: pin.SE3) -> str:
    """Position in [m] and the direction the TCP z axis points in, world frame."""
    x, y, z = T.translation
    ax, ay, az = T.rotation[:, 2]
    return f"at ({x:+.4f}, {y:+.4f}, {z:+.4f}) m, z axis ({ax:+.3f}, {ay:+.3f}, {az:+.3f})"


def main() -> None:
    robot = RobotModel.from_urdf(yumi.URDF_PATH, yumi.SRDF_PATH)
    q_home = robot.q_from_dict(yumi.HOME)  # (robot.nq,)
    tcp = yumi.TCP_FRAME[SIDE]
    print(f"YuMi: {robot.nq} joints; {tcp} at home {describe(robot.frame_pose(q_home, tcp))}")

    ik = ArmIk(robot, yumi.ARM_JOINTS[SIDE], tcp)
    T_world_target = pin.SE3(R_WORLD_TARGET, TARGET_POSITION_M)
    print(f"target {describe(T_world_target)}")

    started = time.perf_counter()
    result = ik.solve(T_world_target, q_home)
    elapsed_ms = (time.perf_counter() - started) * 1e3

    print(f"status {result.status.value} in {elapsed_ms:.2f} ms "
          f"({result.iterations} iterations, {result.restarts} restarts)")
    print(f"error {result.position_error_m * 1e3:.4f} mm, "
          f"{math.degrees(result.rotation_error_rad):.4f} deg")
    print(f"{tcp} reached {describe(robot.frame_pose(result.q, tcp))}")
    for name, value_rad in robot.dict_from_q(result.q, yumi.ARM_JOINTS[SIDE]).items():
        index = robot.joint_index(name)
        print(f"  {name:16s} {math.degrees(value_rad):+9.3f} deg   "
              f"(limits {math.degrees(robot.lower_rad[index]):+8.2f} .. "
              f"{math.degrees(robot.upper_rad[index]):+8.2f})")


if __name__ == "__main__":
    main()
