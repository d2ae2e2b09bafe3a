import dataclasses
import math

import pytest

from perception.interface import ConditionKind
from sim.errors import InvalidInputError
from sim.tasks.task_spec import ObjectChoice, TargetSelection
from sim.tasks.task_toml import (
    MAX_TASK_FILE_BYTES,
    builtin_tasks,
    load_task,
    task_from_toml,
    task_to_toml,
)
from sim.world.d435 import D435Config
from sim.world.sensor import SensorConfig, SensorKind

GOOD = """
name = "mine"
[objects]
choose = "same_type"
count = 2
[targets]
select = "condition"
[condition]
kind = "side"
[placement]
sides = true
yaw_deg = [-90, 90]
"""


def test_the_papers_four_tasks_ship_with_their_text_and_picture_twins():
    assert builtin_tasks() == ("multiple", "selected-position", "selected-position-text",
                               "selected-type", "selected-type-image", "selected-type-moved",
                               "selected-type-text", "single", "single-moved")
    multiple = load_task("multiple")
    assert (multiple.objects, multiple.count, multiple.targets) == (
        ObjectChoice.ONE_OF_EACH, 3, TargetSelection.ALL)
    selected = load_task("selected-type")
    assert selected.condition is ConditionKind.OBJECT_TYPE
    side = load_task("selected-position")
    assert side.sides and side.condition is ConditionKind.SIDE and side.count == 2


