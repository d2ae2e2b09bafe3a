"""What a :class:`~sim.trials.trial_runner.TrialRunner` is given, and whom it tells.

Its model comes from a :data:`ModelFactory` (the oracle reads the runner's world; a learned
model ignores it), and is given :data:`TRIAL_INPUTS` with each prediction; a
:class:`TrialObserver` (e.g. :mod:`sim.trials.gif_recorder`) watches what it sees and every
physics step, and never changes them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

from perception.camera import RgbdFrame
from perception.interface import ModelInput, PerceptionModel, Prediction
from sim.world.head_camera import HeadCamera
from sim.world.yumi_world import World


class TrialObserver(Protocol):
    """Watches trials as they run, e.g. to record them (:mod:`sim.trials.gif_recorder`).

    Watching must not change what happens: an observer reads the world, never moves it.
    """

    def saw(self, frame: RgbdFrame, prediction: Prediction | None) -> None:
        """The RGB-D frame a pick's prediction was made from, and the prediction.

        None: the model gave nothing the robot can act on (it raised, or its prediction was
        refused); the pick ends ``perception_failed``, and the image is still what it saw.
        """

    def stepped(self, world: World) -> None:
        """Called after every physics step of the runner's world."""


TRIAL_INPUTS = frozenset(ModelInput)
"""What a trial gives each prediction: the head camera's RGB, depth and calibration."""

ModelFactory = Callable[[World, HeadCamera], PerceptionModel]
"""Builds a trial's perception model from the runner's world and head camera: the oracle reads
the world; any other model ignores both (e.g. ``lambda world, camera: model``)."""
