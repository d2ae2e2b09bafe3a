"""A trial renders its scene's look: the camera where the mount puts it, the table, the lamp.

What a model reads positions through (issue 74, its first step): a trial hands the frame the
camera it was rendered from, and a demonstration under a look that moves the camera records that
calibration per sample, so ``gva evaluate`` reads the sample as the trial read its frame. And
what it sees (issue 79): each look checked in the pixels of the first frame a model is given,
against the plain task's same scene (the same frame seed: the sensor's noise alike), changed
where the look acts and only there.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import pytest
import torch
from scipy.ndimage import binary_erosion, label

from harness.inputs.collector import CollectSettings, collect
from perception.camera import PinholeCamera, RgbdFrame
from perception.interface import NO_CONDITION, LabelKind, PerceptionModel
from perception.models.rise import rise_above_table
from robots.yumi import YUMI
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.variants import load_task_variant
from sim.trials.oracle import OraclePerception
from sim.trials.trial_runner import TrialRunner
from sim.world.head_camera import HeadCamera, camera_config
from sim.world.looks import moved_camera


def test_a_moved_mount_is_the_frames_calibration_in_a_trial_and_in_its_demonstration(tmp_path):
    settings = CollectSettings("yumi", "single", 1, seed=0, variant="mount")
    dataset = collect(settings, tmp_path / "d.gva", progress=False)
    nominal = PinholeCamera.from_record(dataset.metadata.camera)
    kept = dataset.camera(0)
    assert nominal is not None and kept is not None and kept != nominal
    offset_m = np.linalg.norm(np.subtract(kept.position_m, nominal.position_m))
    assert 0.001 < offset_m <= np.sqrt(3) * 0.015  # the variant's mount: up to 15 mm per axis
    seen: list[PinholeCamera] = []

    class Looks(PerceptionModel):  # the oracle's picks, keeping each frame's calibration
        name, label_kind = "looks", LabelKind.GRASP_POSE

        def __init__(self, inner):
            self.inner = inner

        def predict_frame(self, frame, condition=NO_CONDITION):
            seen.append(frame.camera)
            return self.inner.predict(frame.rgb, condition)

    task = settings.task_spec
    scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TRAIN, 0)  # the dataset's first
    with TrialRunner(task, robot=YUMI) as runner:
        runner.model = Looks(OraclePerception(runner.world, runner.camera))
        record = runner.run(scene, 0, 0, "looks")
        assert runner.camera.pinhole == seen[0]  # rendered from where it says it is
    assert record.outcome.value == "success", record.reason
    assert seen and all(camera == kept for camera in seen)
    clean = collect(CollectSettings("yumi", "single", 1, seed=0), tmp_path / "c.gva",
                    progress=False)
    assert "camera" not in clean.scenes[0]  # a still mount: the dataset's camera, as before
    assert clean.camera(0) == nominal


class Seen(NamedTuple):
    frame: RgbdFrame  # the first frame a trial's model is given
    look: Any  # the scene's SceneLook (None: the plain task's)
    camera: HeadCamera  # the camera the runner holds
    target_m: np.ndarray  # the target's grasp point, the referee's truth


def _first_frame(variant: str | None) -> Seen:
    """What a trial sees first on scene 0 of ``single`` under ``variant``."""
    task = load_task_variant("single", variant)
    scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, 0)
    with TrialRunner(task, robot=YUMI) as runner:
        body = runner.setup(scene)[scene.targets[0]]
        sighting = runner.sight(body)
        return Seen(sighting.frame, scene.look, runner.camera, sighting.truth.position)


def _target_centre_px(frame: RgbdFrame, near_px: np.ndarray) -> np.ndarray:
    """The centre (u, v) of the object standing up nearest ``near_px`` in ``frame``'s depth."""
    rise = rise_above_table(torch.from_numpy(frame.depth_m)[None])[0].numpy()
    parts, count = label(rise > 0.01)
    centres = [np.argwhere(parts == k + 1).mean(axis=0)[::-1] for k in range(count)]
    return min(centres, key=lambda c: float(np.linalg.norm(c - near_px)))


@pytest.fixture(scope="module")
def plain() -> RgbdFrame:
    return _first_frame(None).frame


def test_a_moved_mount_renders_from_where_the_look_put_it(plain):
    # a trial that ignored look.mount rendered the plain view and labelled it moved, or the
    # reverse: the camera held, the calibration handed over and the pixels must all move
    seen = _first_frame("mount")
    frame, moved = seen.frame, moved_camera(camera_config(YUMI), seen.look.mount)
    assert seen.camera.config == moved and frame.camera == seen.camera.pinhole
    assert frame.camera != plain.camera
    # the pixels agree with the calibration handed over, and not with the plain one
    said = frame.camera.project(seen.target_m[None])[0]
    old = plain.camera.project(seen.target_m[None])[0]
    moved_px = _target_centre_px(frame, said) - _target_centre_px(plain, old)
    assert np.linalg.norm(said - old) > 2.0  # this scene's draw moves the target ~1 cm
    assert np.linalg.norm(moved_px - (said - old)) < 0.5, (moved_px, said - old)


def test_another_table_changes_the_table_and_not_the_objects(plain):
    frame, look = _first_frame("table")[:2]
    assert look.table is not None and frame.camera == plain.camera
    rise = rise_above_table(torch.from_numpy(plain.depth_m)[None])[0].numpy()
    on_objects = binary_erosion(rise > 0.02, iterations=3)  # well inside what stands up
    on_table = binary_erosion(np.abs(rise) < 0.003, iterations=3) & (plain.depth_m > 0)
    assert on_objects.sum() > 30 and on_table.mean() > 0.2
    differs = np.abs(frame.rgb.astype(int) - plain.rgb.astype(int)).max(axis=-1) > 12
    assert differs[on_table].mean() > 0.8  # the table's finish, nearly everywhere
    assert differs[on_objects].mean() < 0.1  # the objects as they were


def test_another_lamp_lights_the_whole_frame_otherwise(plain):
    frame, look = _first_frame("light")[:2]
    assert look.light is not None and frame.camera == plain.camera
    shift = np.abs(frame.rgb.astype(float).mean(axis=(0, 1)) - plain.rgb.astype(float).mean(
        axis=(0, 1)))  # per channel: a lamp's brightness and colour temperature
    assert shift.max() > 5.0, shift
    assert np.array_equal(frame.depth_m, plain.depth_m)  # light moves no surface
