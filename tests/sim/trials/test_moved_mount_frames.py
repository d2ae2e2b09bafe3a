"""A moved camera mount: the trial's frames carry that mount's calibration, and a dataset keeps it.

What a model reads positions through (issue 74, its first step): a trial hands the frame the
camera it was rendered from, and a demonstration under a look that moves the camera records that
calibration per sample, so ``gva evaluate`` reads the sample as the trial read its frame.
"""

from __future__ import annotations

import numpy as np

from perception.camera import PinholeCamera
from perception.interface import NO_CONDITION, LabelKind, PerceptionModel
from robots.yumi import YUMI
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.trials.collector import CollectSettings, collect
from sim.trials.oracle import OraclePerception
from sim.trials.trial_runner import TrialRunner


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
