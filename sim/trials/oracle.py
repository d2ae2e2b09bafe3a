"""The oracle: a perception model that reads the simulator's true object poses.

It is the one part of a trial that acts on the simulator's truth, and the only model that may:
it answers through the same ``predict(image, condition)`` interface learned models use, so the
trial runner cannot tell them apart, and the plan that follows sees only its prediction and the
camera. It sets the ceiling a learned model is measured against and produces the expert
demonstrations.
"""

from __future__ import annotations

import numpy as np

from perception.interface import (
    NO_CONDITION,
    Condition,
    ConditionKind,
    LabelKind,
    PerceptionModel,
    Prediction,
    Target,
    check_image,
)
from perception.objects.catalog import OBJECT_TYPES
from perception.objects.grasps import grasp_pose
from sim.errors import TargetNotFoundError
from sim.world.head_camera import HeadCamera
from sim.world.yumi_world import World


class OraclePerception(PerceptionModel):
    """Grasp poses from the true object poses of a :class:`World`.

    Targets follow the condition: none -> every object, in catalog order of their types (then
    from the robot's right to its left); object type -> the object of that type; side -> the
    leftmost (+y) or rightmost (-y) object. Attention points are the projected object centres.

    ``candidates``, when set, limits the targets to those bodies (a scene's distractors are
    presented but never targets); objects taken off the table drop out by themselves.
    ``named``, when set, is what the scene's condition names: asked by a sentence or a
    picture, the oracle reads the target from it, as it reads the poses, from the truth.
    The trial runner sets both per scene.
    """

    name = "oracle"
    label_kind = LabelKind.GRASP_POSE
    sees_through_the_arm = True
    """A closed loop takes its re-predictions whatever the head camera shows (the truth needs no
    view): its bar measures the controller's ceiling. :class:`ViewLimitedOracle` is held."""

    def __init__(self, world: World, camera: HeadCamera) -> None:
        self.world = world
        self.camera = camera
        self.candidates: tuple[int, ...] | None = None
        self.named: Condition | None = None

    def predict(self, image: np.ndarray, condition: Condition = NO_CONDITION) -> Prediction:
        """The canonical grasp of each target; the image is checked but not needed."""
        check_image(image)
        if condition.kind in (ConditionKind.TEXT, ConditionKind.IMAGE):
            if self.named is None:
                raise TargetNotFoundError(f"the oracle reads a {condition.kind.value} condition "
                                          "through what its scene names, and none was set")
            condition = self.named
        bodies = self._targets(condition)
        targets, centres = [], []
        for body in bodies:
            spec = self.world.object_spec(body)
            pose = self.world.object_pose(body)
            grasp = grasp_pose(spec, pose)
            targets.append(Target(grasp.position.copy(), grasp.rotation.copy(), spec.name))
            centres.append(pose.position + pose.rotation @ np.array([0.0, 0.0, spec.height_m / 2]))
        attention = self.camera.project(np.array(centres)) if centres else np.zeros((0, 2))
        return Prediction(targets=tuple(targets), attention_px=attention)

    def _targets(self, condition: Condition) -> list[int]:
        objects = {b: s for b, s in self.world.objects.items()
                   if self.candidates is None or b in self.candidates}
        present = ", ".join(sorted(spec.name for spec in objects.values())) or "nothing"
        if condition.kind is ConditionKind.NONE:
            def order(body: int) -> tuple[int, float]:
                y = float(self.world.object_pose(body).position[1])
                return OBJECT_TYPES.index(objects[body].name), y

            return sorted(objects, key=order)
        if condition.kind is ConditionKind.OBJECT_TYPE:
            matches = [b for b, spec in objects.items() if spec.name == condition.value]
            if not matches:
                raise TargetNotFoundError(
                    f"condition object_type = {condition.value!r} names no object in the scene "
                    f"(present: {present})"
                )
            return matches[:1]
        if not objects:
            raise TargetNotFoundError(f"condition side = {condition.value!r}: the table is empty")
        by_y = sorted(objects, key=lambda b: float(self.world.object_pose(b).position[1]))
        return [by_y[-1] if condition.value == "left" else by_y[0]]


class ViewLimitedOracle(OraclePerception):
    """The oracle held to the closed loop's view rule, as a learned model is (issue 66).

    Each re-prediction is the truth, but the loop heeds it only where the head camera could show
    it (the followed grasp's footprint unhidden, or the new grasp in plain view at two looks in a
    row: :func:`sim.trials.closed_loop.view.unheeded_reason`): what a perfect perceiver behind
    the same camera can pick, the reference for a learned model's closed-loop counts.
    """

    name = "oracle-view"
    sees_through_the_arm = False