def test_a_users_task_file_loads_from_its_path(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(GOOD)
    task = load_task(str(path))
    assert task.name == "mine" and task.source == "mine.toml"
    assert task.yaw_range_rad == pytest.approx((-math.pi / 2, math.pi / 2))


@pytest.mark.parametrize(("text", "message"), [
    ("name = ", r"task file t\.toml = 'not valid TOML' is not allowed: TOML \(Invalid value"),
    ("[objects]\ncount = 1", r"task file t\.toml: name = None is not allowed: a non-empty string"),
    ('name = "x"\ncolour = "red"', r"task file t\.toml: colour = 'red' is not allowed: a known "
     r"key: appearance, camera, condition, description"),
    # The camera table: the sensor's kind, then D435 parameters by their field names.
    ('name = "x"\ncamera = { sensor = "kinect" }', r"task file t\.toml: camera\.sensor = "
     r"'kinect' is not allowed: one of 'ideal', 'd435'"),
    ('name = "x"\ncamera = { sensor = "d435", subpixel_rms_px = -0.1 }', r"task file t\.toml: "
     r"camera\.subpixel_rms_px = -0\.1 is not allowed: a number in \[0\.01, 1\] \(Intel"),
    ('name = "x"\ncamera = { sensor = "d435", depth_unit_m = 10 }', r"camera\.depth_unit_m = 10\.0 "
     r"is not allowed: a number in \[1e-05, 0\.01\]"),
    ('name = "x"\ncamera = { sensor = "d435", baseline_m = 1e-30 }', r"camera\.baseline_m = "
     r"1e-30 is not allowed: a number in \[0\.01, 0\.3\]"),
    ('name = "x"\ncamera = { sensor = "d435", hand_eye_rotation_rms_rad = 10 }',
     r"camera\.hand_eye_rotation_rms_rad = 10\.0 is not allowed: a number in \[0, 0\.0872665\]"),
    ('name = "x"\ncamera = { sensor = "d435", depth_subpixel_px = 0.1 }', r"camera\."
     r"depth_subpixel_px = 0\.1 is not allowed: a known key: baseline_m, "),
    ('name = "x"\ncamera = { depth_unit_m = 0.002 }', r"camera\.depth_unit_m = 0\.002 is not "
     r"allowed: absent unless sensor = 'd435'"),
    ('name = "x"\ncamera = { sensor = "d435", depth_width_px = 848.5 }', r"camera\."
     r"depth_width_px = 848\.5 is not allowed: an integer"),
    ('name = "x"\ncamera = { sensor = "d435", baseline_m = true }', r"camera\.baseline_m = True "
     r"is not allowed: a finite number"),
    ('name = "x"\ncamera = { sensor = "d435", hand_eye_rotation_rms_rad = -0.01 }',
     r"camera\.hand_eye_rotation_rms_rad = -0\.01 is not allowed: a number in \[0, 0\.0872665\]"),
    ('name = "x"\ncamera = { sensor = "d435", colour_distortion_k1_k2_p1_p2_k3 = [0.1, 0] }',
     r"camera\.colour_distortion_k1_k2_p1_p2_k3 = \[0\.1, 0\] is not allowed: a list of five"),
    ('name = "x"\ncamera = { sensor = "d435", colour_distortion_k1_k2_p1_p2_k3 = [-2, 0, 0, 0, '
     '0] }', r"task 'x' \(t\.toml\): camera\.colour_distortion_k1_k2_p1_p2_k3 = \[-2\.0, 0\.0, "
     r"0\.0, 0\.0, 0\.0\] is not allowed: a distortion that is monotonic"),
    ('name = "x"\ncamera = "d435"', r"task file t\.toml: camera = 'd435' is not allowed: a "
     r"\[table\]"),
    ('name = "x"\n[objects]\ncount = "two"', r"task file t\.toml: objects\.count = 'two' is not "
     r"allowed: an integer in \[1, 12\]"),
    ('name = "x"\n[objects]\ncount = true', r"objects\.count = True is not allowed: an integer"),
    ('name = "x"\n[objects]\nchoose = "all"', r"objects\.choose = 'all' is not allowed: one of "
     r"'random', 'one_of_each', 'same_type'"),
    ('name = "x"\n[condition]\nkind = "colour"', r"condition\.kind = 'colour' is not allowed: "
     r"one of 'none', 'object_type', 'side'"),
    ('name = "x"\n[targets]\nselect = "condition"', r"task 'x' \(t\.toml\): condition\.kind = "
     r"'none' is not allowed: object_type or side"),
    ('name = "x"\n[condition]\nkind = "object_type"\n[targets]\nselect = "condition"',
     r"objects\.choose = 'random' is not allowed: 'one_of_each' with condition\.kind"),
    ('name = "x"\n[placement]\nyaw_deg = [10, 5]', r"placement\.yaw_deg = \[10\.0, 5\.0\] is "
     r"not allowed: \[low, high\]"),
    ('name = "x"\n[placement]\nx_m = [0.4]', r"placement\.x_m = \[0\.4\] is not allowed: a list "
     r"of two finite numbers"),
    ('name = "x"\n[lighting]\nbrightness = 0', r"lighting\.brightness = 0\.0 is not allowed: a "
     r"number in \(0, 2\]"),
    ('name = "x"\n[distractors]\ntypes = [3]', r"distractors\.types = \[3\] is not allowed: a "
     r"list of object type names"),
    # Numbers: finite, and within the ranges docs/tasks.md states.
    ('name = "x"\n[objects]\ncount = 1000000000000000000', r"task 'x' \(t\.toml\): objects\.count "
     r"= 1000000000000000000 is not allowed: an integer in \[1, 12\]"),
    ('name = "x"\n[objects]\ncount = 0', r"objects\.count = 0 is not allowed: an integer in \[1"),
    ('name = "x"\n[objects]\ncount = 13', r"objects\.count = 13 is not allowed: an integer in"),
    ('name = "x"\n[objects]\ncount = 1' + "0" * 400, r"objects\.count = 1000000000.*\.\.\. \(401 "
     r"characters\) is not allowed"),
    ('name = "x"\n[placement]\nmin_spacing_m = nan', r"task 'x' \(t\.toml\): placement\."
     r"min_spacing_m = nan is not allowed: a distance in \[0, 0\.5\] m"),
    ('name = "x"\n[placement]\nmin_spacing_m = -inf', r"min_spacing_m = -inf is not allowed"),
    ('name = "x"\n[placement]\nmin_spacing_m = 0.6', r"min_spacing_m = 0\.6 is not allowed"),
    ('name = "x"\n[placement]\nmin_spacing_m = 1' + "0" * 400, r"task file t\.toml: placement\."
     r"min_spacing_m = 1000.*\(401 characters\) is not allowed: a finite number"),
    ('name = "x"\n[placement]\nyaw_deg = [nan, 5]', r"placement\.yaw_deg = \[nan, 5\] is not "
     r"allowed: a list of two finite numbers"),
    ('name = "x"\n[placement]\nyaw_deg = [-720, 5]', r"placement\.yaw_deg = \[-720\.0, 5\.0\] "
     r"is not allowed: \[low, high\] with -360 <= low < high <= 360"),
    ('name = "x"\n[placement]\ny_m = [0.1, inf]', r"placement\.y_m = \[0\.1, inf\] is not "
     r"allowed: a list of two finite numbers"),
    ('name = "x"\n[placement]\nx_m = [0.4, 3.0]', r"placement\.x_m = \[0\.4, 3\.0\] is not "
     r"allowed: \[low, high\] in metres with -1 <= low < high <= 1"),
    ('name = "x"\n[lighting]\nbrightness = inf', r"lighting\.brightness = inf is not allowed"),
    ('name = "x"\n[lighting]\nbrightness = nan', r"lighting\.brightness = nan is not allowed"),
    ('name = "x"\n[objects]\ncount = 11\n[distractors]\ntypes = ["mug", "mug"]',
     r"distractors\.types = \['mug', 'mug'\] is not allowed: at most 1 types \(objects\.count \+ "
     r"distractors <= 12\)"),
    # Strings: bounded, and nothing that breaks a one-line message.
    ('name = "a\\nb"', r"task file t\.toml: name = 'a\\nb' is not allowed: 1-100 printable"),
    (f'name = "{"n" * 200}"', r"name = 'nnn.*\.\.\. \(202 characters\) is not allowed: 1-100"),
    (f'name = "x"\ndescription = "{"d" * 1001}"', r"description = 'ddd.* is not allowed: at most "
     r"1000 characters"),
    ('name = "x"\n[placement]\n"a\\nb" = 1', r'placement\."a\\nb" = 1 is not allowed: a known key'),
    ('name = "x"\n[placement]\nsides = "yes"', r"placement\.sides = 'yes' is not allowed: true or "
     r"false"),
    ('name = "x"\n[objects]\nchoose = "one_of_each"\nbalance_types = true',
     r"objects\.balance_types = True is not allowed: false unless objects\.choose = 'same_type'"),
    ('name = "x"\n[objects]\ncount = 2\nbalance_types = true',
     r"objects\.balance_types = True is not allowed: .*'random' with objects\.count = 1"),
    ('a = ' + "[" * 5000 + "]" * 5000, r"task file t\.toml = 'arrays or tables nested too deeply' "
     r"is not allowed"),
    ('a = ' + "[" * 300 + "]" * 300, r"task file t\.toml: a = \[\[\[.*\.\.\. \(\d+ characters\) is "
     r"not allowed: a known key"),
])
def test_a_bad_task_file_names_the_field_the_value_and_what_is_allowed(text, message):
    with pytest.raises(InvalidInputError, match=message) as raised:
        task_from_toml(text, "t.toml")
    assert "\n" not in str(raised.value) and len(str(raised.value)) < 400  # one readable line


@pytest.mark.parametrize(("data", "message"), [
    (b"\xff\xfename = 'x'", r"task file t\.toml = 'not UTF-8 text' is not allowed: a TOML text "
     r"file in UTF-8 \(byte 0 is 0xff\)"),
    (b"name = 'caf\xe9'", r"task file t\.toml = 'not UTF-8 text' is not allowed: .*\(byte 11 is "
     r"0xe9\)"),
    (b"\x00\x01\x02", r"task file t\.toml = 'not valid TOML' is not allowed: TOML"),
    (b"#" * (MAX_TASK_FILE_BYTES + 1), r"task file t\.toml = '65537 bytes or more' is not allowed: "
     r"a task file of at most 65536 bytes"),
])
def test_a_file_that_is_not_toml_text_is_named_in_one_line(tmp_path, data, message):
    path = tmp_path / "t.toml"
    path.write_bytes(data)
    with pytest.raises(InvalidInputError, match=message) as raised:
        load_task(path)
    assert "\n" not in str(raised.value)


def test_a_task_file_saved_with_a_byte_order_mark_loads(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes("\ufeff".encode() + GOOD.encode())
    assert load_task(path).name == "mine"


def test_unknown_task_and_missing_file_are_named():
    with pytest.raises(InvalidInputError, match=r"task = 'juggle' is not allowed: one of multiple"):
        load_task("juggle")
    with pytest.raises(InvalidInputError, match=r"task file = 'nowhere\.toml' is not allowed: an "
                       r"existing TOML file"):
        load_task("nowhere.toml")


@pytest.mark.parametrize("name", builtin_tasks())
def test_a_task_written_as_toml_reads_back_the_same(name):
    task = load_task(name)
    assert task_from_toml(task_to_toml(task), task.source) == task
    variant = dataclasses.replace(task, name=f"{name}-dim \"x\"", brightness=0.4,
                                  distractors=("sponge", "mug"), workspace_x_m=(0.4, 0.5))
    assert task_from_toml(task_to_toml(variant), task.source) == variant


def test_the_camera_table_picks_the_sensor_and_overrides_d435_fields_by_name():
    single = load_task("single")  # names no sensor: the command's, else the D435 (issue 64)
    assert single.camera is None and single.sensor == SensorConfig(SensorKind.D435)
    task = task_from_toml('name = "x"\ncamera = { sensor = "d435", subpixel_rms_px = 0.1, '
                          'depth_width_px = 640, colour_distortion_k1_k2_p1_p2_k3 = '
                          '[-0.03, 0, 0, 0, 0] }', "t.toml")
    assert task.camera == SensorConfig(SensorKind.D435, D435Config(
        subpixel_rms_px=0.1, depth_width_px=640,
        colour_distortion_k1_k2_p1_p2_k3=(-0.03, 0.0, 0.0, 0.0, 0.0)))
    assert task_from_toml(task_to_toml(task), "t.toml") == task
    assert task_from_toml('name = "x"\ncamera = { sensor = "d435" }', "t.toml").camera == \
        SensorConfig(SensorKind.D435)
    assert task_from_toml('name = "x"\n[camera]\nsensor = "ideal"', "t.toml").camera == \
        SensorConfig()
