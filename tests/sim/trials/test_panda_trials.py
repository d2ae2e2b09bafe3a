"""The same pick stack on a second robot (issue 39): the Panda picks with the oracle through its
own stand camera, and the YuMi's camera is what it was."""

from __future__ import annotations

import json
from dataclasses import asdict, replace
from types import SimpleNamespace

import numpy as np
import pytest

from harness.inputs.collector import CollectSettings, collect
from harness.inputs.trial_settings import TrialSettings
from harness.run_loop import run_trials
from perception.interface import ConditionKind, LabelKind
from perception.learning.learnable import ModelSpec
from perception.models.kqv import KqvConfig
from perception.models.kqv_net import focus_px
from robots import get_robot, yumi
from sim.errors import InvalidInputError
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import get_scene_spec
from sim.tasks.task_sensor import seen_through
from sim.tasks.task_spec import spaced_for
from sim.tasks.task_toml import load_task
from sim.trials.model_fit import check_camera
from sim.trials.records import TrialOutcome
from sim.trials.trial_runner import TrialRunner
from sim.trials.trial_scenes import trial_scene
from sim.world.head_camera import CameraConfig, HeadCamera, camera_config

HEAD_CAMERA_RECORD = (
    '{"width_px": 128, "height_px": 128, "vertical_fov_deg": 37.0, "horizontal_fov_deg": 58.0, '
    '"position_m": [0.09, 0.0, 0.52], "target_m": [0.49, 0.0, 0.0], "up": [0.0, 0.0, 1.0], '
    '"near_m": 0.05, "far_m": 3.0, "lighting": {"direction": [0.4, 0.3, 1.0], "brightness": '
    '1.0, "ambient_coeff": 0.6, "diffuse_coeff": 0.5, "specular_coeff": 0.05, "shadows": true}, '
    '"focus_window_px": 24, "focus_box_px": 18}')
"""The YuMi head camera as every run identity and dataset has recorded it (``asdict``)."""


def test_the_yumis_workcell_camera_is_the_head_camera():
    record = json.dumps(asdict(camera_config(yumi.YUMI)))
    assert record == HEAD_CAMERA_RECORD  # run identities stay as they were, field order too


def test_the_panda_sees_through_its_stand_camera():
    panda, head = camera_config(get_robot("panda")), camera_config(yumi.YUMI)
    assert panda.position_m == get_robot("panda").camera.position_m != head.position_m
    assert panda.width_px == head.width_px  # the same sensor, mounted elsewhere


@pytest.mark.slow
@pytest.mark.parametrize("task", ["single", "selected-position"])
def test_the_panda_picks_with_the_oracle(task):
    spec = load_task(task)
    with TrialRunner(spec, robot=get_robot("panda")) as runner:
        assert runner.world.description.name == "panda"
        record = runner.run(trial_scene(spec, 0, 0), 0, 0, "oracle")
    assert record.outcome is TrialOutcome.SUCCESS, record.reason
    assert {pick["arm"] for pick in record.picks} == {"panda"}
    assert {pick["grip"]["opening_m"] for pick in record.picks} == {0.08}  # its hand, open fully


def test_a_run_names_its_robot_unless_it_is_the_yumi():
    yumi_run = TrialSettings(model="oracle", task="single")
    assert "robot" not in yumi_run.identity()  # folders from before other robots resume
    panda_run = TrialSettings(model="oracle", task="single", robot="panda")
    assert panda_run.identity()["robot"] == "panda"
    assert panda_run.identity()["camera"] != yumi_run.identity()["camera"]
    with pytest.raises(InvalidInputError, match=r"robot = 'ur5' is not allowed: one of yumi, "
                                                r"panda"):
        TrialSettings(model="oracle", task="single", robot="ur5")


def test_a_checkpoint_trained_through_one_robots_camera_is_refused_on_the_other():
    spec = ModelSpec("yumi", "single", LabelKind.GRASP_POSE, 1, ConditionKind.NONE, (), 128, 128,
                     camera=camera_config(yumi.YUMI).pinhole)
    check_camera(spec, yumi.YUMI, "ckpt")  # its own robot
    with pytest.raises(InvalidInputError, match=r"model ckpt = \"trained through the yumi's "
                                                r"camera at \(0.09, 0.0, 0.52\) m\" is not "
                                                r"allowed: a checkpoint trained through the "
                                                r"panda's camera"):
        check_camera(spec, get_robot("panda"), "ckpt")


