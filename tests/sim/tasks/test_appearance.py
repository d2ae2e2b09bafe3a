"""Appearance as a task condition: keys read and refused by name, looks drawn apart from scenes."""

from __future__ import annotations

import dataclasses

import pytest

from perception.objects.catalog import OBJECT_TYPES
from sim.errors import InvalidInputError
from sim.tasks.appearance import TEXTURE_SPLIT, load_palette
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE, get_scene_spec
from sim.tasks.task_toml import load_task, task_from_toml, task_to_toml
from sim.world.looks import part_colours
from sim.world.textures import TextureKind

VARIED = """
name = "varied"
[objects]
choose = "one_of_each"
count = 3
palette = "household"
textures = ["plain", "print", "stripes", "noise"]
[targets]
select = "all"
[lighting]
azimuth_deg = [0, 360]
elevation_deg = [30, 80]
colour_temperature_k = [2700, 6500]
ambient = [0.4, 0.8]
diffuse = 0.5
shadows = false
[table]
looks = ["wood", "white", "grey", "cloth"]
[camera]
mount_offset_mm = 15
mount_offset_deg = 2
[distractors]
types = ["colour_twin", "bottle_twin"]
"""


def varied(extra: str = "") -> object:
    return task_from_toml(VARIED + extra, "varied.toml")


def plain_of(task):
    """The task with today's looks (and no look-alikes): the scene the varied one presents."""
    return dataclasses.replace(task, appearance=type(task.appearance)())


def test_a_varied_task_presents_the_same_scene_as_the_plain_task():
    task = varied()
    plain = plain_of(task)
    for stream in SeedStream:
        for index in range(20):
            looked = sample_scene(task, YUMI_SCENE, 3, stream, index)
            today = sample_scene(plain, YUMI_SCENE, 3, stream, index)
            assert looked.look is not None and today.look.table == "wood"  # the twin's colour
            assert dataclasses.replace(looked, look=None) == dataclasses.replace(today, look=None)
            record, plain_record = looked.to_record(), today.to_record()
            assert record.pop("look") != plain_record.pop("look")
            assert record == plain_record


def test_todays_tasks_draw_no_look_and_record_none():
    for name in ("single", "multiple", "selected-type", "selected-position"):
        task = load_task(name)
        assert task.appearance.is_default and "appearance" not in task.recorded_fields()
        scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, 0)
        assert scene.look is None and "look" not in scene.to_record()


def test_looks_are_seeded_and_vary_over_scenes():
    task = varied()
    looks = [sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, i).look for i in range(30)]
    again = [sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, i).look for i in range(30)]
    assert looks == again
    assert len({look.table for look in looks}) == 4
    assert len({look.objects[0].colours for look in looks}) >= 4  # the sponge's colourways
    assert len({look.objects[0].texture for look in looks}) == 4
    temperatures = [look.light.colour_temperature_k for look in looks]
    assert all(2700 <= t <= 6500 for t in temperatures)
    assert all(look.light.diffuse_coeff == 0.5 and not look.light.shadows for look in looks)
    for look in looks:
        assert all(abs(v) <= 0.015 for v in look.mount.offset_m)
        assert abs(look.mount.pan_rad) <= 0.0350 and abs(look.mount.tilt_rad) <= 0.0350


def test_a_colour_twin_takes_its_first_targets_colour_and_shape_twins_keep_wood():
    task = varied()
    for index in range(10):
        scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TRAIN, index)
        types = [o.object_type for o in scene.objects]
        first = scene.look.objects[scene.targets[0]].colours
        assert scene.look.objects[types.index("colour_twin")].colours == (first[0], first[-1])
        assert scene.look.objects[types.index("bottle_twin")].is_catalog


def test_a_held_out_task_shows_training_scenes_only_the_train_half():
    task = varied('[appearance]\nheld_out = true\n')
    palette = load_palette("household")
    for stream, half in ((SeedStream.TRAIN, "train"), (SeedStream.TEST, "test")):
        tables = set()
        for index in range(40):
            look = sample_scene(task, YUMI_SCENE, 1, stream, index).look
            tables.add(look.table)
            for object_type, object_look in zip(OBJECT_TYPES, look.objects, strict=False):
                entry = next(e for e in palette.for_type(object_type)
                             if e.colours == object_look.colours)
                assert entry.split.value == half
                assert TEXTURE_SPLIT[object_look.texture] == half
        assert tables == {"wood", "white", "grey", "cloth"}  # every table in both halves


def test_the_household_palette_gives_each_part_a_colour_and_both_halves():
    palette = load_palette("household")
    assert palette is not None and {t for t, _ in palette.entries} == set(OBJECT_TYPES)
    for object_type, entries in palette.entries:
        from perception.objects.catalog import get_object_spec

        parts = len(part_colours(get_object_spec(object_type)))
        assert all(len(e.colours) == parts for e in entries)
        assert {e.split.value for e in entries} == {"train", "test"}


def test_appearance_survives_a_round_trip_through_toml_and_is_recorded():
    task = varied('[appearance]\nheld_out = true\n')
    again = task_from_toml(task_to_toml(task), "again.toml")
    assert again.appearance == task.appearance
    recorded = task.recorded_fields()["appearance"]
    assert recorded["palette"]["name"] == "household" and len(recorded["palette"]["sha256"]) == 64
    assert recorded["held_out"] is True and recorded["tables"] == ["wood", "white", "grey",
                                                                   "cloth"]


