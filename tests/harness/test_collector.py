import dataclasses

import numpy as np
import pytest
from user_models import synthetic_dataset

from experiments.cli import main
from harness.inputs import collector
from harness.inputs.collector import (
    APPROACH_HIDDEN_SHARE_MAX,
    APPROACH_MASKED_KEY,
    HIDDEN_SHARE_KEY,
    CollectSettings,
    collect,
)
from perception.camera import RgbdFrame
from perception.interface import ConditionKind, LabelKind
from perception.labels import split_label
from perception.learning.dataset_file import DatasetError, load_dataset
from perception.learning.learnable import ModelSpec
from robots.yumi import YUMI
from sim.errors import InvalidInputError
from sim.tasks.scene_sampling import SeedStream
from sim.tasks.scene_specs import get_scene_spec
from sim.tasks.task_toml import load_task, task_to_toml
from sim.trials.closed_loop.view import hidden_share
from sim.world.head_camera import CameraConfig, camera_config
from sim.world.sensor import SensorConfig, SensorKind


@pytest.fixture(scope="module")
def yumi_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("yumi")
    paths = {}
    for name, seed in (("a", 0), ("b", 0), ("c", 1)):
        paths[name] = folder / f"{name}.gva"
        collect(CollectSettings("yumi", "selected-type", size=2, seed=seed), paths[name],
                progress=False)
    return paths


@pytest.mark.slow
def test_a_demonstration_of_several_picks_keeps_the_image_before_each(tmp_path):
    data = collect(CollectSettings("yumi", "multiple", size=1, seed=0), tmp_path / "m.gva",
                   progress=False)
    assert len(data) == 3 and data.metadata.extra["scenes"] == 1
    assert [record.get("taken", []) for record in data.scenes] == [[], [0], [0, 1]]
    np.testing.assert_array_equal(data.target_present(), [[True] * 3, [False, True, True],
                                                          [False, False, True]])
    # A picked target keeps its last label; the others stay within a millimetre of theirs.
    np.testing.assert_array_equal(data.labels[1, 0], data.labels[0, 0])
    np.testing.assert_array_equal(data.labels[2, :2], data.labels[1, :2])
    np.testing.assert_allclose(data.labels[1:, 2], data.labels[:2, 2], atol=1e-3)
    assert all(len(record["objects"]) == 3 for record in data.scenes)  # the scene, as drawn
    for before, after in ((0, 1), (1, 2)):  # the picked object is gone from the next image
        assert np.any(data.images[before] != data.images[after], axis=-1).sum() > 100
    # the RGB-D frame's depth and the robot's joints of each image are kept, and read back
    assert data.depths_m is not None and data.joint_positions is not None
    assert data.depths_m.shape == (3, 128, 128) and 0.3 < float(np.median(data.depths_m)) < 1.0
    names = data.metadata.extra["joint_names"]
    assert data.joint_positions.shape == (3, len(names)) and len(names) == 18
    assert load_dataset(tmp_path / "m.gva") == data


@pytest.mark.slow
def test_same_seed_gives_a_byte_identical_dataset(yumi_files):
    assert yumi_files["a"].read_bytes() == yumi_files["b"].read_bytes()
    assert yumi_files["a"].read_bytes() != yumi_files["c"].read_bytes()


@pytest.mark.slow
def test_yumi_dataset_holds_grasp_labels_conditions_and_scene_records(yumi_files):
    data = load_dataset(yumi_files["a"], expect={"scene": "yumi", "task": "selected-type"})
    meta = data.metadata
    assert meta.label_kind is LabelKind.GRASP_POSE and meta.targets == 1
    assert meta.condition_choices == ("sponge", "spray_bottle", "mug")
    assert data.images.shape == (6, 128, 128, 3) and data.images.dtype == np.uint8
    assert meta.extra["scenes"] == 2 and meta.extra["every_condition"] is True
    for scene in (0, 1):  # one image of each scene, asked each of the three types
        shown = [n for n, record in enumerate(data.scenes) if record["index"] == data.scenes[
            3 * scene]["index"]]
        assert len(shown) == 3 and sorted(data.conditions[shown].argmax(1)) == [0, 1, 2]
        assert all(np.array_equal(data.images[n], data.images[shown[0]]) for n in shown)
    assert meta.extra["stream"] == "train" and meta.extra["demonstrations_redrawn"] >= 0
    assert meta.extra["object_types"] == list(meta.condition_choices)  # the scene's vocabulary
    d435 = SensorConfig(SensorKind.D435).to_json()  # no sensor named: the D435 (issue 64)
    assert meta.camera["sensor"] == d435 and meta.extra["task"]["camera"] == d435
    np.testing.assert_array_equal(data.target_type_indices()[:, 0], data.conditions.argmax(1))
    for condition, label, record in zip(data.conditions, data.labels, data.scenes, strict=True):
        named = meta.condition_choices[int(np.argmax(condition))]
        assert record["condition"]["value"] == named
        target = record["objects"][record["targets"][0]]
        assert target["type"] == named
        position, rotation = split_label(label[0])
        assert np.linalg.norm(position[:2] - np.array(target["position_xy_m"])) < 0.06
        assert np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-4)


