"""Scenes labelled by the catalog, never picked, in randomised looks (issue 74, item 2)."""

import numpy as np
import pytest

from experiments.cli import main
from harness.inputs.collector import CollectSettings, LabelSource, LookSource, collect
from harness.run_files import dataset_present
from perception.learning.dataset_file import load_dataset
from robots.yumi import YUMI
from sim.errors import InvalidInputError, RunFolderError
from sim.tasks.appearance import Split, load_palette
from sim.tasks.scene_sampling import SeedStream
from sim.tasks.scene_specs import YUMI_SCENE
from sim.trials.scene_sets.randomised_looks import RandomisedLooks
from sim.world.textures import TextureKind

CATALOG, RANDOMISED = LabelSource.CATALOG, LookSource.RANDOMISED


def _samples_of(data, index):
    return [n for n, record in enumerate(data.scenes) if record["index"] == index]


@pytest.mark.slow
@pytest.mark.parametrize(("task", "looks"), [("multiple", LookSource.TASK),
                                             ("selected-type", RANDOMISED)])
def test_catalog_labels_are_what_a_demonstration_of_the_same_scene_labels(tmp_path, task, looks):
    """The same scene, demonstrated (picked in physics) and labelled by the catalog: the same
    samples, conditions and records; the first image and every label taken from it the same to
    the bit; a later pick's labels within 2 mm (a pick may brush the objects left)."""
    picked = collect(CollectSettings("yumi", task, 1, seed=0, looks=looks), tmp_path / "p.gva",
                     progress=False)
    index = picked.scenes[0]["index"]  # a failed demonstration is redrawn from the next scene
    catalog = collect(CollectSettings("yumi", task, index + 1, seed=0, labels=CATALOG,
                                      looks=looks), tmp_path / "c.gva", progress=False)
    ours = _samples_of(catalog, index)
    assert len(ours) == len(picked) and catalog.metadata.task == picked.metadata.task
    assert [catalog.scenes[n] for n in ours] == list(picked.scenes)
    np.testing.assert_array_equal(catalog.conditions[ours], picked.conditions)
    np.testing.assert_array_equal(catalog.target_present()[ours], picked.target_present())
    first = [n for n, record in enumerate(picked.scenes) if "taken" not in record]
    np.testing.assert_array_equal(catalog.images[ours][first], picked.images[first])
    np.testing.assert_array_equal(catalog.depths_m[ours][first], picked.depths_m[first])
    np.testing.assert_array_equal(catalog.labels[ours][first], picked.labels[first])
    np.testing.assert_allclose(catalog.labels[ours], picked.labels, atol=2e-3)


def test_a_catalog_scene_of_several_targets_gives_an_image_before_each_pick(tmp_path):
    """As a demonstration: the targets taken so far gone from the image, marked, labelled."""
    data = collect(CollectSettings("yumi", "multiple", 1, seed=0, labels=CATALOG),
                   tmp_path / "m.gva", progress=False)
    assert [record.get("taken", []) for record in data.scenes] == [[], [0], [0, 1]]
    np.testing.assert_array_equal(data.target_present(), [[True] * 3, [False, True, True],
                                                          [False, False, True]])
    np.testing.assert_array_equal(data.labels[1:], data.labels[:2])  # nothing else moved
    for before, after in ((0, 1), (1, 2)):
        assert np.any(data.images[before] != data.images[after], axis=-1).sum() > 100
    assert data.depths_m is not None and data.joint_positions is not None


def test_randomised_catalog_scenes_record_what_they_are_and_their_hues_vary(tmp_path):
    data = collect(CollectSettings("yumi", "single", 4, seed=2, labels=CATALOG,
                                   looks=RANDOMISED), tmp_path / "r.gva", progress=False)
    meta = data.metadata
    assert meta.task == "single+randomised" and meta.extra["labels"] == "catalog"
    assert meta.extra["looks"] == {"kind": "randomised", "look_stream": 4,
                                   "draw": RandomisedLooks().to_json()}
    assert meta.extra["stream"] == "train" and "demonstrations_redrawn" not in meta.extra
    assert load_dataset(tmp_path / "r.gva") == data  # the project's dataset format
    colours = [record["look"]["objects"][record["targets"][0]]["colours"][0]
               for record in data.scenes]
    assert len(set(colours)) == 4
    assert len({record["look"]["table"] for record in data.scenes}) > 1
    assert all(not np.array_equal(data.images[0], image) for image in data.images[1:])
    # a demonstration set records neither: its bytes are as before
    picked = CollectSettings("yumi", "single", 1)
    assert picked.recorded() == {} and picked.task_spec.name == "single"


