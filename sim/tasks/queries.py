"""What the model is given for a scene's condition: the name itself, a sentence or a picture.

A scene's :class:`~perception.interface.Condition` names its target ("mug", "left"): the
referee judges by it. A task given as text or as a picture hands the model something else for
it: a sentence drawn from the task's phrasings of that target (training phrasings for training
scenes, test phrasings for test scenes and trials), or a picture of an object of that type
taken in a picture scene of its own (:mod:`sim.world.pictures`: training pictures for training
scenes, test pictures for test scenes and trials). The draw has its own seed stream beside the
scene's (``SeedSequence([seed, stream, index, 2, choice])``), so a text or image task presents
exactly the scenes of its one-hot twin, and each condition value of a scene gets its own
sentence or picture.
"""

from __future__ import annotations

import numpy as np

from perception.interface import Condition, ConditionKind
from sim.tasks.task_spec import ConditionForm, TaskSpec
from sim.world.pictures import PICTURES_PER_SPLIT, render_picture

QUERY_STREAM = 2
"""The sentence's (or picture's) seed stream, beside the scene's and the distractors' (1)."""
SPLITS = {0: "train", 1: "test"}
"""Which phrasings (and pictures) a seed stream draws from: training scenes the training ones."""


def query_for(task: TaskSpec, scene: str, condition: Condition, seed: int, stream: int,
              index: int) -> Condition | None:
    """What the model is given for ``condition`` in ``scene``'s scene ``index``; None: itself.

    Raises:
        InvalidInputError: (from the task's check) a target has no phrasing in the split.

    """
    if task.given_as is ConditionForm.ONE_HOT or condition.kind is ConditionKind.NONE:
        return None
    assert condition.value is not None  # a one-hot condition names its value
    choice = condition.choices.index(condition.value)
    rng = np.random.default_rng(np.random.SeedSequence([seed, int(stream), index, QUERY_STREAM,
                                                        choice]))
    split = SPLITS[int(stream)]
    if task.given_as is ConditionForm.TEXT:
        assert task.phrasings is not None  # TaskSpec: text tasks have phrasings
        phrasings = task.phrasings.of(split, condition.value)
        return Condition(ConditionKind.TEXT, phrasings[int(rng.integers(len(phrasings)))])
    number = int(rng.integers(PICTURES_PER_SPLIT))
    return Condition(ConditionKind.IMAGE,
                     picture=render_picture(scene, condition.value, split, number))
