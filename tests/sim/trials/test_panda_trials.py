"""The same pick stack on a second robot (issue 39): the Panda picks with the oracle through its
own stand camera, and the YuMi's camera is what it was."""

from __future__ import annotations

import pytest

from robots import get_robot, yumi
from sim.tasks.task_toml import load_task
from sim.trials.records import TrialOutcome
from sim.trials.run_loop import trial_scene
from sim.trials.trial_runner import TrialRunner
from sim.world.head_camera import CameraConfig, camera_config


def test_the_yumis_workcell_camera_is_the_head_camera():
    assert camera_config(yumi.YUMI) == CameraConfig()  # run identities stay as they were


def test_the_panda_sees_through_its_stand_camera():
    panda = camera_config(get_robot("panda"))
    assert panda.position_m == get_robot("panda").camera.position_m != CameraConfig().position_m
    assert panda.width_px == CameraConfig().width_px  # the same sensor, mounted elsewhere


@pytest.mark.slow
@pytest.mark.parametrize("task", ["single", "selected-position"])
def test_the_panda_picks_with_the_oracle(task):
    spec = load_task(task)
    with TrialRunner(spec, robot=get_robot("panda")) as runner:
        assert runner.world.description.name == "panda"
        record = runner.run(trial_scene(spec, 0, 0), 0, 0, "oracle")
    assert record.outcome is TrialOutcome.SUCCESS, record.reason
    assert {pick["arm"] for pick in record.picks} == {"panda"}
