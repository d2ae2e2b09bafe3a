"""Pictures of what a model sees: a scene rendered by its camera, written as a PNG."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from perception.drawing import write_png
from perception.objects.catalog import get_object_spec
from robots import DEFAULT_ROBOT, get_robot
from robots.description import RobotDescription
from sim.errors import InvalidInputError
from sim.tasks.scene_sampling import Scene
from sim.tasks.task_spec import TaskSpec
from sim.world.head_camera import HeadCamera, camera_config
from sim.world.looks import lighting_for, moved_camera
from sim.world.sensor import SensorSeed
from sim.world.yumi_world import World

SETTLE_S = 0.25


def render_scene(scene: Scene, task: TaskSpec | None = None,
                 robot: RobotDescription | None = None) -> np.ndarray:
    """The camera image of ``scene`` (uint8 (H, W, 3)), as a model would get it.

    Under ``task``'s light and sensor (:attr:`~sim.tasks.task_spec.TaskSpec.sensor`, the D435
    where it names none; its first frame: the D435's noise drawn as a trial's would be) and the
    scene's look; None: the ideal camera in the scene's normal light. The yumi scene is seen in
    ``robot``'s workcell through its camera (None: the default robot's), as that robot's
    demonstrations and trials see it; the paper-sim scene through its own camera, an ideal
    pinhole, whatever the task's sensor.
    """
    brightness = 1.0 if task is None else task.brightness
    if scene.scene == "paper-sim":
        from sim.world.paper_world import PaperWorld

        with PaperWorld() as paper:
            paper.reset_scene()
            for placed in scene.objects:
                paper.add_object(placed.object_type, placed.position_xy_m, placed.yaw_rad)
            paper.settle()
            return paper.render(brightness)
    look = scene.look
    robot = robot or get_robot(DEFAULT_ROBOT)
    with World(robot=robot) as world:
        world.reset_scene()
        for index, placed in enumerate(scene.objects):
            world.add_object(get_object_spec(placed.object_type), placed.position_xy_m,
                             placed.yaw_rad, None if look is None else look.objects[index])
        if look is not None:
            world.dress_table(look.table)
        world.step(round(SETTLE_S / world.config.time_step_s))
        config = moved_camera(camera_config(robot), None if look is None else look.mount)
        camera = HeadCamera(config, None if task is None else task.sensor)
        lighting = lighting_for(dataclasses.replace(config.lighting, brightness=brightness),
                                None if look is None else look.light)
        return camera.render(world.client, lighting,
                             SensorSeed(scene.seed, int(scene.stream), scene.index))


def write_scene_png(image: np.ndarray, path: str | Path, scale: int = 1) -> Path:
    """Writes ``image`` enlarged ``scale`` times (nearest neighbour, so pixels stay visible)."""
    if scale < 1:
        raise InvalidInputError("scale", scale, "an integer >= 1")
    enlarged = np.kron(image, np.ones((scale, scale, 1), dtype=np.uint8)) if scale > 1 else image
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    return write_png(out, enlarged)
