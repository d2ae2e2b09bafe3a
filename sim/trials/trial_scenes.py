"""Which scene each trial of a run runs.

Trial ``i`` of a run with seed ``s`` runs test scene ``i`` of seed ``s`` (see
:mod:`sim.tasks.scene_sampling`), so the same seed gives the same trials, and no trial runs on a
scene a model was trained on.
"""

from __future__ import annotations

from sim.tasks.scene_sampling import Scene, SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_spec import TaskSpec


def trial_scene(task: TaskSpec, seed: int, index: int) -> Scene:
    """Trial ``index``'s scene: test scene ``index`` of the run's seed."""
    return sample_scene(task, YUMI_SCENE, seed, SeedStream.TEST, index)
