"""Which sensor a task is seen through: --sensor, the file's, a fallback, the D435 (issue 64)."""

import dataclasses

import pytest

from harness.inputs.trial_settings import task_identity
from sim.errors import InvalidInputError
from sim.tasks.task_sensor import seen_in_scene, seen_through
from sim.tasks.task_toml import builtin_tasks, load_task, task_from_toml, task_to_toml
from sim.world.d435 import D435Config
from sim.world.sensor import DEFAULT_SENSOR, SensorConfig, SensorKind, sensor_kind

IDEAL, D435 = SensorConfig(), SensorConfig(SensorKind.D435)
CUSTOM = SensorConfig(SensorKind.D435, D435Config(subpixel_rms_px=0.1))


@pytest.mark.parametrize("name", builtin_tasks())
def test_every_built_in_task_names_no_sensor_so_every_command_sees_the_d435(name):
    task = load_task(name)
    assert DEFAULT_SENSOR is SensorKind.D435
    assert task.camera is None and task.sensor == D435 and seen_through(task).camera == D435


def test_the_flag_replaces_the_file_which_beats_the_fallback_which_beats_the_default():
    bare = load_task("single")
    custom = dataclasses.replace(bare, camera=CUSTOM)
    ideal = dataclasses.replace(bare, camera=IDEAL)
    assert seen_through(custom, SensorKind.IDEAL).camera == IDEAL  # as reproduce real --sensor
    assert seen_through(ideal, SensorKind.D435).camera == D435
    assert seen_through(custom, None, IDEAL).camera == CUSTOM  # the file's
    assert seen_through(ideal, None, D435).camera == IDEAL
    assert seen_through(bare, None, IDEAL).camera == IDEAL  # e.g. a checkpoint's own
    assert seen_through(bare).camera == D435
    assert seen_through(custom, "ideal").camera == IDEAL  # a name, as the env's sensor="ideal"
    with pytest.raises(InvalidInputError, match="sensor = 'kinect' is not allowed: None or one "
                       "of 'ideal', 'd435'"):
        seen_through(bare, "kinect")


def test_a_sensor_name_becomes_its_kind_in_one_place():
    assert sensor_kind("d435") is SensorKind.D435 and sensor_kind(SensorKind.IDEAL) is IDEAL.kind
    for name in ("kinect", None, 3, ["d435"]):
        with pytest.raises(InvalidInputError, match=r"file\.sensor = .* is not allowed: one of "
                           "'ideal', 'd435'"):
            sensor_kind(name, "file.sensor")


def test_a_file_without_a_sensor_is_the_d435_and_one_naming_ideal_stays_ideal():
    assert task_from_toml('name = "x"', "t.toml").camera is None
    mount_only = task_from_toml('name = "x"\n[camera]\nmount_offset_mm = 5.0', "t.toml")
    assert mount_only.camera is None and mount_only.sensor == D435
    named = task_from_toml('name = "x"\n[camera]\nsensor = "ideal"', "t.toml")
    assert named.camera == IDEAL and seen_through(named).camera == IDEAL
    for task in (load_task("single"), named, mount_only):  # written back as read
        assert task_from_toml(task_to_toml(task), task.source) == task


def test_identities_of_ideal_records_and_of_d435_runs_are_kept():
    bare, named_ideal = load_task("single"), dataclasses.replace(load_task("single"),
                                                                 camera=IDEAL)
    assert "camera" not in task_identity(named_ideal)  # as before sensors: ideal by omission
    d435_run = dataclasses.replace(load_task("single"), camera=D435)  # reproduce real's
    assert task_identity(d435_run)["camera"] == D435.to_json()
    assert task_identity(bare) == task_identity(d435_run)  # no sensor named: the D435, in full


def test_the_paper_scene_renders_through_its_own_camera_and_keeps_its_identities():
    bare = load_task("selected-position")
    paper = seen_in_scene(bare, "paper-sim")
    assert paper.camera == IDEAL and "camera" not in task_identity(paper)  # as before
    d435_file = dataclasses.replace(bare, camera=D435)  # recorded as it always was
    assert seen_in_scene(d435_file, "paper-sim") == d435_file
    assert seen_in_scene(bare, "yumi").camera == D435
    assert seen_in_scene(bare, "yumi", SensorKind.IDEAL).camera == IDEAL
    with pytest.raises(InvalidInputError, match=r"sensor = 'ideal' is not allowed: none for "
                       r"the paper-sim scene"):
        seen_in_scene(bare, "paper-sim", SensorKind.IDEAL)
