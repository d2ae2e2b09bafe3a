"""The two scenes of the paper's experiments, as the tasks and the data collector see them.

| | ``paper-sim`` (Table II) | ``yumi`` (Table III) |
|---|---|---|
| objects | duck, soccer ball, mug (pybullet_data, ~10 cm) | sponge, spray bottle, mug |
| distractors only | none | a wooden block, clutter (drink can, notebook, ...), look-alikes |
| camera | at the table centre from 50 cm | the YuMi's head camera |
| label per target | the object's position (x, y, z) [m] | the TCP pose that picks it |

The simulators themselves are :class:`sim.world.paper_world.PaperWorld` and
:class:`sim.world.yumi_world.World`.
"""

from __future__ import annotations

from dataclasses import dataclass

from perception.interface import LabelKind
from perception.objects.catalog import (
    CLUTTER_TYPES,
    DISTRACTOR_TYPES,
    LOOK_ALIKE_TYPES,
    OBJECT_TYPES,
)
from robots.description import RobotDescription
from sim.errors import InvalidInputError
from sim.world.head_camera import CameraConfig, camera_config


@dataclass(frozen=True)
class SceneSpec:
    """What a scene offers a task.

    Args:
        name: ``paper-sim`` or ``yumi``.
        object_types: The scene's object types, in one-hot (and target) order.
        distractor_types: Further types a task may present as distractors only.
        workspace_x_m, workspace_y_m: Where object centres may be placed [m].
        label_kind: What a model predicts per target in this scene.

    """

    name: str
    object_types: tuple[str, ...]
    workspace_x_m: tuple[float, float]
    workspace_y_m: tuple[float, float]
    label_kind: LabelKind
    distractor_types: tuple[str, ...] = ()

    @property
    def centre_y_m(self) -> float:
        """The line between the left (+y) and the right (-y) side [m]."""
        return 0.5 * (self.workspace_y_m[0] + self.workspace_y_m[1])


YUMI_SCENE = SceneSpec(
    name="yumi",
    object_types=OBJECT_TYPES,
    # In front of the robot, where the camera sees every object and the planner reaches every
    # catalog grasp at any yaw: nearer than x = 0.40 m the spray bottle's low side grasp puts
    # the wrist over the robot's foot at |y| > 0.15 m (mapped with the planner).
    workspace_x_m=(0.40, 0.55),
    workspace_y_m=(-0.20, 0.20),
    label_kind=LabelKind.GRASP_POSE,
    # The block (the experiments' look-alike), the clutter and the other look-alikes (the
    # bottle's and the mug's shape twins, the colour twin), never targets.
    distractor_types=DISTRACTOR_TYPES + CLUTTER_TYPES + LOOK_ALIKE_TYPES,
)


def _paper_scene() -> SceneSpec:
    from sim.world.paper_world import PAPER_OBJECT_TYPES, PAPER_WORKSPACE_X_M, PAPER_WORKSPACE_Y_M

    return SceneSpec("paper-sim", PAPER_OBJECT_TYPES, PAPER_WORKSPACE_X_M, PAPER_WORKSPACE_Y_M,
                     LabelKind.POSITION)


SCENE_NAMES = ("paper-sim", "yumi")


def get_scene_spec(name: str) -> SceneSpec:
    """The scene called ``name``; an unknown name lists the allowed ones."""
    if name == "yumi":
        return YUMI_SCENE
    if name == "paper-sim":
        return _paper_scene()
    raise InvalidInputError("scene", name, f"one of {', '.join(SCENE_NAMES)}")


def scene_camera(name: str, robot: RobotDescription) -> CameraConfig:
    """The head camera that takes the images of the scene called ``name``.

    The yumi scene's is ``robot``'s (the run's robot, whose workcell it is); paper-sim's its own.
    """
    get_scene_spec(name)  # an unknown name lists the allowed ones
    if name == "yumi":
        return camera_config(robot)
    from sim.world.paper_world import PaperWorldConfig

    return PaperWorldConfig().camera
