"""Whether a task's demonstrations stay true when mirrored across the world's xz-plane.

A learner may train on each demonstration's mirror image as well (y -> -y; see
:mod:`perception.learning.mirror`) only if the mirrored image shows a scene the task could
have drawn and its mirrored labels are that scene's labels. The simulator knows what that
takes, so the collector records the answer in a dataset (``metadata.extra["mirror_symmetric"]``):

* the camera sits on the xz-plane looking along it, with z up (the yumi head camera);
* every object the task may present is its own mirror image (the catalog's are);
* the workspace is symmetric about y = 0, so mirrored positions are positions of the task;
* the targets' order does not follow their y: a task's targets are all its objects only when
  they are one of each type (ordered by type), else there is one target; a side condition
  swaps (the learner swaps it too).

The grasp labels follow: the canonical grasp (:func:`perception.objects.grasps.grasp_pose`) of
a mirrored object is the mirror of the canonical grasp, up to the gripper's half turn.
"""

from __future__ import annotations

import numpy as np

from perception.objects.catalog import ObjectSpec, PrimitiveKind, get_object_spec
from sim.tasks.scene_specs import SceneSpec
from sim.tasks.task_in_scene import target_count
from sim.tasks.task_spec import ObjectChoice, TaskSpec
from sim.world.head_camera import CameraConfig

TOLERANCE = 1e-9
MIRROR_Y = np.diag([1.0, -1.0, 1.0])


def object_is_mirror_symmetric(spec: ObjectSpec) -> bool:
    """Whether every primitive's mirror image across the object's xz-plane is one of them."""
    def same(a: np.ndarray, b: np.ndarray, kind: PrimitiveKind) -> bool:
        # a box is its own image under any flip of its axes, a cylinder under a turn about z
        columns = range(3) if kind is PrimitiveKind.BOX else (2,)
        return all(abs(abs(float(a[:, i] @ b[:, i])) - 1.0) < 1e-6 for i in columns)

    for primitive in spec.primitives:
        pose = primitive.pose
        position = MIRROR_Y @ pose.position
        rotation = MIRROR_Y @ pose.rotation @ MIRROR_Y
        if not any(other.kind is primitive.kind and other.size_m == primitive.size_m
                   and other.rgba == primitive.rgba
                   and np.allclose(other.pose.position, position, atol=TOLERANCE)
                   and same(other.pose.rotation, rotation, primitive.kind)
                   for other in spec.primitives):
            return False
    return True


def mirror_symmetric(task: TaskSpec, scene: SceneSpec, camera: CameraConfig) -> bool:
    """Whether ``task``'s demonstrations in ``scene`` seen by ``camera`` may be mirrored."""
    on_plane = all(abs(v[1]) < TOLERANCE for v in (camera.position_m, camera.target_m,
                                                    camera.up))
    y_low, y_high = task.workspace_y_m or scene.workspace_y_m
    types = set(scene.object_types) | set(task.distractors)
    ordered_by_type = target_count(task) == 1 or task.objects is ObjectChoice.ONE_OF_EACH
    # A one-hot side is swapped with the image; a sentence by what it names, by a model that
    # trains each sentence as its named side's row (kqv); one reading the embedding does not.
    return (on_plane and abs(y_low + y_high) < TOLERANCE
            and ordered_by_type
            and all(object_is_mirror_symmetric(get_object_spec(t)) for t in types))
