"""What a demonstration keeps of its picks: the image before each, with every target's label.

The collector (:mod:`harness.inputs.collector`) watches each demonstration through
:class:`PickImages`, a trial observer, and turns its :class:`Stage` list into dataset samples;
:func:`calibration_record` is what a sample records of the camera where a look moved it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from perception.camera import RgbdFrame
from perception.interface import Prediction
from perception.labels import label_vector
from perception.learning.data import SAMPLE_CAMERA_KEY
from sim.trials.closed_loop.view import hidden_share
from sim.trials.trial_runner import TrialRunner
from sim.world.yumi_world import World


@dataclass(frozen=True)
class Stage:
    """A demonstration's image before one pick: the frame, the joints, every target's label."""

    frame: RgbdFrame
    joint_positions: np.ndarray  # (J,) in the robot's joint order
    labels: np.ndarray  # (q, 12)
    taken: list[int]  # the targets already picked
    approach: bool = False  # taken during the pick's approach (the arm in view)


class PickImages:
    """Watches a demonstration: the image before each pick, every target's label just then.

    A :class:`~sim.trials.runner_hooks.TrialObserver`; ``saw`` comes after the image is taken
    and before the plan, so the world is as the image shows it. A target already set aside keeps
    the label it had when it was last on the table. An approach image in which the arm hides
    more than ``hidden_share_max`` of a target's footprint (``LoopSettings.footprint_radius_m``;
    the collector's :data:`~harness.inputs.collector.APPROACH_HIDDEN_SHARE_MAX`) is left out
    (counted): a label the image cannot show teaches the model to guess.
    """

    def __init__(self, runner: TrialRunner, hidden_share_max: float) -> None:
        self.runner = runner
        self.hidden_share_max = hidden_share_max
        self.joint_names = tuple(runner.world.robot.joint_names)
        self.footprint_radius_m = runner.loop.footprint_radius_m
        self.hidden = 0  # approach images left out: the arm hid a target's footprint
        self.start([])

    def start(self, targets: list[int]) -> None:
        """Watches a new demonstration whose targets are these bodies, in target order."""
        self.targets = targets
        self.labels: dict[int, np.ndarray] = {}
        self.stages: list[Stage] = []
        self.first: dict[int, np.ndarray] = {}  # every object's label in the first image

    def saw(self, frame: RgbdFrame, prediction: Prediction | None) -> None:
        """Keeps the frame and the joints with every target's label and the targets taken."""
        on_table = {body: label_vector(*self.runner.truth(body))
                    for body in self.runner.world.objects}
        if not self.stages:
            self.first = on_table
        self.labels |= {k: on_table[body] for k, body in enumerate(self.targets)
                        if body in on_table}
        taken = [k for k, body in enumerate(self.targets) if body not in on_table]
        labels = np.stack([self.labels[k] for k in range(len(self.targets))])  # (q, 12)
        joints = self.runner.world.robot.joint_positions(self.joint_names)
        approach = bool(self.stages) and self.stages[-1].taken == taken  # the same pick's
        if approach and any(hidden_share(frame, on_table[body][:3], self.footprint_radius_m)
                            > self.hidden_share_max
                            for body in self.targets if body in on_table):
            self.hidden += 1  # a target the arm hides: the loop would not heed it, nor learn it
            return
        self.stages.append(Stage(frame, np.array([joints[n] for n in self.joint_names]), labels,
                                 taken, approach))

    def stepped(self, world: World) -> None:
        """Nothing to watch between images."""


def calibration_record(frame: RgbdFrame, runner: TrialRunner) -> dict[str, Any]:
    """A sample record's own calibration, where its frame's is not the dataset's camera.

    A look that moves the camera for a scene: the sample is read through that calibration, as
    a trial reads its frame's (:data:`~perception.learning.data.SAMPLE_CAMERA_KEY`).
    """
    if frame.camera == runner.mounted_camera.pinhole:
        return {}
    return {SAMPLE_CAMERA_KEY: frame.camera.to_json()}
