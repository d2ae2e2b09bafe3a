"""Plan a jerk-limited motion of the YuMi's right arm: home -> a reach -> home.

Each segment is a time-optimal rest-to-rest ruckig trajectory along the straight line in joint
space, within the URDF's position and velocity limits and the stated acceleration and jerk
limits. The table shows how close each joint comes to its limits.

Run: python examples/02_jerk_limited_trajectory.py
"""

import numpy as np

from control.robot_model import RobotModel
from control.trajectory import JointLimits, plan_segment, plan_through
from robots import yumi

robot = RobotModel.from_urdf(yumi.URDF_PATH)
limits = JointLimits.from_robot(
    robot,
    yumi.ARM_JOINTS["r"],
    max_acceleration=yumi.MAX_ACCELERATION_RAD_S2,
    max_jerk=yumi.MAX_JERK_RAD_S3,
)

q_home = np.array([yumi.HOME[name] for name in limits.joint_names])  # (7,) [rad]
# a reach forward over the table, keyed by joint name [rad] (the arm's joints in chain order)
reach = dict(zip(yumi.ARM_JOINTS["r"], (0.6, -1.2, -1.0, 0.2, 1.5, 1.2, -2.0), strict=True))
q_reach = np.array([reach[name] for name in limits.joint_names])  # (7,) [rad]

out = plan_segment(q_home, q_reach, limits)
back = plan_segment(q_reach, q_home, limits)
trajectory = plan_through([q_home, q_reach, q_home], limits)  # the same two segments, chained
print(f"home -> reach: {out.duration_s:.3f} s, reach -> home: {back.duration_s:.3f} s, "
      f"round trip: {trajectory.duration_s:.3f} s in {trajectory.times_s.size} samples "
      f"every {trajectory.dt_s * 1e3:.2f} ms")

# Jerk between consecutive samples: for ruckig's piecewise-constant jerk, |da/dt| <= j_max.
jerk = np.diff(trajectory.accelerations, axis=0) / np.diff(trajectory.times_s)[:, None]
peaks = {  # title: (peak per joint (7,), limit per joint (7,))
    "velocity [rad/s]": (np.abs(trajectory.velocities).max(axis=0), limits.max_velocity),
    "acceleration [rad/s^2]": (np.abs(trajectory.accelerations).max(axis=0),
                               limits.max_acceleration),
    "jerk [rad/s^3]": (np.abs(jerk).max(axis=0), limits.max_jerk),
}
print(f"\n{'joint':<16}" + "".join(f"{title:>26}" for title in peaks))
for j, name in enumerate(limits.joint_names):
    cells = [f"{peak[j]:8.3f} / {limit[j]:7.3f} ({peak[j] / limit[j]:4.0%})"
             for peak, limit in peaks.values()]
    print(f"{name:<16}" + "".join(f"{cell:>26}" for cell in cells))

ends_ok = np.array_equal(trajectory.positions[-1], q_home) and not trajectory.velocities[-1].any()
print(f"\nends exactly at home, at rest: {ends_ok}")
print(f"halfway through the first segment: {np.round(trajectory.at(out.duration_s / 2), 3)}")
