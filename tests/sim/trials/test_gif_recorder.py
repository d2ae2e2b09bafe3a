"""Recording trials: the runner's observer hook, the frames, the GIF file."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from PIL import Image
from user_models import NotARotation, Raises

from perception.interface import LabelKind, PerceptionModel, Prediction, Target
from robots.yumi import YUMI
from sim.errors import InvalidInputError
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task
from sim.trials.gif_recorder import (
    CAPTION_PX,
    RecordingSettings,
    TrialRecorder,
    join_trials,
    write_gif,
)
from sim.trials.trial_runner import TrialRunner


class CountingRecorder(TrialRecorder):
    """A recorder that also counts the hook's calls."""

    def __init__(self) -> None:
        super().__init__(RecordingSettings(frame_every_s=0.2, max_frames=12))
        self.steps = 0
        self.predictions = 0

    def saw(self, frame, prediction) -> None:
        self.predictions += 1
        super().saw(frame, prediction)

    def stepped(self, world) -> None:
        self.steps += 1
        super().stepped(world)


def _comparable(record):
    return (record.outcome, record.reason, record.lift_m, record.predicted, record.sim_time_s,
            record.arm, record.position_error_m)


def test_recording_a_trial_calls_the_hook_and_changes_nothing():
    task = load_task("single")
    scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, 1)
    with TrialRunner(task, robot=YUMI) as runner:
        plain = runner.run(scene, 1, 0, "oracle")
    recorder = CountingRecorder()
    with TrialRunner(task, observer=recorder, robot=YUMI) as runner:
        recorder.start("oracle / single, trial 1")
        recorded = runner.run(scene, 1, 0, "oracle")
        time_step_s = runner.world.config.time_step_s
        frames = recorder.finish(recorded.outcome.value)
    assert _comparable(recorded) == _comparable(plain)
    assert recorded.success  # the oracle picks it
    assert recorder.steps == round(recorded.sim_time_s / time_step_s)  # every physics step
    assert recorder.predictions == 1
    assert 2 <= len(frames) <= 12  # a 4-5 s trial at 5 frames/s, thinned to 12
    assert all(f.shape == (CAPTION_PX + 128, 256, 3) and f.dtype == np.uint8 for f in frames)
    assert not np.array_equal(frames[0][CAPTION_PX:, 128:], frames[-1][CAPTION_PX:, 128:])
    assert not np.array_equal(frames[-2][:CAPTION_PX], frames[-1][:CAPTION_PX])  # the outcome


def test_a_trial_refused_before_the_robot_moves_still_gets_a_frame():
    task = load_task("single")
    scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, 0)
    recorder = TrialRecorder()
    with TrialRunner(task, observer=recorder, robot=YUMI) as runner:
        oracle = runner.model

        class FarAway(PerceptionModel):  # a grasp 80 cm beyond the target: no arm reaches it
            name = "far"
            label_kind = LabelKind.GRASP_POSE

            def predict(self, image, condition):
                (target,) = oracle.predict(image, condition).targets
                return Prediction((Target(target.position_m + np.array([0.8, 0.0, 0.0]),
                                          target.rotation),))

        runner.model = FarAway()
        recorder.start("far / single, trial 0")
        record = runner.run(scene, 0, 0, "far")
        frames = recorder.finish(record.outcome.value)
    assert record.outcome.value == "ik_unreachable"
    assert len(frames) == 1 and frames[0].shape == (CAPTION_PX + 128, 256, 3)


@pytest.mark.parametrize("model", [Raises(), NotARotation()], ids=["raises", "refused"])
def test_a_trial_that_fails_in_perception_still_shows_what_the_model_saw(model):
    """An untrained model's first prediction may be refused: its GIF still gets its frame."""
    task = load_task("single")
    scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, 0)
    recorder = CountingRecorder()
    with TrialRunner(task, lambda world, camera: model, observer=recorder, robot=YUMI) as runner:
        recorder.start("misbehaving / single, trial 0")
        record = runner.run(scene, 0, 0, "misbehaving")
        frames = recorder.finish(record.outcome.value)
    assert record.outcome.value == "perception_failed"
    assert recorder.predictions == 1
    assert len(frames) == 1 and frames[0].shape == (CAPTION_PX + 128, 256, 3)


def test_a_runner_without_an_observer_leaves_the_world_unhooked():
    with TrialRunner(load_task("single"), robot=YUMI) as runner:
        assert runner.observer is None and runner.world.step_hook is None


def test_trials_join_into_one_looping_gif(tmp_path):
    rng = np.random.default_rng(0)
    trials = [[rng.integers(0, 255, (20, 30, 3), dtype=np.uint8) for _ in range(k)]
              for k in (3, 2)]
    frames, durations = join_trials(trials, frame_ms=100, last_ms=900)
    assert durations == [100, 100, 900, 100, 900]
    path = write_gif(tmp_path / "gifs" / "t.gif", frames, durations)
    assert path.read_bytes()[:6] == b"GIF89a"
    with Image.open(path) as image:
        assert image.n_frames == 5 and image.size == (30, 20) and image.info["loop"] == 0
    with pytest.raises(InvalidInputError, match="one duration per frame"):
        write_gif(tmp_path / "bad.gif", frames, durations[:-1])
    with pytest.raises(InvalidInputError, match="max_frames"):
        RecordingSettings(max_frames=1)


def test_a_closed_loop_gif_shows_the_grasp_follow_the_moved_target():
    """Each re-prediction replaces the panel: its white grasp dot lands on the moved target."""
    from sim.tasks.disturbance import Disturbance
    from sim.trials.closed_loop.loop_settings import Loop, LoopSettings

    task = dataclasses.replace(load_task("single"), name="single-moved",
                               disturbance=Disturbance(move_m=(0.06, 0.06)))
    scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, 0)
    recorder = CountingRecorder()
    with TrialRunner(task, observer=recorder, loop=LoopSettings(Loop.CLOSED), robot=YUMI) as runner:
        recorder.start("oracle / single-moved, trial 0")
        record = runner.run(scene, 0, 0, "oracle")
        frames = recorder.finish(record.outcome.value)
    assert record.success, record.reason
    assert recorder.predictions == 1 + len(record.picks[0]["repredictions"])

    def white_dot(frame):  # the centre of the panel's pure-white pixels
        v, u = np.nonzero(np.all(frame[CAPTION_PX:, :128] == 255, axis=-1))
        return np.array([u.mean(), v.mean()])

    moved = np.linalg.norm(white_dot(frames[-1]) - white_dot(frames[0]))
    assert moved > 5  # px: 6 cm on the table is about 20 px in the 128 px image
