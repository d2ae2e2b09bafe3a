"""The head camera: a RealSense D435 stand-in on top of the YuMi body, looking at the workspace.

It renders colour and depth from one call (:meth:`HeadCamera.render_rgbd`), as the D435 gives
both: the models read the colour, the planner the depth. Through its sensor
(:mod:`sim.world.sensor`): an ideal pinhole, or the D435-like lens, noise, invalid depth and
hand-eye error of :mod:`sim.world.d435`, while the frame carries the calibration a robot has.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
import pybullet
from scipy import ndimage

from perception.camera import PinholeCamera, RgbdFrame
from perception.interface import InvalidInputError as PerceptionInputError
from robots.description import CameraMount, RobotDescription
from robots.errors import InvalidInputError as RobotInputError
from sim.errors import InvalidInputError
from sim.world.d435 import (
    CalibrationError,
    calibration_error,
    colour_noise,
    depth_noise,
    distort_depth,
    distort_image,
    invalid_depth_edges,
    true_camera,
    wide_camera_for,
)
from sim.world.lighting import Lighting
from sim.world.sensor import SensorConfig, SensorKind, SensorSeed

SELF_FILTER_PADDING_PX = 2
"""How far a frame's self filter grows the robot's own pixels [px]: about 6 mm at the table
(128 px over 37 deg, 0.6 m away), over twice what the hand-eye rotation error's RMS (0.25 deg,
``D435Config``) moves an edge there (2.6 mm), so the arm's silhouette leaves no rim behind."""

FOCUS_BEFORE_RECORDED_PX = (24, 18)
"""The heatmap focus (window, box) [px] a camera record from before records stated it read its
heatmaps with (:meth:`CameraConfig.from_json`): the one focus every model had then, the YuMi
head camera's (``robots.yumi.HEAD_CAMERA``), so those datasets and runs still resume."""


