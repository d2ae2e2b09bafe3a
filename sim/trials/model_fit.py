"""Whether a perception model can run a task's trials: grasp poses, for this task, sensor, camera.

:func:`check_model_fits_task` refuses, in one line that says why, a model that does not predict
grasp poses, or a checkpoint trained for another scene, condition, target count or image size,
under another sensor (unless allowed) or through another robot's camera, in-process or served
(by the spec ``gva serve`` announces); the trials' settings (:mod:`harness.inputs.trial_settings`)
call it before the first trial.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from perception.interface import LabelKind, PerceptionModel
from perception.learning.learnable import LearnableModel, ModelSpec
from perception.remote.client import RemoteModel
from robots import ROBOT_NAMES, get_robot
from robots.description import RobotDescription
from sim.errors import InvalidInputError
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_in_scene import condition_choices, target_count
from sim.tasks.task_spec import TaskSpec
from sim.world.head_camera import camera_config
from sim.world.sensor import SensorConfig, sensor_from_table


def check_model_fits_task(model: PerceptionModel, task: TaskSpec, where: str,
                          allow_sensor_change: bool = False, *,
                          robot: RobotDescription) -> None:
    """Raises unless ``model`` predicts grasp poses for what ``task`` asks in the yumi scene.

    A model with a :class:`~perception.learning.learnable.ModelSpec` must have been trained on
    the yumi scene with the task's condition (kind and choices), target count and the head camera's
    image size, and (unless ``allow_sensor_change``) under the task's sensor
    (:func:`trained_sensor` against :attr:`TaskSpec.sensor`; the refusal names ``--sensor``
    with the checkpoint's own first, then ``--allow-sensor-change``), through ``robot``'s
    camera (where its spec records the camera: one robot's images are not another's). Its task
    may have another name (e.g. the same task under dimmer light).
    """
    kind = getattr(model, "label_kind", None)
    if kind is not LabelKind.GRASP_POSE:
        shown = kind.value if isinstance(kind, LabelKind) else kind
        raise InvalidInputError(f"model {where}: label_kind", shown, "'grasp_pose': pick trials "
                                "need a grasp pose (TCP position and rotation) per target; a "
                                "position model (e.g. one trained on paper-sim) cannot pick")
    spec = model_spec(model)
    if spec is None:
        return
    camera = camera_config(robot)
    check_camera(spec, robot, where)
    needed = (YUMI_SCENE.name, task.model_condition.value, condition_choices(task, YUMI_SCENE),
              target_count(task), camera.height_px, camera.width_px)
    trained = (spec.scene, spec.condition_kind.value, tuple(spec.condition_choices),
               spec.targets, spec.image_height_px, spec.image_width_px)
    if trained != needed:
        raise InvalidInputError(f"model {where}", f"trained for task {spec.task} "
                                f"{_describe(*trained)}", f"a checkpoint for trial task "
                                f"{task.name} {_describe(*needed)}")
    sensor = trained_sensor(spec, where)
    if sensor != task.sensor and not allow_sensor_change:
        own = (f"--sensor {sensor.kind.value}" if sensor == SensorConfig(sensor.kind) else
               f"a task file whose [camera] names sensor {sensor.describe()}")
        raise InvalidInputError(f"model {where}", f"trained on images of sensor "
                                f"{sensor.describe()}", f"trials under that sensor ({own}; "
                                f"trial task {task.name} is seen through "
                                f"{task.sensor.describe()}), or --allow-sensor-change to try it "
                                f"under {task.sensor.describe()}")


def model_spec(model: PerceptionModel) -> ModelSpec | None:
    """What ``model`` was trained for: a learnable model's spec, or the one its server announced.

    A served checkpoint (``gva serve``) announces its spec, so it is checked as in-process; a
    model without one (a plug-in without weights, a server announcing none) is not checked.
    """
    if isinstance(model, LearnableModel | RemoteModel) and isinstance(model.spec, ModelSpec):
        return model.spec
    return None


def check_camera(spec: ModelSpec, robot: RobotDescription, where: str) -> None:
    """Raises where ``spec`` records a camera placed elsewhere than ``robot``'s, naming both."""
    if spec.camera is None:
        return  # older checkpoints record no camera: they were all the YuMi's
    seen = tuple(float(v) for v in spec.camera.position_m)
    if np.allclose(seen, robot.camera.position_m, atol=1e-9):
        return
    others = [name for name in ROBOT_NAMES
              if np.allclose(seen, get_robot(name).camera.position_m, atol=1e-9)]
    through = f"the {others[0]}'s camera" if others else "a camera"
    raise InvalidInputError(f"model {where}", f"trained through {through} at {seen} m",
                            f"a checkpoint trained through the {robot.name}'s camera at "
                            f"{robot.camera.position_m} m (train on the {robot.name}'s "
                            "demonstrations)")


def trained_sensor(spec: ModelSpec, where: str) -> SensorConfig:
    """The sensor a checkpoint's training images were rendered by, as its spec records it.

    A spec's ``sensor`` record (:meth:`SensorConfig.to_json`, from its dataset's
    ``metadata.camera["sensor"]``); a spec without one is the ideal camera's, the only sensor
    datasets were rendered by before sensors were recorded.
    """
    return recorded_sensor(spec.sensor, where)


def recorded_sensor(record: dict[str, Any] | None, where: str) -> SensorConfig:
    """A spec's ``sensor`` record as a sensor; None: the ideal camera (before sensors)."""
    return SensorConfig() if record is None else sensor_from_table(record, f"model {where}: "
                                                                   "sensor")


def _describe(scene: str, condition: str, choices: tuple[str, ...], targets: int,
              height_px: int, width_px: int) -> str:
    over = f"{condition} condition over {', '.join(choices)}" if choices else "no condition"
    return (f"on scene {scene} ({over}; {targets} target{'s' * (targets != 1)}; "
            f"{width_px}x{height_px} px images)")
