"""Robot control as pure math.

Pinocchio kinematics and IK, ruckig trajectories, collision checking and the pick planner. No
simulator and no torch in here: the planner hands joint references to whoever executes them.
"""
