"""What a collection makes of a scene's images: samples, each asked and labelled.

Shared by the demonstrations (:mod:`harness.inputs.collector`) and the scenes labelled by the
catalog (:mod:`sim.trials.scene_sets.catalog_labels`), so a sample means the same in both: the
image before each pick with every target's label (a target already taken keeps its last one and
is listed under ``"taken"``), then, with every condition asked, the first image once per other
condition value, labelled with the object that value names.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from sim.tasks.scene_sampling import Scene
from sim.tasks.task_spec import TaskSpec
from sim.trials.pick_images import PickImages, calibration_record


@dataclass(frozen=True)
class Sample:
    """One sample as collected: the image, what the model is asked, the labels, the record.

    ``depth_m`` and ``joint_positions`` are the RGB-D frame's depth and the robot's joints when
    the image was taken (the yumi scene; the paper's scene has neither).
    """

    image: np.ndarray  # (H, W, 3) uint8
    condition: np.ndarray  # (C,)
    labels: np.ndarray  # (q, D)
    scene: dict[str, Any]
    depth_m: np.ndarray | None = None  # (H, W)
    joint_positions: np.ndarray | None = None  # (J,)


class Collected(NamedTuple):
    """A collection's samples, its camera record and the metadata's ``extra`` it adds."""

    samples: list[Sample]
    camera: dict[str, Any]
    extra: dict[str, Any]


def asked(task: TaskSpec, scene: Scene, every_condition: bool) -> tuple[Scene, ...]:
    """The scene as drawn, then (with ``every_condition``) under each other value it can be."""
    others = [value for value in scene.askable() if value != scene.condition.value]
    return (scene,) + (tuple(scene.asking(value, task) for value in others)
                       if every_condition else ())


def scene_samples(task: TaskSpec, scene: Scene, bodies: list[int], images: PickImages,
                  every_condition: bool, approach: bool = False) -> list[Sample]:
    """The samples of one scene whose images ``images`` watched (its bodies: ``bodies``).

    ``approach``: keep the images taken along each approach too (``"stage": "approach"``).
    """
    runner = images.runner
    record = scene.to_record() | calibration_record(images.stages[0].frame, runner)
    samples = [Sample(stage.frame.rgb, scene.given.vector(), stage.labels,
                      record | ({"taken": stage.taken} if stage.taken else {})
                      | ({"stage": "approach"} if stage.approach else {}),
                      stage.frame.depth_m, stage.joint_positions)
               for stage in images.stages if approach or not stage.approach]
    first = images.stages[0]
    return samples + [Sample(first.frame.rgb, question.given.vector(),
                             np.stack([images.first[bodies[t]] for t in question.targets]),
                             question.to_record() | calibration_record(first.frame, runner),
                             first.frame.depth_m, first.joint_positions)
                      for question in asked(task, scene, every_condition)[1:]]
