"""Table clutter (issue 49): objects that are never targets, and a random number of them a scene.

The clutter must rest on the table, look unlike every target and the block, and a task's
``distractors.per_scene`` must draw them per scene without touching the rest of the scene.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Iterator

import numpy as np
import pinocchio as pin
import pytest

from harness.inputs.collector import _task_json
from harness.inputs.trial_settings import task_identity
from perception.objects.catalog import (
    CLUTTER_TYPES,
    DISTRACTOR_TYPES,
    LOOK_ALIKE_TYPES,
    OBJECT_TYPES,
    PrimitiveKind,
    catalog_names,
    get_object_spec,
)
from robots.yumi import YUMI
from sim.errors import InvalidInputError
from sim.tasks.mirror_symmetry import mirror_symmetric, object_is_mirror_symmetric
from sim.tasks.scene_picture import render_scene
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_in_scene import check_task_fits
from sim.tasks.task_spec import MAX_OBJECTS
from sim.tasks.task_toml import load_task, task_from_toml, task_to_toml
from sim.world.head_camera import camera_config
from sim.world.sensor import SensorConfig
from sim.world.yumi_world import World

MIN_RGB_DISTANCE = 0.25
"""Every clutter colour lies at least this far from every target and block colour in RGB."""
MIN_CHROMA_DISTANCE = 0.15
"""... and in chromaticity (rgb / sum): above the colour detector example's 0.12, so it ignores
clutter; grey and black would have white's chromaticity (the spray bottle's)."""
CLUTTER_TASK = ('name = "clutter"\n[objects]\nchoose = "one_of_each"\ncount = 3\n'
                '[targets]\nselect = "condition"\n[condition]\nkind = "object_type"\n'
                '[distractors]\ntypes = ["drink_can", "notebook", "marker", "glue_stick"]\n'
                'per_scene = [0, 4]\n')


@pytest.fixture(scope="module")
def world() -> Iterator[World]:
    with World(robot=YUMI) as w:
        yield w


def _colours(names: tuple[str, ...]) -> list[np.ndarray]:
    return [np.array(p.rgba[:3]) for n in names for p in get_object_spec(n).primitives]


def _chroma(rgb: np.ndarray) -> np.ndarray:
    return rgb / rgb.sum()


def test_clutter_is_in_the_catalog_and_the_yumi_scene_but_never_a_target():
    assert CLUTTER_TYPES == ("drink_can", "notebook", "marker", "glue_stick")
    assert DISTRACTOR_TYPES == ("block",)  # the experiments' look-alike, unchanged
    assert set(CLUTTER_TYPES) <= set(catalog_names())
    assert not set(CLUTTER_TYPES) & set(OBJECT_TYPES + DISTRACTOR_TYPES)
    assert YUMI_SCENE.distractor_types == DISTRACTOR_TYPES + CLUTTER_TYPES + LOOK_ALIKE_TYPES
    assert not set(LOOK_ALIKE_TYPES) & set(OBJECT_TYPES)
    assert YUMI_SCENE.object_types == OBJECT_TYPES


@pytest.mark.parametrize("name", CLUTTER_TYPES)
def test_clutter_colours_are_far_from_every_target_and_the_block(name):
    others = _colours(OBJECT_TYPES + DISTRACTOR_TYPES)
    for colour in _colours((name,)):
        assert min(np.linalg.norm(colour - o) for o in others) >= MIN_RGB_DISTANCE
        assert min(np.linalg.norm(_chroma(colour) - _chroma(o)) for o in others) >= \
            MIN_CHROMA_DISTANCE


@pytest.mark.parametrize("name", CLUTTER_TYPES)
def test_clutter_is_unlike_the_block_in_shape_and_fits_the_spacing(name):
    spec, block = get_object_spec(name), get_object_spec("block")
    assert len(spec.primitives) <= 16 and 0.0 < spec.mass_kg <= 0.5
    assert object_is_mirror_symmetric(spec)  # mirrored demonstrations stay valid
    reach_m = max(math.hypot(*p.position_m[:2]) + 0.5 * math.hypot(*p.size_m[:2])
                  for p in spec.primitives)
    assert reach_m <= 0.075  # no farther from its centre than the mug's handle (+ 8 mm)
    for p in spec.primitives:  # no box with the block's (or the sponge's) footprint
        if p.kind is PrimitiveKind.BOX:
            footprint = sorted(p.size_m[:2], reverse=True)
            block_footprint = sorted(block.primitives[0].size_m[:2], reverse=True)
            assert max(abs(a - b) for a, b in zip(footprint, block_footprint, strict=True)) \
                > 0.02


@pytest.mark.parametrize("name", CLUTTER_TYPES)
def test_clutter_builds_and_rests_on_the_table(world, name):
    for yaw in (0.7, -2.0):
        world.reset_scene()
        body = world.add_object(get_object_spec(name), (0.45, 0.05), yaw)
        start = world.object_pose(body)
        np.testing.assert_allclose(start.position, [0.45, 0.05, 0.0], atol=1e-9)
        world.step(round(1.0 / world.config.time_step_s))
        end = world.object_pose(body)
        assert np.linalg.norm(end.position - start.position) < 0.002
        turned = float(np.linalg.norm(pin.log3(start.rotation.T @ end.rotation)))
        assert turned < math.radians(0.5)
        assert abs(world.object_bottom_z_m(body)) < 0.002


# Scenes 0-2 of selected-type + distractors block, mug under seed 7 (training stream), drawn
# by the code before distractors.per_scene existed: (type, x, y, yaw, distractor), target, value.
BEFORE_PER_SCENE = [
    ([("sponge", 0.493764319991, 0.158885520388, 3.113320100578, False),
      ("spray_bottle", 0.516352853537, -0.109917124004, 1.838849070775, False),
      ("mug", 0.475682238844, 0.02139894083, 0.767674739267, False),
      ("block", 0.415521660292, -0.176715371048, 0.411571629289, True),
      ("mug", 0.361539905132, -0.028060099035, 0.028526485694, True)], (1,), "spray_bottle"),
    ([("sponge", 0.524976224257, -0.006265371498, -1.550478981098, False),
      ("spray_bottle", 0.508849050038, 0.192342574969, 1.969836625517, False),
      ("mug", 0.40835340484, -0.08130902383, -2.393370106261, False),
      ("block", 0.409933413498, 0.118373745953, -2.939787524389, True),
      ("mug", 0.493549912219, -0.182646537976, 1.420613161513, True)], (0,), "sponge"),
    ([("sponge", 0.40451433676, -0.105618973862, 0.342397135922, False),
      ("spray_bottle", 0.544104344957, -0.174629773639, -2.060813138442, False),
      ("mug", 0.505350927498, 0.107602160705, 1.63322963031, False),
      ("block", 0.413849707589, 0.020806865885, 1.729470683999, True),
      ("mug", 0.529790636412, -0.025635466793, 2.114659142739, True)], (0,), "sponge"),
]


def test_a_task_without_per_scene_draws_the_scenes_it_drew_before():
    task = dataclasses.replace(load_task("selected-type"), distractors=("block", "mug"))
    for index, (objects, targets, value) in enumerate(BEFORE_PER_SCENE):
        scene = sample_scene(task, YUMI_SCENE, 7, SeedStream.TRAIN, index)
        got = [(o.object_type, *o.position_xy_m, o.yaw_rad, o.distractor) for o in scene.objects]
        assert [(g[0], g[4]) for g in got] == [(o[0], o[4]) for o in objects]
        np.testing.assert_allclose([g[1:4] for g in got], [o[1:4] for o in objects],
                                   rtol=0, atol=1e-11)
        assert (scene.targets, scene.condition.value) == (targets, value)


def test_per_scene_draws_every_count_distinct_clutter_and_leaves_the_scene_alone():
    task = task_from_toml(CLUTTER_TASK, "clutter.toml")
    plain_task = dataclasses.replace(task, distractors=(), distractors_per_scene=None)
    counts = set()
    for stream, index in itertools.product(SeedStream, range(30)):
        plain = sample_scene(plain_task, YUMI_SCENE, 3, stream, index)
        scene = sample_scene(task, YUMI_SCENE, 3, stream, index)
        head, clutter = scene.objects[:len(plain.objects)], scene.objects[len(plain.objects):]
        assert head == plain.objects
        assert (scene.targets, scene.condition, scene.query) == \
            (plain.targets, plain.condition, plain.query)
        types = [o.object_type for o in clutter]
        assert all(o.distractor for o in clutter) and set(types) <= set(CLUTTER_TYPES)
        assert len(set(types)) == len(types)  # never the same type twice in a scene
        assert not set(types) & set(OBJECT_TYPES)
        assert all(not scene.objects[t].distractor for t in scene.targets)
        xy = np.array([o.position_xy_m for o in scene.objects])  # (n, 2)
        gaps = np.linalg.norm(xy[:, None] - xy[None], axis=-1)[np.triu_indices(len(xy), 1)]
        assert gaps.min() >= task.min_spacing_m
        counts.add(len(clutter))
    assert counts == {0, 1, 2, 3, 4}
    again = sample_scene(task, YUMI_SCENE, 3, SeedStream.TEST, 5)
    assert again == sample_scene(task, YUMI_SCENE, 3, SeedStream.TEST, 5)  # seeded
    assert mirror_symmetric(task, YUMI_SCENE, camera_config(YUMI))


@pytest.mark.parametrize(("per_scene", "message"), [
    ("[1]", r"distractors\.per_scene = \[1\] is not allowed: a list of two integers"),
    ("[0, 1.5]", r"distractors\.per_scene = \[0, 1\.5\] is not allowed: a list of two integers"),
    ("[true, 1]", r"distractors\.per_scene = \[True, 1\] is not allowed: a list of two integ"),
    ('"0-2"', r"distractors\.per_scene = '0-2' is not allowed: a list of two integers"),
    ("[2, 1]", r"distractors\.per_scene = \[2, 1\] is not allowed: \[low, high\] with 0 <= "
               r"low <= high <= 4 \(the number of distractors\.types\)"),
    ("[-1, 1]", r"distractors\.per_scene = \[-1, 1\] is not allowed: \[low, high\] with 0 <="),
    ("[0, 5]", r"distractors\.per_scene = \[0, 5\] is not allowed: \[low, high\] with 0 <= "
               r"low <= high <= 4"),
])
def test_bad_per_scene_values_are_refused_naming_the_file_and_field(per_scene, message):
    text = CLUTTER_TASK.replace("per_scene = [0, 4]", f"per_scene = {per_scene}")
    with pytest.raises(InvalidInputError, match=r"clutter\.toml.*" + message):
        task_from_toml(text, "clutter.toml")


def test_per_scene_keeps_the_object_bound_and_needs_distinct_types():
    many = ', '.join(f'"{t}"' for t in (*CLUTTER_TYPES, "block", "sponge", "mug",
                                         "spray_bottle"))
    text = f'name = "m"\n[objects]\ncount = 5\n[distractors]\ntypes = [{many}]\n'
    assert task_from_toml(text + "per_scene = [0, 7]\n").distractor_count_range == (0, 7)
    with pytest.raises(InvalidInputError, match=rf"distractors\.per_scene = \[0, 8\] is not "
                       rf"allowed: \[low, high\] with high <= 7 \(objects\.count \+ distractors "
                       rf"<= {MAX_OBJECTS}\)"):
        task_from_toml(text + "per_scene = [0, 8]\n")
    with pytest.raises(InvalidInputError, match=r"distractors\.types = \['mug', 'mug'\] is not "
                       r"allowed: distinct types when distractors\.per_scene is given"):
        task_from_toml('name = "d"\n[distractors]\ntypes = ["mug", "mug"]\nper_scene = [1, 1]')
    spaced = task_from_toml(text.replace("count = 5", "count = 1") + "per_scene = [0, 6]\n"
                            "[placement]\nmin_spacing_m = 0.5\n")  # 6 fit: the area bound
    with pytest.raises(InvalidInputError, match=r"distractors\.per_scene = \[0, 6\] is not "
                       r"allowed: at most 5 distractors: no more than 6 objects 0\.5 m apart"):
        check_task_fits(spaced, YUMI_SCENE)
    check_task_fits(dataclasses.replace(spaced, distractors_per_scene=(0, 5)), YUMI_SCENE)


def test_per_scene_round_trips_and_enters_the_identity_only_when_given():
    task = task_from_toml(CLUTTER_TASK, "clutter.toml")
    assert task.distractors_per_scene == (0, 4)
    assert task_from_toml(task_to_toml(task), "clutter.toml") == task
    assert "per_scene = [0, 4]" in task_to_toml(task)
    assert task_identity(task)["distractors_per_scene"] == (0, 4)
    everything = dataclasses.replace(task, distractors_per_scene=None)
    assert "per_scene" not in task_to_toml(everything)
    assert task_from_toml(task_to_toml(everything), "clutter.toml") == everything
    assert task_identity(task) != task_identity(everything)
    # An old task's identity has exactly the keys it had before per_scene existed.
    # An old task's identity (runs) and record (datasets) have exactly the keys they had
    # before per_scene existed, so old run folders and datasets still match.
    before = {"name", "description", "objects", "count", "balance_types", "targets", "condition",
              "given_as", "phrasings", "sides", "yaw_range_rad", "min_spacing_m",
              "workspace_x_m", "workspace_y_m", "brightness", "distractors"}
    old = dataclasses.replace(load_task("single"), camera=SensorConfig())  # ideal, as before 64
    assert set(task_identity(old)) == before
    assert set(_task_json(old)) == before
    assert _task_json(task)["distractors_per_scene"] == [0, 4]


def test_a_cluttered_scene_renders_every_clutter_object_through_the_head_camera():
    task = dataclasses.replace(task_from_toml(CLUTTER_TASK), distractors_per_scene=(4, 4))
    scene = sample_scene(task, YUMI_SCENE, 3, SeedStream.TRAIN, 0)
    image = render_scene(scene).reshape(-1, 3).astype(float) / 255.0  # (H W, 3)
    chroma = image / np.maximum(image.sum(axis=1, keepdims=True), 1e-9)
    for name in CLUTTER_TYPES:
        colour = np.array(get_object_spec(name).primitives[0].rgba[:3])
        near = np.linalg.norm(chroma - _chroma(colour), axis=1) < 0.05
        assert near.sum() >= 10, name  # seen: its own colour on at least 10 pixels