def test_a_palette_file_is_read_relative_to_the_task_file(tmp_path):
    (tmp_path / "mine.toml").write_text('[[mug]]\nname = "olive"\ncolours = ["#808000"]\n')
    (tmp_path / "task.toml").write_text('name = "t"\n[objects]\npalette = "mine.toml"\n')
    task = load_task(tmp_path / "task.toml")
    scene = sample_scene(dataclasses.replace(task, count=3, objects=type(task.objects)(
        "one_of_each")), YUMI_SCENE, 0, SeedStream.TEST, 0)
    looks = dict(zip([o.object_type for o in scene.objects], scene.look.objects, strict=True))
    assert looks["mug"].colours == ("#808000",)
    assert looks["sponge"].colours is None  # a type the palette leaves out keeps its colours


@pytest.mark.parametrize(("palette", "message"), [
    ('[[cup]]\nname = "a"\ncolours = ["#000000"]', r"table = 'cup' is not allowed: "
     r"a target type's \[\[table\]\]: sponge, spray_bottle, mug"),  # issue 77: the value named
    ('[[sponge]]\nname = "a"\ncolours = ["#000000"]', r"sponge\[0\]\.colours = \['#000000'\] is "
     r"not allowed: 2 colours '#rrggbb', one per part"),
    ('[[mug]]\nname = "a"\ncolours = ["red"]', r"mug\[0\]\.colours = 'red' is not allowed: a "
     r"colour written '#rrggbb'"),
    ('[[mug]]\nname = "a"\ncolours = ["#ff0000"]\nsplit = "dev"', r"mug\[0\]\.split = 'dev' is "
     r"not allowed: one of 'train', 'test', 'both'"),
    ('[[mug]]\nname = "a"\ncolour = ["#ff0000"]', r"mug\[0\]\.colour = \['#ff0000'\] is not "
     r"allowed: a known key"),
])
def test_a_bad_palette_file_names_its_field(tmp_path, palette, message):
    (tmp_path / "mine.toml").write_text(palette)
    (tmp_path / "task.toml").write_text('name = "t"\n[objects]\npalette = "mine.toml"\n')
    prefix = r"task file task\.toml: palette mine\.toml: "
    with pytest.raises(InvalidInputError, match=prefix + message):
        load_task(tmp_path / "task.toml")


@pytest.mark.parametrize(("keys", "message"), [
    ('[objects]\npalette = "rainbow"', r"objects\.palette = 'rainbow' is not allowed: one of "
     r"catalog, household, or an existing palette \.toml file"),
    ('[objects]\ntextures = ["plaid"]', r"objects\.textures = \['plaid'\] is not allowed: names "
     r"among plain, print, stripes, noise"),
    ('[objects]\ntextures = []', r"objects\.textures = \[\] is not allowed: distinct names"),
    ('[table]\nlooks = ["granite"]', r"table\.looks = \['granite'\] is not allowed: distinct "
     r"names among wood, white"),
    ('[lighting]\ncolour_temperature_k = [1000, 6500]', r"lighting\.colour_temperature_k = "
     r"\[1000\.0, 6500\.0\] is not allowed: .*1800 <= low <= high <= 10000 \(kelvin\)"),
    ('[lighting]\nelevation_deg = -10', r"lighting\.elevation_deg = \[-10\.0, -10\.0\] is not "
     r"allowed: .*5 <= low"),
    ('[lighting]\nambient = [0.8, 0.2]', r"lighting\.ambient = \[0\.8, 0\.2\] is not allowed"),
    ('[lighting]\nazimuth_deg = [0, 1, 2]', r"lighting\.azimuth_deg = \[0, 1, 2\] is not allowed:"
     r" a finite number or a list of two"),
    ('[lighting]\nshadows = 1', r"lighting\.shadows = 1 is not allowed: true or false"),
    ('[camera]\nmount_offset_mm = 80', r"camera\.mount_offset_mm = 80\.0 is not allowed: a "
     r"number in \[0, 50\] mm"),
    ('[camera]\nmount_offset_deg = -1', r"camera\.mount_offset_deg = -1\.0 is not allowed"),
    ('[appearance]\nheld_out = "yes"', r"appearance\.held_out = 'yes' is not allowed: true or "
     r"false"),
    ('[appearance]\nheld_out = true\n[objects]\ntextures = ["plain", "stripes"]',
     r"objects\.textures = \['plain', 'stripes'\] is not allowed: at least one test member "
     r"when appearance\.held_out = true"),
])
def test_a_bad_appearance_key_names_the_field_the_value_and_what_is_allowed(keys, message):
    with pytest.raises(InvalidInputError, match=message):
        task_from_toml('name = "t"\n' + keys, "t.toml")


@pytest.mark.parametrize(("keys", "named"), [
    ('[objects]\ntextures = ["print"]', r"objects\.textures = \['print'\]"),
    ("[lighting]\nambient = 0.5", r"lighting\.ambient = \[0\.5, 0\.5\]"),
    ("[camera]\nmount_offset_mm = 15", r"camera\.mount_offset_mm = 15\.0"),
    ('[distractors]\ntypes = ["colour_twin"]', r"distractors\.types = \['colour_twin'\]"),
])
def test_the_paper_scene_refuses_a_varied_look_naming_the_task_files_key(keys, named):
    """The refusal names the key a user wrote, not the record's internal form (issue 77)."""
    with pytest.raises(InvalidInputError, match=r"in scene 'paper-sim': " + named +
                       r" is not allowed: today's looks") as error:
        sample_scene(task_from_toml('name = "t"\n' + keys, "t.toml"),
                     get_scene_spec("paper-sim"), 0, SeedStream.TEST, 0)
    assert "{" not in str(error.value)


def test_every_texture_belongs_to_a_half():
    assert set(TEXTURE_SPLIT) == set(TextureKind)