def test_randomised_looks_never_draw_a_held_out_colourway_print_or_look_alike_finish():
    settings = CollectSettings("yumi", "multiple", 1, looks=RANDOMISED)
    task, looks = settings.task_spec, RandomisedLooks()
    scenes = [settings.scene_at(task, YUMI_SCENE, index) for index in range(300)]
    held_out = {kind: [e.colours for e in entries if e.split is Split.TEST]
                for kind, entries in load_palette("household").entries}
    drawn = []
    for scene in scenes:
        assert scene.look is not None and scene.look.mount is None  # the camera stays put
        for placed, look in zip(scene.objects, scene.look.objects, strict=True):
            if placed.distractor:
                continue
            assert look.colours not in held_out[placed.object_type]
            assert looks.allowed(placed.object_type, look.colours)
            assert look.texture in (TextureKind.PLAIN, TextureKind.STRIPES)
            drawn.append(look.colours[0])
    buckets = {round(int(c[1:3], 16) / 32) * 100 + round(int(c[3:5], 16) / 32) * 10
            + round(int(c[5:7], 16) / 32) for c in drawn}
    assert len(buckets) > 150  # spread over colour space, not a palette's few entries
    assert sum(any(p.distractor for p in scene.objects) for scene in scenes) > 100  # sometimes
    # the rule itself, on the palette's own values
    assert not looks.allowed("mug", ("#ff69b4",))  # hotpink: a held-out mug
    assert not looks.allowed("sponge", ("#87cefa", "#000080"))  # a held-out sponge
    assert looks.allowed("mug", ("#ffd700",))  # gold: a training mug
    assert looks.allowed("sponge", ("#87cefa", "#ffd700"))  # the held-out foam, another scourer
    assert not looks.allowed("mug", ("#cc9e66",))  # the shape twins' wood
    assert not looks.allowed("sponge", ("#ffd700", "#cd9f65"))  # any part near it


def test_bad_labels_and_looks_are_refused_naming_the_field():
    with pytest.raises(InvalidInputError, match=r"labels = 'catalog' is not allowed: one of "
                                                r"LabelSource.PICKED, LabelSource.CATALOG"):
        CollectSettings("yumi", "single", 4, labels="catalog")
    with pytest.raises(InvalidInputError, match=r"looks = 'randomised' is not allowed: 'task' "
                                                r"for the paper-sim scene"):
        CollectSettings("paper-sim", "single", 4, looks=RANDOMISED)
    with pytest.raises(InvalidInputError, match=r"labels = 'catalog' is not allowed: 'picked'"):
        CollectSettings("paper-sim", "single", 4, labels=CATALOG)
    with pytest.raises(InvalidInputError, match=r"looks = 'randomised' is not allowed: 'task' "
                                                r"with a variant"):
        CollectSettings("yumi", "single", 4, variant="varied", looks=RANDOMISED)
    with pytest.raises(InvalidInputError, match=r"approach_hz = 5.0 is not allowed: None with "
                                                r"catalog labels"):
        CollectSettings("yumi", "single", 4, approach_hz=5.0, labels=CATALOG)
    with pytest.raises(InvalidInputError, match=r"textures = \['plain', 'print'\] is not "
                                                r"allowed: one or more of the train half"):
        RandomisedLooks(textures=(TextureKind.PLAIN, TextureKind.PRINT))
    with pytest.raises(InvalidInputError, match=r"elevation_deg = \(0.0, 90.0\) is not allowed"):
        RandomisedLooks(elevation_deg=(0.0, 90.0))


def test_cli_collect_takes_labels_and_looks_and_never_overwrites(tmp_path, capsys):
    out = tmp_path / "s.gva"
    assert main(["collect", "--scene", "yumi", "--task", "single", "--size", "2", "--labels",
                 "catalog", "--looks", "randomised", "--out", str(out), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "single+randomised" in printed and "labelled by the catalog, never picked" in printed
    before = out.read_bytes()
    assert main(["collect", "--scene", "yumi", "--task", "single", "--size", "2", "--labels",
                 "catalog", "--out", str(out)]) == 2
    assert "--out = " in capsys.readouterr().err and out.read_bytes() == before
    with pytest.raises(SystemExit):
        main(["collect", "--scene", "yumi", "--task", "single", "--size", "2", "--labels",
              "guessed", "--out", str(tmp_path / "x.gva")])
    assert "invalid choice: 'guessed'" in capsys.readouterr().err


def test_a_catalog_set_is_never_taken_for_a_run_folders_demonstrations(tmp_path):
    path = tmp_path / "single-train-1-s0.gva"
    collect(CollectSettings("yumi", "single", 1, labels=CATALOG), path, progress=False)
    with pytest.raises(RunFolderError, match=r"'labels': \('catalog', None\)"):
        dataset_present(path, "yumi", "single", 1, 0, SeedStream.TRAIN, robot=YUMI)
