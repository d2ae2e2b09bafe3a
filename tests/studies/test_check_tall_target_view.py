"""studies/check_tall_target_view.py: a look the loop heeds, onto a grasp judged missed, counts."""

from __future__ import annotations

import numpy as np
from benchmark_scripts import load_study

from perception.camera import PinholeCamera, RgbdFrame
from perception.interface import NO_CONDITION
from perception.objects.catalog import get_object_spec
from perception.objects.grasps import grasp_pose
from perception.poses import Pose
from sim.trials.closed_loop.loop_settings import LoopSettings

CAMERA = PinholeCamera((0.09, 0.0, 0.52), (0.49, 0.0, 0.0), (0.0, 0.0, 1.0), 37.0, None, 64, 48)
"""The head camera's pose, at a quarter of its pixels."""


def frame(hidden_px: tuple[slice, slice] | None = None) -> RgbdFrame:
    """A frame of an empty table, the robot's pixels over ``hidden_px``."""
    mask = np.zeros((48, 64), bool)
    if hidden_px is not None:
        mask[hidden_px] = True
    return RgbdFrame(np.zeros((48, 64, 3), np.uint8), np.full((48, 64), 0.5, np.float32),
                     CAMERA, robot_mask=mask)


def test_a_heeded_look_off_the_truth_and_judged_missed_is_a_wrong_retarget():
    study = load_study("check_tall_target_view")
    spec = get_object_spec("spray_bottle")
    truth = grasp_pose(spec, Pose.from_xy_yaw(0.49, 0.0, 0.0))
    off = Pose(truth.position + np.array([0.0, 0.03, 0.0]), truth.rotation)  # 3 cm aside
    looks = [study.Look(0, frame(), NO_CONDITION, "spray_bottle", truth, 0.0, 0.0, 0.0),
             study.Look(0, frame(), NO_CONDITION, "spray_bottle", truth, 0.0, 0.0, 0.0),
             study.Look(1, frame((slice(None), slice(None))), NO_CONDITION, "spray_bottle",
                        truth, 0.0, 1.0, 1.0)]
    tally = study.tally_looks(looks, [truth, off, off], LoopSettings())
    assert tally.heeded["spray_bottle"] == 2  # the footprint seen; the last look all hidden
    assert tally.wrong["spray_bottle"] == 1 and tally.wrong_scenes["spray_bottle"] == {0}
    assert tally.scenes["spray_bottle"] == {0, 1}
    assert [len(rows) for rows in tally.errors.values()] == [2, 1]


def test_the_column_is_hidden_where_the_arm_hides_the_upper_body_only():
    study = load_study("check_tall_target_view")
    grasp = np.array([0.49, 0.0, 0.07])
    top = frame()
    u, v = np.round(CAMERA.project(np.array([[0.49, 0.0, 0.17]]))[0]).astype(int)
    top.robot_mask[max(v - 2, 0):v + 3, u - 2:u + 3] = True  # over the bottle's head alone
    assert study.hidden_share(top, grasp, 0.045) == 0.0
    assert study.column_hidden_share(top, grasp, 0.17, 0.045) > 0.0