@pytest.mark.slow
def test_the_pandas_demonstrations_name_it_and_its_camera(tmp_path):
    dataset = collect(CollectSettings(scene="yumi", task="single", size=1, robot="panda"),
                      tmp_path / "panda.gva", progress=False)
    assert dataset.metadata.extra["robot"] == "panda"
    assert tuple(dataset.metadata.camera["position_m"]) == get_robot("panda").camera.position_m
    with pytest.raises(InvalidInputError, match=r"robot = 'panda' is not allowed: 'yumi' for "
                                                r"the paper-sim scene"):
        CollectSettings(scene="paper-sim", task="single", size=1, robot="panda")


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
def test_a_run_of_trials_picks_with_the_robot_it_names(tmp_path, workers):
    """In one process or in a pool, the trials run the run's robot (not the YuMi)."""
    settings = TrialSettings(model="oracle", task="single", n=2, robot="panda")
    run_trials(settings, tmp_path / "run", progress=False, workers=workers)
    records = [json.loads(line) for line in (tmp_path / "run" / "trials.jsonl").open()]
    assert {pick["arm"] for record in records for pick in record["picks"]} == {"panda"}


def test_a_panda_scene_keeps_its_objects_apart_for_the_hand():
    """The Panda's hand needs 16 cm between object centres; the YuMi's tasks keep their own."""
    assert get_robot("panda").neighbour_spacing_m == 0.16
    assert get_robot("yumi").neighbour_spacing_m is None
    for task in ("single", "multiple", "selected-type", "selected-position"):
        assert TrialSettings("oracle", task=task, robot="panda").task_spec.min_spacing_m == 0.16
        assert TrialSettings("oracle", task=task).task_spec == seen_through(  # the YuMi: as is,
            load_task(task))  # its sensor named (the D435: issue 64)
        assert CollectSettings("yumi", task, 2, robot="panda").task_spec.min_spacing_m == 0.16
    wide = replace(load_task("multiple"), min_spacing_m=0.2)
    assert spaced_for(wide, 0.16) is wide  # a task that keeps them farther apart already
    scene = sample_scene(TrialSettings("oracle", task="multiple", robot="panda").task_spec,
                         get_scene_spec("yumi"), 0, SeedStream.TEST, 0)
    xy = np.array([o.position_xy_m for o in scene.objects])
    assert min(np.linalg.norm(a - b) for i, a in enumerate(xy) for b in xy[i + 1:]) >= 0.16


def test_each_robots_camera_records_the_heatmap_focus_derived_for_it():
    yumi_record = HeadCamera(camera_config(yumi.YUMI)).record()
    panda_record = HeadCamera(camera_config(get_robot("panda"))).record()
    assert (yumi_record["focus_window_px"], yumi_record["focus_box_px"]) == (24, 18)
    assert (panda_record["focus_window_px"], panda_record["focus_box_px"]) == (0, 0)
    metadata = {"scene": "yumi", "task": "single", "label_kind": LabelKind.GRASP_POSE,
                "targets": 1, "condition_kind": ConditionKind.NONE, "condition_choices": (),
                "image_height_px": 128, "image_width_px": 128, "extra": {}}
    specs = [ModelSpec.from_metadata(SimpleNamespace(**metadata, camera=record))
             for record in (yumi_record, panda_record)]
    assert [(s.focus_window_px, s.focus_box_px) for s in specs] == [(24, 18), (0, 0)]
    assert [focus_px(s, KqvConfig()) for s in specs] == [(24, 18), (0, 18)]
    assert CameraConfig.from_json(panda_record) == camera_config(get_robot("panda"))
    with pytest.raises(InvalidInputError, match=r"focus_box_px = 0 is not allowed: 0 with no "
                                                r"focus window, >= 1 with one"):
        replace(camera_config(yumi.YUMI), focus_box_px=0)
