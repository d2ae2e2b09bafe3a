"""Pictures of objects for image conditions: one object alone, from its own view and light.

An image condition shows the model a small picture of the wanted object instead of naming it.
The picture never comes from the scene the model looks at: it is taken in a picture scene of
its own, the object alone on the table at its own yaw, seen from its own viewpoint, distance
and light. Pictures are numbered per scene, object type and split; training scenes draw from
the training pictures and test scenes and trials from the test ones, so a trial's picture was
never seen in training (:mod:`sim.tasks.queries` draws the number).

A picture is rendered at twice :data:`~perception.interface.PICTURE_PX` and averaged down
2 x 2 (PyBullet's software renderer does not smooth edges). Each process keeps one world per
scene for its pictures and caches every picture it rendered.
"""

from __future__ import annotations

import functools
import math
import zlib

import numpy as np

from perception.interface import PICTURE_PX
from perception.objects.catalog import get_object_spec
from robots import get_robot
from robots.description import CameraMount
from sim.errors import InvalidInputError
from sim.world.head_camera import CameraConfig, HeadCamera
from sim.world.lighting import Lighting
from sim.world.paper_world import PaperWorld
from sim.world.yumi_world import World

PICTURES_PER_SPLIT = 64
"""Distinct pictures per scene, object type and split: each its own yaw, view and light."""
SPLIT_STREAMS = {"train": 0, "test": 1}
"""Picture seed streams: training and test pictures are drawn from disjoint seeds."""
PICTURE_SEED = 0x6A7A
"""Pictures do not depend on an experiment's seed: they are the same photos for every run."""
YUMI_PICTURE_XY_M = (0.85, 0.0)
"""Where the yumi picture scene puts its object: on the table, far ahead of the robot, so a
view from the robot's side shows table behind it, never the robot."""
DISTANCE_M = (0.32, 0.45)
"""Camera distance from the object's centre [m]."""
ELEVATION_DEG = (35.0, 70.0)
"""Camera elevation above the table plane [deg]."""
AZIMUTH_DEG = 60.0
"""Largest turn of the viewpoint from straight behind the object (seen from the robot) [deg]."""
BRIGHTNESS = (0.7, 1.2)
"""Range of the picture scene's light."""


def render_picture(scene: str, object_type: str, split: str, number: int) -> np.ndarray:
    """Picture ``number`` of ``object_type`` in ``scene``'s ``split``: uint8 (32, 32, 3).

    Raises:
        InvalidInputError: An unknown scene, type or split, or a number out of range.

    """
    if split not in SPLIT_STREAMS:
        raise InvalidInputError("split", split, f"one of {', '.join(SPLIT_STREAMS)}")
    if not 0 <= number < PICTURES_PER_SPLIT:
        raise InvalidInputError("number", number, f"an integer in [0, {PICTURES_PER_SPLIT})")
    picture = _rendered(scene, object_type, split, number)
    picture.flags.writeable = False
    return picture


@functools.lru_cache(maxsize=2048)
def _rendered(scene: str, object_type: str, split: str, number: int) -> np.ndarray:
    rng = np.random.default_rng(np.random.SeedSequence(
        [PICTURE_SEED, SPLIT_STREAMS[split], zlib.crc32(f"{scene}/{object_type}".encode()),
         number]))
    yaw = float(rng.uniform(-math.pi, math.pi))
    world = _world(scene)
    if isinstance(world, World):
        body = world.add_object(get_object_spec(object_type), YUMI_PICTURE_XY_M, yaw)
    else:
        body = world.add_object(object_type, (0.0, 0.0), yaw)
    try:
        low, high = (np.array(v) for v in world.client.getAABB(body))
        centre, extent = 0.5 * (low + high), float(np.max(high - low))
        distance = float(rng.uniform(*DISTANCE_M))
        elevation = math.radians(float(rng.uniform(*ELEVATION_DEG)))
        azimuth = math.pi + math.radians(float(rng.uniform(-AZIMUTH_DEG, AZIMUTH_DEG)))
        eye = centre + distance * np.array([math.cos(elevation) * math.cos(azimuth),
                                            math.cos(elevation) * math.sin(azimuth),
                                            math.sin(elevation)])
        fov_deg = math.degrees(2 * math.atan(0.75 * extent / distance)) * rng.uniform(0.9, 1.2)
        light = Lighting(direction=(float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), 1.0),
                         brightness=float(rng.uniform(*BRIGHTNESS)))
        mount = CameraMount(tuple(eye), tuple(centre))  # no heatmap focus: no model reads it
        camera = HeadCamera(CameraConfig.for_mount(
            mount, width_px=2 * PICTURE_PX, height_px=2 * PICTURE_PX, vertical_fov_deg=fov_deg,
            horizontal_fov_deg=None, near_m=0.02, lighting=light))
        image = camera.render(world.client).astype(np.float32)  # (64, 64, 3)
    finally:
        if isinstance(world, World):
            world.remove_object(body)
        else:
            world.reset_scene()
    small = image.reshape(PICTURE_PX, 2, PICTURE_PX, 2, 3).mean(axis=(1, 3))
    return np.rint(small).astype(np.uint8)


@functools.cache
def _world(scene: str) -> World | PaperWorld:
    """The process's picture world of ``scene`` (kept: building one takes a few tenths of s)."""
    if scene == "yumi":
        return World(robot=get_robot("yumi"))  # the yumi scene is the YuMi's workcell
    if scene == "paper-sim":
        return PaperWorld()
    raise InvalidInputError("scene", scene, "paper-sim or yumi")
