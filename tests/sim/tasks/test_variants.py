"""Variants: a task under another appearance, laid over it from a fragment of a task file."""

from __future__ import annotations

import dataclasses
import tomllib

import pytest

from harness.inputs.trial_settings import TrialSettings
from sim.errors import InvalidInputError
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task, task_to_toml
from sim.tasks.variants import builtin_variants, read_variant, with_variant

TASKS = ("single", "multiple", "selected-type", "selected-position", "selected-type-text",
         "single-moved")


@pytest.mark.parametrize("variant", builtin_variants())
def test_every_variant_lays_over_every_task_and_keeps_its_scenes(variant):
    for name in TASKS:
        task = load_task(name)
        varied = with_variant(task, variant)
        assert varied.name == f"{name}+{variant}"
        assert dataclasses.replace(varied, name=task.name, appearance=task.appearance,
                                   brightness=task.brightness, distractors=task.distractors,
                                   distractors_per_scene=task.distractors_per_scene,
                                   source=task.source) == task
        # and what the variant sets is what the varied task holds (issue 79: a with_variant
        # that changed nothing passed the line above)
        written = tomllib.loads(task_to_toml(varied))
        for table, keys in read_variant(variant)[1].items():
            for key, value in keys.items():
                held = written[table][key]
                if (table, key) == ("distractors", "types"):  # joined to the task's own
                    assert set(value) <= set(held)
                else:
                    assert held == value, (table, key)
        for index in range(3):
            plain = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, index)
            scene = sample_scene(varied, YUMI_SCENE, 0, SeedStream.TEST, index)
            assert scene.objects[:len(plain.objects)] == plain.objects
            assert (scene.targets, scene.condition) == (plain.targets, plain.condition)


def test_the_paper_robustness_rows_are_variants():
    assert with_variant(load_task("single"), "dark").brightness == 0.5
    block = with_variant(load_task("single"), "block")
    assert block.distractors == ("block",) and block.appearance.is_default


def test_a_variants_distractors_join_the_tasks_own(tmp_path):
    (tmp_path / "t.toml").write_text('name = "t"\n[distractors]\ntypes = ["marker", "block"]\n')
    task = with_variant(load_task(tmp_path / "t.toml"), "shape-twins")
    assert task.distractors == ("marker", "block", "bottle_twin", "mug_twin")


@pytest.mark.parametrize(("text", "message"), [
    ("[placement]\nsides = true", r"variant file v\.toml: placement = \{'sides': True\} is not "
     r"allowed: a table among objects, lighting, table, camera, distractors, appearance"),
    ('[objects]\ncount = 3', r"variant file v\.toml: objects\.count = 3 is not allowed: a key a "
     r"variant sets there: palette, textures"),
    ('[camera]\nsensor = "d435"', r"camera\.sensor = 'd435' is not allowed: a key a variant "
     r"sets there: mount_offset_deg, mount_offset_mm"),
    ('[table]\nlooks = ["marble"]', r"task 'single\+v' \(single\.toml \+ variant v\): "
     r"table\.looks = \['marble'\] is not allowed"),
    ("[lighting\n", r"variant file v\.toml = 'not a TOML text in UTF-8'"),
    ('[distractors]\ntypes = "block"', r"variant file v: distractors\.types = 'block' is not "
     r"allowed: a list of object type names"),  # issue 77: read as five letters
])
def test_a_bad_variant_names_its_file_and_field(tmp_path, text, message):
    (tmp_path / "v.toml").write_text(text)
    with pytest.raises(InvalidInputError, match=message):
        with_variant(load_task("single"), tmp_path / "v.toml")


def test_an_unknown_variant_lists_the_built_in_ones():
    with pytest.raises(InvalidInputError, match=r"variant = 'foggy' is not allowed: one of "
                       r"block, colour-twins, dark"):
        with_variant(load_task("single"), "foggy")


def test_trial_settings_take_a_variant_into_the_runs_identity():
    plain = TrialSettings(model="oracle", task="single")
    varied = TrialSettings(model="oracle", task="single", variant="palette")
    assert varied.task_spec.name == "single+palette"
    assert varied.identity()["task"] != plain.identity()["task"]
    assert varied.inputs()["variant_file"].name == "palette.toml"
