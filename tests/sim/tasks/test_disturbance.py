"""Targets that move during a pick (issue 36): the ``[disturbance]`` table and its draws."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sim.errors import InvalidInputError
from sim.tasks import scene_sampling
from sim.tasks.disturbance import (
    DISTURBANCE_STREAM,
    Disturbance,
    DisturbanceDraw,
    DisturbanceWhen,
    draw_disturbance,
    scene_disturbance,
)
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import get_scene_spec
from sim.tasks.task_spec import TaskSpec
from sim.tasks.task_toml import builtin_tasks, load_task, task_from_toml, task_to_toml

ISSUE_EXAMPLE = """
name = "moving"
[disturbance]
move_m = [0.03, 0.08]
turn_deg = [-45, 45]
when = "approach"
"""


def test_the_issues_example_reads_into_a_disturbance():
    task = task_from_toml(ISSUE_EXAMPLE, "m.toml")
    assert task.disturbance == Disturbance(move_m=(0.03, 0.08), turn_deg=(-45.0, 45.0),
                                           when=DisturbanceWhen.APPROACH)
    assert task.disturbance.velocity_m_s == 0.0
    inline = task_from_toml('name = "s"\ndisturbance = { velocity_m_s = 0.05 }', "s.toml")
    assert inline.disturbance == Disturbance(velocity_m_s=0.05)
    assert task_from_toml('name = "still"', "t.toml").disturbance is None


@pytest.mark.parametrize(("table", "message"), [
    ("[disturbance]", r"task file t\.toml: disturbance = \{'move_m': \[0\.0, 0\.0\], 'turn_deg': "
     r"\[0\.0, 0\.0\], 'velocity_m_s': 0\.0, 'when': 'approach'\} is not allowed: a move_m, "
     r"turn_deg or velocity_m_s that is not zero"),
    ("disturbance = 3", r"task file t\.toml: disturbance = 3 is not allowed: a \[table\]"),
    ("[disturbance]\npush = 1", r"task file t\.toml: disturbance\.push = 1 is not allowed: a "
     r"known key: move_m, turn_deg, velocity_m_s, when"),
    ("[disturbance]\nmove_m = [0.1, 0.2]", r"task file t\.toml: disturbance\.move_m = \[0\.1, "
     r"0\.2\] is not allowed: \[low, high\], two finite numbers with 0 <= low <= high <= 0\.15 "
     r"\[m\]"),
    ("[disturbance]\nmove_m = [-0.01, 0.02]", r"disturbance\.move_m = \[-0\.01, 0\.02\] is not "
     r"allowed: \[low, high\], two finite numbers with 0 <= low"),
    ("[disturbance]\nmove_m = [0.08, 0.03]", r"disturbance\.move_m = \[0\.08, 0\.03\] is not "
     r"allowed: \[low, high\]"),
    ("[disturbance]\nmove_m = [0.03]", r"disturbance\.move_m = \[0\.03\] is not allowed: a list "
     r"of two finite numbers \[low, high\]"),
    ("[disturbance]\nmove_m = [0.03, nan]", r"disturbance\.move_m = \[0\.03, nan\] is not "
     r"allowed: a list of two finite numbers"),
    ("[disturbance]\nmove_m = 0.05", r"disturbance\.move_m = 0\.05 is not allowed: a list of two"),
    ("[disturbance]\nturn_deg = [-270, 0]", r"disturbance\.turn_deg = \[-270\.0, 0\.0\] is not "
     r"allowed: \[low, high\], two finite numbers with -180 <= low <= high <= 180 \[deg\]"),
    ("[disturbance]\nvelocity_m_s = 0.5", r"disturbance\.velocity_m_s = 0\.5 is not allowed: a "
     r"speed in \[0, 0\.1\] m/s \(0: no slide\)"),
    ("[disturbance]\nvelocity_m_s = -0.01", r"disturbance\.velocity_m_s = -0\.01 is not allowed"),
    ("[disturbance]\nvelocity_m_s = inf", r"disturbance\.velocity_m_s = inf is not allowed"),
    ("[disturbance]\nvelocity_m_s = true", r"disturbance\.velocity_m_s = True is not allowed: a "
     r"finite number"),
    ("[disturbance]\nvelocity_m_s = " + "9" * 400, r"disturbance\.velocity_m_s = 999.* is not "
     r"allowed: a finite number"),
    ('[disturbance]\nmove_m = [0.03, 0.05]\nwhen = "grasp"', r"disturbance\.when = 'grasp' is "
     r"not allowed: one of 'approach'"),
    ("[disturbance]\nmove_m = [0.03, 0.05]\nwhen = 1", r"disturbance\.when = 1 is not allowed: "
     r"a str"),
])
def test_a_bad_disturbance_names_the_file_the_field_the_value_and_what_is_allowed(table, message):
    with pytest.raises(InvalidInputError, match=message) as raised:
        task_from_toml(f'name = "x"\n{table}', "t.toml")
    assert "\n" not in str(raised.value) and len(str(raised.value)) < 400


def test_a_disturbance_made_in_code_is_checked_too():
    with pytest.raises(InvalidInputError, match=r"^disturbance\.turn_deg = \[10, 5\] is not "):
        Disturbance(turn_deg=(10, 5))
    with pytest.raises(InvalidInputError, match=r"^disturbance\.when = 'approach' is not "):
        Disturbance(move_m=(0.0, 0.01), when="approach")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match=r"^disturbance\.move_m = \[0, 1000"):
        Disturbance(move_m=(0, 10**400))  # an int beyond a float's range
    with pytest.raises(InvalidInputError, match=r"task 'x' \(<code>\): disturbance = 'far' is not "
                       r"allowed: a Disturbance or None"):
        TaskSpec(name="x", disturbance="far")  # type: ignore[arg-type]
    assert Disturbance(move_m=(0.05, 0.05)).move_m == (0.05, 0.05)  # a fixed distance
    assert Disturbance(turn_deg=(0.0, 180.0), velocity_m_s=0.1).velocity_m_s == 0.1  # the edges


STILL = tuple(name for name in builtin_tasks() if load_task(name).disturbance is None)
"""The built-in tasks whose target lies still: all but the moved twins (issue 36)."""


@pytest.mark.parametrize("name", STILL)
def test_a_task_with_a_disturbance_written_as_toml_reads_back_the_same(name):
    task = dataclasses.replace(load_task(name), disturbance=Disturbance(
        move_m=(0.0, 0.15), turn_deg=(-180.0, 12.5), velocity_m_s=0.025))
    assert task_from_toml(task_to_toml(task), task.source) == task
    assert "[disturbance]" not in task_to_toml(load_task(name))


def test_the_moved_twins_differ_from_their_still_tasks_by_the_disturbance():
    """And ``selected-type-moved``'s demonstrations name the types in turn (issue 66)."""
    for name in ("single", "selected-type"):
        still, moved = load_task(name), load_task(f"{name}-moved")
        assert moved.disturbance == Disturbance(move_m=(0.03, 0.08), turn_deg=(-45.0, 45.0))
        assert moved.balance_types == (name == "selected-type") and not still.balance_types
        assert dataclasses.replace(moved, name=name, description=still.description,
                                   disturbance=None, source=still.source,
                                   balance_types=False) == still
        assert task_from_toml(task_to_toml(moved), moved.source) == moved


