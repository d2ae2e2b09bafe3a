"""The GIFs of ``gva reproduce real``: a model's first trials recorded again, frame by frame.

Trial ``i`` is scene ``i`` of the TEST stream, run in a fresh
:class:`~sim.trials.trial_runner.TrialRunner` in the same order as the trial run did, so a
recorded trial replays the logged one (the simulation is deterministic, and recording only
renders). Each frame shows the head camera's
image with the model's attention points (numbered by head) beside a camera watching the robot
(:mod:`sim.trials.gif_recorder`); the last frame of each trial names its outcome.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from harness.inputs.trial_settings import TrialSettings, load_trial_model
from perception.interface import ConditionKind
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.trials.gif_recorder import TrialRecorder, join_trials, write_gif
from sim.trials.trial_models import torch_threads
from sim.trials.trial_runner import TrialRunner
from sim.world.lighting import Lighting


def record_gif(model_name: str, trials: TrialSettings, count: int, path: Path
               ) -> list[dict[str, Any]]:
    """Records trials ``0 .. count - 1`` of ``trials`` into the GIF ``path``; what each did.

    Returns:
        Per trial: ``index``, ``outcome``, ``reason`` and the target's ``position_error_m``.

    """
    model = load_trial_model(trials)
    task = trials.task_spec
    lighting = Lighting(brightness=task.brightness)  # the camera's light, dimmed
    recorder = TrialRecorder(lighting=lighting)
    recorded: list[list[Any]] = []
    shown: list[dict[str, Any]] = []
    with torch_threads(1), TrialRunner(task, model.factory, trials.settle_s, trials.execution,
                                       observer=recorder, obstacles=trials.obstacles,
                                       loop=trials.loop, robot=trials.description()) as runner:
        for index in range(count):
            scene = sample_scene(task, YUMI_SCENE, trials.seed, SeedStream.TEST, index)
            given = scene.given
            asked = f': "{given.value}"' if given.kind is ConditionKind.TEXT else (
                " (picture: top right)" if given.kind is ConditionKind.IMAGE else "")
            recorder.start(f"{model_name} / {task.name}, trial {index}{asked}", given.picture)
            record = runner.run(scene, index, trials.seed, trials.model)
            recorded.append(recorder.finish(record.outcome.value))
            shown.append({"index": index, "outcome": record.outcome.value,
                          "reason": record.reason,
                          "position_error_m": record.position_error_m})
    write_gif(path, *join_trials(recorded))
    return shown