@pytest.mark.slow
def test_a_dataset_of_another_scene_is_refused(yumi_files):
    with pytest.raises(DatasetError, match=r"scene is 'yumi' in the file, expected 'paper-sim'"):
        load_dataset(yumi_files["a"], expect={"scene": "paper-sim"})


def test_bad_collect_settings_are_named():
    with pytest.raises(InvalidInputError, match=r"scene = 'kitchen' is not allowed: one of "
                       r"paper-sim, yumi"):
        CollectSettings("kitchen", "single", 4)
    with pytest.raises(InvalidInputError, match=r"size = 0 is not allowed: an integer >= 1"):
        CollectSettings("yumi", "single", 0)


def test_cli_collect_reports_a_bad_task(tmp_path, capsys):
    assert main(["collect", "--scene", "yumi", "--task", "juggle", "--size", "2",
                 "--out", str(tmp_path / "x.gva")]) == 2
    assert "task = 'juggle' is not allowed" in capsys.readouterr().err


@pytest.mark.parametrize(("given", "stream"), [([], SeedStream.TRAIN),
                                              (["--stream", "test"], SeedStream.TEST)])
def test_cli_collect_passes_the_stream_to_the_settings(tmp_path, capsys, monkeypatch, given,
                                                      stream):
    import experiments.commands.collect

    asked = []

    def collected(settings, out_path, progress=True):
        asked.append(settings)
        return synthetic_dataset(size=2)

    monkeypatch.setattr(experiments.commands.collect, "collect", collected)
    assert main(["collect", "--scene", "yumi", "--task", "single", "--size", "100", "--seed",
                 "0", *given, "--out", str(tmp_path / "x.gva"), "--no-progress"]) == 0
    assert asked == [CollectSettings("yumi", "single", 100, 0, stream)]
    assert f"{stream.name.lower()} stream" in capsys.readouterr().out
    with pytest.raises(SystemExit):  # argparse names the choices
        main(["collect", "--scene", "yumi", "--task", "single", "--size", "2", "--stream",
              "validation", "--out", str(tmp_path / "x.gva")])
    assert "invalid choice: 'validation' (choose from" in capsys.readouterr().err


def test_paper_sim_dataset_is_seeded_and_labelled_with_positions(tmp_path):
    paths = [tmp_path / f"{i}.gva" for i in range(3)]
    for path, seed in zip(paths, (0, 0, 1), strict=True):
        collect(CollectSettings("paper-sim", "multiple", size=3, seed=seed), path, progress=False)
    assert paths[0].read_bytes() == paths[1].read_bytes()
    assert paths[0].read_bytes() != paths[2].read_bytes()
    data = load_dataset(paths[0], expect={"scene": "paper-sim", "label_kind": "position"})
    assert data.labels.shape == (3, 3, 3) and data.conditions.shape == (3, 0)
    vocabulary = data.metadata.extra["object_types"]
    assert vocabulary == list(get_scene_spec("paper-sim").object_types)
    assert [[vocabulary[i] for i in row] for row in data.target_type_indices()] == \
        [[record["objects"][t]["type"] for t in record["targets"]] for record in data.scenes]
    for labels, record in zip(data.labels, data.scenes, strict=True):
        for label, target in zip(labels, record["targets"], strict=True):
            placed = record["objects"][target]["position_xy_m"]
            assert np.linalg.norm(label[:2] - np.array(placed)) < 0.01