@pytest.mark.parametrize("name", STILL)
def test_built_in_tasks_record_the_same_fields_as_before_disturbances(name):
    task = load_task(name)
    recorded = task.recorded_fields()
    assert "disturbance" not in recorded  # run identities of existing tasks are unchanged
    before = dataclasses.asdict(task)  # the rule before issue 36, without the new fields
    for key in ("source", "camera", "disturbance", "appearance"):
        before.pop(key)
    if task.distractors_per_scene is None:
        before.pop("distractors_per_scene")
    if task.sensor.to_json() != {"sensor": "ideal"}:
        before["camera"] = task.sensor.to_json()
    assert recorded == before
    moving = dataclasses.replace(task, disturbance=Disturbance(move_m=(0.03, 0.08)))
    assert moving.recorded_fields() == recorded | {"disturbance": {
        "move_m": [0.03, 0.08], "turn_deg": [0.0, 0.0], "velocity_m_s": 0.0, "when": "approach"}}


def test_draws_are_reproducible_per_scene_and_in_their_ranges():
    task = task_from_toml(ISSUE_EXAMPLE + "velocity_m_s = 0.04\n", "m.toml")
    draws = [scene_disturbance(task.disturbance, 7, i) for i in range(300)]
    assert draws == [scene_disturbance(task.disturbance, 7, i) for i in range(300)]  # seeded
    assert draws != [scene_disturbance(task.disturbance, 8, i) for i in range(300)]
    assert draws != [scene_disturbance(task.disturbance, 7, i, SeedStream.TRAIN)
                     for i in range(300)]
    assert len({d.time_fraction for d in draws if d is not None}) == 300  # one per scene
    for draw in draws:
        assert isinstance(draw, DisturbanceDraw)
        assert 0.0 <= draw.time_fraction < 1.0
        assert 0.03 <= math.hypot(draw.dx_m, draw.dy_m) <= 0.08
        assert -math.pi / 4 <= draw.dyaw_rad <= math.pi / 4
        assert math.hypot(*draw.velocity_xy_m_s) == pytest.approx(0.04)
        assert draw.moves and draw.slides
    angles = np.array([math.atan2(d.dy_m, d.dx_m) for d in draws if d is not None])
    assert np.histogram(angles, bins=4, range=(-math.pi, math.pi))[0].min() > 50  # any direction
    assert scene_disturbance(load_task("single").disturbance, 7, 0) is None
    with pytest.raises(InvalidInputError, match=r"seed/index = \(-1, 0\) is not allowed"):
        scene_disturbance(task.disturbance, -1, 0)


def test_a_draw_without_a_range_is_zero_there():
    rng = np.random.default_rng(0)
    slide = draw_disturbance(Disturbance(velocity_m_s=0.1), rng)
    assert (slide.dx_m, slide.dy_m, slide.dyaw_rad) == (0.0, 0.0, 0.0) and not slide.moves
    turn = draw_disturbance(Disturbance(turn_deg=(30.0, 30.0)), rng)
    assert turn.velocity_xy_m_s == (0.0, 0.0) and not turn.slides
    assert turn.dyaw_rad == pytest.approx(math.radians(30.0)) and turn.dx_m == 0.0


def test_a_disturbance_leaves_the_scene_itself_unchanged():
    assert DISTURBANCE_STREAM not in (scene_sampling.DISTRACTOR_STREAM,
                                      scene_sampling.BALANCE_STREAM)
    spec = get_scene_spec("yumi")
    for name in ("multiple", "selected-position"):
        still = load_task(name)
        moving = dataclasses.replace(still, disturbance=Disturbance(move_m=(0.03, 0.08)))
        for stream in SeedStream:
            assert [sample_scene(moving, spec, 3, stream, i) for i in range(5)] == \
                [sample_scene(still, spec, 3, stream, i) for i in range(5)]
