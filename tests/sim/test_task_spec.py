import dataclasses
import math

import pytest

from perception.interface import ConditionKind
from sim.errors import InvalidInputError
from sim.tasks.task_spec import (
    ObjectChoice,
    TargetSelection,
    builtin_tasks,
    load_task,
    task_from_toml,
    task_to_toml,
)

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


def test_the_papers_four_tasks_ship():
    assert builtin_tasks() == ("multiple", "selected-position", "selected-type", "single")
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
     r"key: condition, description"),
    ('name = "x"\n[objects]\ncount = "two"', r"task file t\.toml: objects\.count = 'two' is not "
     r"allowed: a int"),
    ('name = "x"\n[objects]\ncount = true', r"objects\.count = True is not allowed: a int"),
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
     r"of two numbers"),
    ('name = "x"\n[lighting]\nbrightness = 0', r"lighting\.brightness = 0\.0 is not allowed: a "
     r"number in \(0, 2\]"),
    ('name = "x"\n[distractors]\ntypes = [3]', r"distractors\.types = \[3\] is not allowed: a "
     r"list of object type names"),
])
def test_a_bad_task_file_names_the_field_the_value_and_what_is_allowed(text, message):
    with pytest.raises(InvalidInputError, match=message):
        task_from_toml(text, "t.toml")


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