@dataclass(frozen=True)
class CameraConfig:
    """Intrinsics, placement and lighting of the head camera (world frame, [m] and [deg]).

    The placement and the heatmap focus are a camera mount's (:class:`robots.description.
    CameraMount`), given by the caller: :meth:`for_mount`, or :func:`camera_config` for a
    robot's own; no robot is assumed. The other fields default to the D435-like head camera.
    The YuMi's mount puts the optical centre 5 cm above the front edge of the body's top
    (z = 0.47 m, x = 0.09 m), between the two shoulders, tilted down toward x = 0.49 m on the
    table. From
    there no arm link at HOME hides any part of the workspace (x 0.30-0.55 m, y ±0.25 m, objects
    up to 17 cm tall; checked by ray casts): from further back or higher, the forward-pointing
    first links of the arms cut off the workspace's near corners. The image is the part of the
    D435 colour frame (69° x 42°) that holds the workspace, 58° x 37°, resized to 128 x 128, as
    a robot's image pipeline crops its region of interest: pixels are then not square (1.7 : 1),
    and no pixel is spent on the floor beyond the table. Every part of every object the scene
    may place lies within u 6-122 px, v 7-107 px; 1 cm on the table is 2.0-2.7 px along x and
    1.6-1.9 px along y (the full square
    69° frame gave 1.0-1.3 and 1.4-1.5: attention points, and so grasps, are read from twice as
    many pixels); the grippers at HOME stay out of view.

    Attributes:
        width_px: Image width [px].
        height_px: Image height [px].
        vertical_fov_deg: Vertical field of view [deg].
        horizontal_fov_deg: Horizontal field of view [deg]; None: square pixels, the horizontal
            field following the image's aspect. Given, the image is a crop resized to
            ``width_px x height_px``, its pixels stretched where the two disagree.
        position_m: Optical centre in the world (keyword only, required: the mount's).
        target_m: The point the optical axis passes through (keyword only, required).
        up: World direction that appears up in the image.
        near_m: Near clipping distance.
        far_m: Far clipping distance.
        lighting: The light the image is rendered with.
        focus_window_px: The attention heatmap focus derived for this camera's images
            (:class:`robots.description.CameraMount`; 0: none derived; keyword only,
            required). A dataset records it with the camera, and a model trained there reads
            its heatmaps so.
        focus_box_px: The side of the focus's densest square [px]; 0 without a focus (keyword
            only, required).

    The four mount fields keep their place among the fields (``asdict``, and so every run
    identity and dataset record, lists them as before); only the constructor takes them by
    keyword.

    """

    width_px: int = 128
    height_px: int = 128
    vertical_fov_deg: float = 37.0
    horizontal_fov_deg: float | None = 58.0
    position_m: tuple[float, float, float] = field(kw_only=True)
    target_m: tuple[float, float, float] = field(kw_only=True)
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    near_m: float = 0.05
    far_m: float = 3.0
    lighting: Lighting = field(default_factory=Lighting)
    focus_window_px: int = field(kw_only=True)
    focus_box_px: int = field(kw_only=True)

    def __post_init__(self) -> None:
        for name in ("width_px", "height_px"):
            if not 8 <= getattr(self, name) <= 4096:
                raise InvalidInputError(name, getattr(self, name), "an integer in [8, 4096] px")
        if not 1.0 <= self.vertical_fov_deg <= 170.0:
            raise InvalidInputError("vertical_fov_deg", self.vertical_fov_deg, "in [1, 170] deg")
        if self.horizontal_fov_deg is not None and not 1.0 <= self.horizontal_fov_deg <= 170.0:
            raise InvalidInputError("horizontal_fov_deg", self.horizontal_fov_deg,
                                    "None or in [1, 170] deg")
        if not 0.0 < self.near_m < self.far_m:
            raise InvalidInputError("near_m/far_m", (self.near_m, self.far_m), "0 < near < far")
        try:  # the placement: PinholeCamera checks it (a point to look at, an up off the axis)
            self.pinhole  # noqa: B018
        except PerceptionInputError as error:
            raise InvalidInputError(error.field, error.value, error.allowed) from None
        try:  # the focus: the robot description's rule (both 0, or both >= 1)
            CameraMount(self.position_m, self.target_m, self.focus_window_px, self.focus_box_px)
        except RobotInputError as error:
            raise InvalidInputError(error.field.removeprefix("camera."), error.value,
                                    error.allowed) from None

    @classmethod
    def for_mount(cls, mount: CameraMount, **overrides: Any) -> CameraConfig:
        """The head camera on ``mount``: its placement and focus, the other fields the defaults.

        ``overrides`` replaces any field (e.g. ``width_px``, ``lighting``), the mount's too.
        """
        placed: dict[str, Any] = {"position_m": mount.position_m, "target_m": mount.target_m,
                                  "focus_window_px": mount.focus_window_px,
                                  "focus_box_px": mount.focus_box_px}
        return cls(**placed | overrides)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> CameraConfig:
        """The config a dataset's metadata recorded (``asdict`` as JSON; lists back to tuples).

        A camera recorded before ``horizontal_fov_deg`` existed had square pixels (None); one
        recorded before the focus was (issue 39) read its heatmaps with
        :data:`FOCUS_BEFORE_RECORDED_PX`. The record's ``sensor`` (:meth:`HeadCamera.record`)
        is the sensor's, not this config's.
        """
        def plain(fields: dict[str, Any]) -> dict[str, Any]:
            return {k: tuple(v) if isinstance(v, list) else v for k, v in fields.items()
                    if k != "sensor"}

        window_px, box_px = FOCUS_BEFORE_RECORDED_PX
        fields = {"horizontal_fov_deg": None, "focus_window_px": window_px,
                  "focus_box_px": box_px} | plain(data)
        fields["lighting"] = Lighting(**plain(data.get("lighting", {})))
        return cls(**fields)

    @property
    def pinhole(self) -> PinholeCamera:
        """The camera's geometry alone (what a dataset's record gives a perception model)."""
        return PinholeCamera(self.position_m, self.target_m, self.up, self.vertical_fov_deg,
                             self.horizontal_fov_deg, self.width_px, self.height_px)

    @property
    def projection_aspect(self) -> float:
        """The projection's width : height in the image plane (ratio of half-FOV tangents)."""
        if self.horizontal_fov_deg is None:
            return self.width_px / self.height_px
        return math.tan(math.radians(self.horizontal_fov_deg) / 2) / math.tan(
            math.radians(self.vertical_fov_deg) / 2)


def camera_config(robot: RobotDescription) -> CameraConfig:
    """The camera settings of ``robot``'s workcell.

    Its camera mount and the heatmap focus derived for it; every other setting the head
    camera's (the D435-like crop, the image size, the light).
    """
    return CameraConfig.for_mount(robot.camera)