def test_a_test_stream_dataset_is_recorded_and_a_smaller_set_is_a_prefix(tmp_path):
    small = collect(CollectSettings("paper-sim", "single", size=2, seed=4), tmp_path / "a.gva",
                    progress=False)
    large = collect(CollectSettings("paper-sim", "single", size=3, seed=4), tmp_path / "b.gva",
                    progress=False)
    test = collect(CollectSettings("paper-sim", "single", size=2, seed=4,
                                   stream=SeedStream.TEST), tmp_path / "t.gva", progress=False)
    assert large.first_scenes(2) == small
    assert small.metadata.extra["stream"] == "train" and test.metadata.extra["stream"] == "test"
    assert [s["stream"] for s in test.scenes] == ["test", "test"]
    assert not np.array_equal(test.labels, small.labels)
    with pytest.raises(InvalidInputError, match=r"stream = 1 is not allowed: one of "
                       r"SeedStream.TRAIN, SeedStream.TEST"):
        CollectSettings("paper-sim", "single", 2, stream=1)  # type: ignore[arg-type]


def test_a_training_scene_is_asked_every_condition_and_a_test_scene_its_own(tmp_path):
    train = collect(CollectSettings("paper-sim", "selected-position", size=3, seed=2),
                    tmp_path / "a.gva", progress=False)
    test = collect(CollectSettings("paper-sim", "selected-position", size=3, seed=2,
                                   stream=SeedStream.TEST), tmp_path / "t.gva", progress=False)
    one = collect(CollectSettings("paper-sim", "selected-position", size=3, seed=2,
                                  every_condition=False), tmp_path / "b.gva", progress=False)
    assert (len(train), len(test), len(one)) == (6, 3, 3)
    assert train.metadata.extra["scenes"] == 3 and train.metadata.extra["every_condition"]
    assert not test.metadata.extra["every_condition"]
    # the drawn question first, as the one-question dataset has it, then the other side
    np.testing.assert_array_equal(train.images[::2], one.images)
    np.testing.assert_array_equal(train.labels[::2], one.labels)
    for first, second in zip(train.scenes[::2], train.scenes[1::2], strict=True):
        assert first["index"] == second["index"] and first["objects"] == second["objects"]
        assert {first["condition"]["value"], second["condition"]["value"]} == {"left", "right"}
        ys = {record["condition"]["value"]: record["objects"][record["targets"][0]]
              ["position_xy_m"][1] for record in (first, second)}
        assert ys["left"] > ys["right"]  # the robot's left is +y
    assert train.first_scenes(2).metadata.extra["scenes"] == 2 and len(train.first_scenes(2)) == 4


@pytest.mark.parametrize("task", ["selected-type-text", "selected-type-image"])
def test_a_sentence_or_picture_dataset_keeps_what_each_sample_was_asked(tmp_path, task):
    """Every condition of a training scene, each with its own sentence or picture as the row."""
    data = collect(CollectSettings("paper-sim", task, size=2, seed=0), tmp_path / "d.gva",
                   progress=False)
    spec = get_scene_spec("paper-sim")
    assert data.metadata.condition_kind is (ConditionKind.TEXT if task.endswith("text")
                                            else ConditionKind.IMAGE)
    assert data.metadata.condition_choices == spec.object_types and len(data) == 6
    assert sorted(data.condition_names()) == sorted(spec.object_types * 2)
    phrasings = load_task(task).phrasings
    for n, record in enumerate(data.scenes):
        given = data.condition(n)
        assert record["query"] == {"kind": given.kind.value, "value": given.value}
        assert record["condition"]["value"] == data.condition_names()[n]
        if phrasings is not None:  # a training scene says a training phrasing of its target
            assert given.value in phrasings.of("train", data.condition_names()[n])
        np.testing.assert_allclose(given.vector(), data.conditions[n], atol=1e-6)


def test_a_d435_dataset_records_its_sensor_and_keeps_the_calibration(tmp_path):
    path = tmp_path / "single-d435.toml"
    path.write_text(task_to_toml(dataclasses.replace(
        load_task("single"), name="single-d435", camera=SensorConfig(SensorKind.D435))))
    data = collect(CollectSettings("yumi", str(path), size=1, seed=0), tmp_path / "d.gva",
                   progress=False)
    sensor = SensorConfig(SensorKind.D435).to_json()
    meta = data.metadata
    assert meta.camera["sensor"] == sensor and meta.extra["task"]["camera"] == sensor
    assert CameraConfig.from_json(meta.camera) == camera_config(YUMI)
    assert ModelSpec.from_metadata(meta).camera == camera_config(YUMI).pinhole  # the nominal one
    assert data.depths_m is not None and (data.depths_m == 0.0).any()  # the sensor's holes


