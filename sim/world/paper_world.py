"""The paper's simulator scene (Table II), without a robot.

A checker floor, a wooden table, a duck, a soccer ball and a mug, each about 10 cm wide, and a
camera at the table centre from 50 cm. The world frame has the table centre at the origin and
the table top at z = 0; x points away from the camera, y to its left, so the image's left is +y
as in the ``yumi`` scene.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from robots.description import CameraMount
from sim.errors import InvalidInputError
from sim.world.bullet_world import TABLE_TOP_Z_IN_URDF_M, BulletWorld
from sim.world.head_camera import CameraConfig, HeadCamera
from sim.world.world_config import check_wait_s

PAPER_OBJECT_TYPES: tuple[str, ...] = ("duck", "soccer_ball", "mug")
"""The scene's object types, in one-hot (and target) order."""

PAPER_WORKSPACE_X_M: tuple[float, float] = (-0.14, 0.14)
PAPER_WORKSPACE_Y_M: tuple[float, float] = (-0.18, 0.18)
"""Where object centres may lie [m]: an object at any corner, at any yaw, is wholly in the
image (its bounding box projects within 4.5-123.5 px of 128)."""


@dataclass(frozen=True)
class _Asset:
    urdf: str
    scale: float  # globalScaling that makes the widest horizontal extent ~0.10 m
    roll_rad: float  # turn about x that stands the mesh upright, before its yaw


# Native widest horizontal extents: duck 0.091 m, soccer ball 1.0 m, mug 0.128 m (with handle).
# The duck's mesh lies on its side; a quarter turn about x stands it up.
_ASSETS: Mapping[str, _Asset] = {
    "duck": _Asset("duck_vhacd.urdf", 1.1, math.pi / 2),
    "soccer_ball": _Asset("soccerball.urdf", 0.1, 0.0),
    "mug": _Asset("objects/mug.urdf", 0.78, 0.0),
}


def _paper_camera() -> CameraConfig:
    # 50 cm from the table centre, 65 degrees above the table, looking along +x; the 76 degree
    # field of view frames the workspace with a 10 cm object about 16 px wide.
    distance_m, elevation = 0.50, math.radians(65.0)
    eye = (-distance_m * math.cos(elevation), 0.0, distance_m * math.sin(elevation))
    # Its focus is the one the paper-sim datasets and runs have always recorded (the YuMi head
    # camera's, then every camera's): records state it, and a changed one would not resume.
    return CameraConfig.for_mount(CameraMount(eye, (0.0, 0.0, 0.0), focus_window_px=24,
                                              focus_box_px=18),
                                  vertical_fov_deg=76.0, horizontal_fov_deg=None)


@dataclass(frozen=True)
class PaperWorldConfig:
    """Physics and camera of the paper's scene.

    Args:
        time_step_s: Physics step [s].
        settle_s: How long placed objects settle before an image [s]; they are placed resting,
            so a short settle suffices.
        camera: The 50 cm camera.

    """

    time_step_s: float = 1.0 / 240.0
    settle_s: float = 0.1
    camera: CameraConfig = field(default_factory=_paper_camera)

    def __post_init__(self) -> None:
        if not 0.0 < self.time_step_s <= 0.01:
            raise InvalidInputError("time_step_s", self.time_step_s, "in (0, 0.01] s")
        check_wait_s("settle_s", self.settle_s)


class PaperWorld(BulletWorld[str]):
    """One headless PyBullet world of the paper's scene; a context manager."""

    def __init__(self, config: PaperWorldConfig | None = None) -> None:
        self.config = config or PaperWorldConfig()
        self._connect(self.config.time_step_s, 9.81)
        self.client.loadURDF("plane.urdf", [0.0, 0.0, -TABLE_TOP_Z_IN_URDF_M])
        self.table_id = int(self.client.loadURDF(
            "table/table.urdf", [0.0, 0.0, -TABLE_TOP_Z_IN_URDF_M], useFixedBase=True))
        self.camera = HeadCamera(self.config.camera)
        self._objects: dict[int, str] = {}

    def object_type(self, body_id: int) -> str:
        """The type of an object in the world."""
        try:
            return self._objects[body_id]
        except KeyError:
            raise InvalidInputError("body_id", body_id, "an object in this world") from None

    def reset_scene(self) -> None:
        """Removes every object; the client, floor and table stay."""
        for body in list(self._objects):
            self.client.removeBody(body)
        self._objects.clear()

    def add_object(
        self, object_type: str, position_xy_m: tuple[float, float], yaw_rad: float
    ) -> int:
        """Places an object upright and resting on the table, turned by ``yaw_rad`` about z."""
        asset = _ASSETS.get(object_type)
        if asset is None:
            raise InvalidInputError("object type", object_type,
                                    f"one of {', '.join(PAPER_OBJECT_TYPES)}")
        client = self.client
        orientation = client.getQuaternionFromEuler([asset.roll_rad, 0.0, float(yaw_rad)])
        x, y = (float(v) for v in position_xy_m)
        body = int(client.loadURDF(asset.urdf, [x, y, 0.0], orientation,
                                   globalScaling=asset.scale))
        # Centre the footprint on (x, y), its box's bottom on the table top; the box carries the
        # mesh's 2-3 mm collision margin, so then close the gap the narrow phase reports: the
        # object starts touching and settling does not drop it.
        (lo_x, lo_y, lo_z), (hi_x, hi_y, _) = client.getAABB(body)
        position = np.array(client.getBasePositionAndOrientation(body)[0])
        position += [x - 0.5 * (lo_x + hi_x), y - 0.5 * (lo_y + hi_y), -lo_z + 1e-4]
        client.resetBasePositionAndOrientation(body, position.tolist(), orientation)
        gaps = [point[8] for point in client.getClosestPoints(body, self.table_id, 0.01)]
        if gaps:
            position[2] -= min(gaps)
            client.resetBasePositionAndOrientation(body, position.tolist(), orientation)
        client.changeDynamics(body, -1, lateralFriction=1.0, rollingFriction=0.002,
                              spinningFriction=0.002, restitution=0.0)
        self._objects[body] = object_type
        return body

    def settle(self) -> None:
        """Lets the objects settle for ``settle_s``."""
        for _ in range(round(self.config.settle_s / self.config.time_step_s)):
            self.client.stepSimulation()

    def object_position_m(self, body_id: int) -> np.ndarray:
        """The label: the centre of the object's axis-aligned bounding box in the world [m]."""
        self.object_type(body_id)
        low, high = self.client.getAABB(body_id)
        return 0.5 * (np.array(low) + np.array(high))

    def render(self, brightness: float = 1.0) -> np.ndarray:
        """The camera image, uint8 (H, W, 3); ``brightness`` scales the light (1 = normal)."""
        lighting = dataclasses.replace(self.config.camera.lighting, brightness=brightness)
        return self.camera.render(self.client, lighting)