class HeadCamera:
    """Renders and projects with one :class:`CameraConfig` (PyBullet's CPU renderer: no GPU, no X).

    The view and projection matrices are PyBullet's own (OpenGL, column-major), so
    :meth:`project` agrees with an ideal :meth:`render` to the pixel. Through a D435 sensor the
    image is rendered from the camera's true pose through its true lens (:meth:`true_camera`);
    :meth:`project` and every frame keep the calibration (:attr:`pinhole`), as a robot does.

    Args:
        config: Intrinsics, placement and lighting (a robot's: :func:`camera_config`).
        sensor: What renders the frames; the ideal pinhole when None.

    """

    def __init__(self, config: CameraConfig, sensor: SensorConfig | None = None) -> None:
        if not isinstance(config, CameraConfig):
            raise InvalidInputError("config", config, "a CameraConfig (a robot's: camera_config)")
        self.config = config
        self.sensor = SensorConfig() if sensor is None else sensor
        if not isinstance(self.sensor, SensorConfig):
            raise InvalidInputError("sensor", self.sensor, "a SensorConfig")
        c = self.config
        self.view_matrix = pybullet.computeViewMatrix(c.position_m, c.target_m, c.up)
        self.projection_matrix = pybullet.computeProjectionMatrixFOV(
            c.vertical_fov_deg, c.projection_aspect, c.near_m, c.far_m
        )
        # Column-major 4x4 lists -> row-major arrays acting on column vectors.
        view = np.array(self.view_matrix).reshape(4, 4).T
        projection = np.array(self.projection_matrix).reshape(4, 4).T
        self.clip_from_world = projection @ view  # (4, 4), PyBullet's own
        self.pinhole = c.pinhole
        self._mounts: dict[int, CalibrationError] = {}  # the hand-eye error, per seed
        self._wide: dict[int, PinholeCamera] = {}  # the wide ideal view, per seed
        if self.sensor.kind is SensorKind.D435:
            lens = self.sensor.d435.colour_distortion_k1_k2_p1_p2_k3
            try:  # the lens must be one-to-one over this image (PinholeCamera checks it)
                self._lens = replace(self.pinhole, distortion_k1_k2_p1_p2_k3=lens)
            except PerceptionInputError as error:
                raise InvalidInputError("camera.colour_distortion_k1_k2_p1_p2_k3", lens,
                                        error.allowed) from None

    def record(self) -> dict[str, Any]:
        """The camera as a dataset records it: the config's fields and the sensor's."""
        return json.loads(json.dumps(asdict(self.config))) | {"sensor": self.sensor.to_json()}

    def mount_error(self, seed: int) -> CalibrationError:
        """How the camera's true pose differs from its calibration under run seed ``seed``."""
        if seed not in self._mounts:
            drawn = SensorSeed(seed).mount_rng()
            self._mounts[seed] = calibration_error(drawn, self.sensor.d435)
        return self._mounts[seed]

    def true_camera(self, seed: int) -> PinholeCamera:
        """The camera as it really is under run seed ``seed``: its pose and lens (the referee's).

        The ideal sensor's is its calibration; a D435's stands off it by :meth:`mount_error`
        and distorts by the sensor's lens, while its frames carry :attr:`pinhole`.
        """
        if self.sensor.kind is SensorKind.IDEAL:
            return self.pinhole
        return true_camera(self._lens, self.mount_error(seed))

    def render(self, client: Any, lighting: Lighting | None = None,
               seed: SensorSeed | None = None) -> np.ndarray:
        """Render an RGB image of the world on ``client``: uint8 (H, W, 3), row 0 at the top.

        Args:
            client: A ``BulletClient`` (e.g. ``World.client``).
            lighting: Overrides the config's light for this image (e.g. a darker room).
            seed: Which frame this is (a D435's noise and mount are drawn from it; the ideal
                sensor ignores it).

        """
        return self.render_rgbd(client, lighting, seed).rgb

    def render_rgbd(self, client: Any, lighting: Lighting | None = None,
                    seed: SensorSeed | None = None, self_body: int | None = None) -> RgbdFrame:
        """Render colour and depth together, with the camera's calibration (see :meth:`render`).

        Depth is along the optical axis [m], from PyBullet's depth buffer (OpenGL's non-linear
        [0, 1]). The ideal sensor: exact, inf where nothing is seen within ``far_m``. A D435:
        rendered wider from :meth:`true_camera`'s pose, distorted by its lens (colour
        bilinear, depth nearest), the stereo shadow and noise added, 0.0 where it has no depth;
        ``seed`` is required (the noise is drawn per frame, never from a global generator).

        ``self_body``: the robot's body, whose own pixels (grown by
        :data:`SELF_FILTER_PADDING_PX`) get no depth (0: no measurement) and the colour of the
        rest of the image (its per-channel median, the table's), so a frame taken while the arm
        is in view gives the planner no obstacle and the model no arm where the arm is; the
        frame's ``robot_mask`` says which pixels those are. A real
        robot does the same by rendering its model at the measured joints through the
        calibrated camera (e.g. ``realtime_urdf_filter``); here PyBullet's segmentation of that
        model stands in for it.
        """
        c, light = self.config, self.config.lighting if lighting is None else lighting
        if self.sensor.kind is SensorKind.IDEAL:
            rgb, depth, bodies = self._render(client, c.width_px, c.height_px,
                                              self.view_matrix, self.projection_matrix, light)
            return _self_filtered(RgbdFrame(rgb, depth, self.pinhole), bodies, self_body)
        if not isinstance(seed, SensorSeed):
            raise InvalidInputError("seed", seed, "a SensorSeed: a D435 draws its noise per "
                                    "frame and its mount per run seed")
        sensor, true = self.sensor.d435, self.true_camera(seed.seed)
        if seed.seed not in self._wide:
            self._wide[seed.seed] = wide_camera_for(true)
        wide = self._wide[seed.seed]
        tan_x, tan_y = wide.tan_half_fov
        view = pybullet.computeViewMatrix(wide.position_m, wide.target_m, wide.up)
        projection = pybullet.computeProjectionMatrixFOV(wide.vertical_fov_deg, tan_x / tan_y,
                                                         c.near_m, c.far_m)
        rgb_wide, depth_wide, bodies_wide = self._render(client, wide.width_px, wide.height_px,
                                                         view, projection, light)
        rng = seed.noise_rng()
        rgb = colour_noise(distort_image(rgb_wide, wide, true), rng, sensor)
        depth = invalid_depth_edges(distort_depth(depth_wide, wide, true), true, sensor)
        depth = depth_noise(depth, true, rng, sensor)
        frame = RgbdFrame(rgb, depth, self.pinhole)
        if self_body is None:
            return frame
        bodies = distort_depth(bodies_wide.astype(np.float32), wide, true).astype(int)
        return _self_filtered(frame, bodies, self_body)  # ids registered as the depth (nearest)

    def _render(self, client: Any, width_px: int, height_px: int, view: Any, projection: Any,
                light: Lighting) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """PyBullet's image: RGB, depth and the body each pixel shows.

        RGB uint8 (H, W, 3); depth float32 (H, W) [m], inf for none; bodies int (H, W), -1 for
        none.
        """
        c = self.config
        _, _, rgba, buffer, segmentation = client.getCameraImage(
            width_px, height_px, view, projection,
            lightDirection=list(light.direction),
            lightColor=[light.brightness * c for c in light.colour_rgb],
            lightAmbientCoeff=light.ambient_coeff * light.brightness,
            lightDiffuseCoeff=light.diffuse_coeff,
            lightSpecularCoeff=light.specular_coeff,
            shadow=int(light.shadows),
            renderer=pybullet.ER_TINY_RENDERER,
        )
        image = np.asarray(rgba, dtype=np.uint8).reshape(height_px, width_px, 4)
        rgb = np.ascontiguousarray(image[:, :, :3])
        buffer = np.asarray(buffer, dtype=np.float64).reshape(height_px, width_px)
        with np.errstate(divide="ignore"):
            depth = c.far_m * c.near_m / (c.far_m - (c.far_m - c.near_m) * buffer)
        bodies = np.asarray(segmentation, dtype=np.int64).reshape(height_px, width_px)
        return rgb, np.where(buffer >= 1.0, np.inf, depth).astype(np.float32), bodies

    def project(self, points_world: np.ndarray) -> np.ndarray:
        """Pixel coordinates (u right, v down) of world points, (N, 3) -> (N, 2).

        Integer coordinates are pixel centres: ``round(u), round(v)`` index ``image[v, u]``.
        Points behind the camera get NaN. The geometry is :class:`perception.camera.
        PinholeCamera`'s, the one a perception model reads from a dataset's camera record.
        """
        if np.ndim(points_world) not in (1, 2) or np.shape(points_world)[-1] != 3:
            raise InvalidInputError("points_world", np.shape(points_world), "shape (N, 3)")
        return self.pinhole.project(points_world)


def _self_filtered(frame: RgbdFrame, bodies: np.ndarray, self_body: int | None) -> RgbdFrame:
    """``frame`` without the robot, whose pixels get no depth and the rest's colour.

    The robot's pixels: where ``bodies`` shows ``self_body``, grown by
    :data:`SELF_FILTER_PADDING_PX`; they get depth 0, the per-channel median colour of the
    others (the table's: it fills most of the view; set per frame, so no colour is chosen by
    hand) and the frame's ``robot_mask``. None: ``frame`` unchanged.
    """
    if self_body is None:
        return frame
    own = ndimage.binary_dilation(bodies == self_body, iterations=SELF_FILTER_PADDING_PX)
    rgb = frame.rgb.copy()
    rgb[own] = np.median(frame.rgb[~own], axis=0).astype(rgb.dtype) if (~own).any() else 0
    depth = np.where(own, np.float32(0.0), frame.depth_m).astype(np.float32)
    return RgbdFrame(rgb, depth, frame.camera, robot_mask=own)