def test_sensor_replaces_the_task_files_and_the_paper_scene_keeps_its_own_camera(tmp_path):
    ideal = collect(CollectSettings("yumi", "single", size=1, seed=0, sensor=SensorKind.IDEAL),
                    tmp_path / "i.gva", progress=False).metadata
    assert ideal.camera["sensor"] == {"sensor": "ideal"} and "camera" not in ideal.extra["task"]
    paper = collect(CollectSettings("paper-sim", "single", size=1, seed=0), tmp_path / "p.gva",
                    progress=False).metadata  # its datasets as before the D435 default
    assert paper.camera["sensor"] == {"sensor": "ideal"} and "camera" not in paper.extra["task"]
    with pytest.raises(InvalidInputError, match=r"sensor = 'd435' is not allowed: none for the "
                       r"paper-sim scene: it renders through its own camera"):
        CollectSettings("paper-sim", "single", 1, sensor=SensorKind.D435)


def test_approach_images_keep_the_pick_label_and_mask_the_arm_coming_in(tmp_path):
    """``approach_hz``: each approach adds images labelled as the pick's image, the arm masked
    out of them as a closed-loop trial's re-predictions have it (issue 36)."""
    path = tmp_path / "approach.gva"
    dataset = collect(CollectSettings("yumi", "single", 2, approach_hz=5.0,
                                      sensor=SensorKind.IDEAL), path, progress=False)
    stages = [record.get("stage", "pick") for record in dataset.scenes]
    assert stages.count("pick") == 2 and stages.count("approach") >= 6  # > 0.6 s an approach
    assert dataset.metadata.extra["approach_hz"] == 5.0
    assert dataset.metadata.extra[APPROACH_MASKED_KEY] is True
    last = len(stages) - 1  # an approach image: the arm in view, no depth and one colour on it
    assert stages[last] == "approach" and dataset.depths_m is not None
    arm = dataset.depths_m[last] == 0.0
    assert arm.sum() > 100
    colours = np.unique(dataset.images[last][arm].reshape(-1, 3), axis=0)
    assert len(colours) == 1
    camera = ModelSpec.from_metadata(dataset.metadata).camera
    shares = [hidden_share(RgbdFrame(dataset.images[i], dataset.depths_m[i], camera,
                                     robot_mask=dataset.depths_m[i] == 0.0),  # the ideal camera's
                           dataset.labels[i, 0, :3], 0.045)
              for i, stage in enumerate(stages) if stage == "approach"]
    assert max(shares) <= APPROACH_HIDDEN_SHARE_MAX  # at least half of each footprint seen,
    assert max(shares) > 0.0  # some of it hidden by the hand coming in (issue 66)
    picks = [i for i, stage in enumerate(stages) if stage == "pick"]
    for start, end in zip(picks, [*picks[1:], len(stages)], strict=True):
        np.testing.assert_allclose(dataset.labels[start:end], np.broadcast_to(
            dataset.labels[start], dataset.labels[start:end].shape),
                                   atol=1e-4)  # the demonstration's target does not move
        moved = np.abs(dataset.joint_positions[end - 1] - dataset.joint_positions[start])
        assert moved.max() > 0.3  # the last approach image has the arm well on its way
        assert not np.array_equal(dataset.images[end - 1], dataset.images[start])
    with pytest.raises(InvalidInputError, match=r"approach_hz = 5.0 is not allowed: None for "
                                                 r"the paper-sim scene"):
        CollectSettings("paper-sim", "single", 2, approach_hz=5.0)
    with pytest.raises(InvalidInputError, match=r"replan_hz = -1.0 is not allowed"):
        CollectSettings("yumi", "single", 2, approach_hz=-1.0)


def test_approach_images_hiding_more_of_a_target_are_left_out_and_counted(tmp_path, monkeypatch):
    """An approach image in which the arm hides more of a target's footprint than the share a
    demonstration keeps is left out and counted; at issue 36's share (none hidden) the same two
    demonstrations leave some out and keep fewer images than at today's."""
    settings = CollectSettings("yumi", "single", 2, approach_hz=5.0, sensor=SensorKind.IDEAL)
    today = collect(settings, tmp_path / "today.gva", progress=False)
    monkeypatch.setattr(collector, "APPROACH_HIDDEN_SHARE_MAX", 0.0)
    strict = collect(settings, tmp_path / "strict.gva", progress=False)
    assert strict.metadata.extra["approach_images_hidden"] > 0
    assert strict.metadata.extra[HIDDEN_SHARE_KEY] == 0.0
    assert len(strict) + strict.metadata.extra["approach_images_hidden"] == \
        len(today) + today.metadata.extra["approach_images_hidden"]  # the same looks, kept or not
