"""The simulated worlds: the YuMi scene and the paper's, the robot, the head camera, the catalog.

What a trial acts in and on; nothing here knows of tasks or trials.
"""
