"""A RealSense D435-like sensor: what the head camera's colour and depth images suffer from.

Pure numpy, applied to images an ideal pinhole rendered: the colour lens's distortion
(:func:`distort_image`, :func:`distort_depth` resample a wider ideal render), sensor noise
(:func:`colour_noise`), stereo depth's noise, 1 mm steps, minimum range and field-of-view band
(:func:`depth_noise`), the stereo shadow at depth edges (:func:`invalid_depth_edges`), and a
seeded hand-eye calibration error (:func:`calibration_error`, :func:`true_camera`). Invalid
depth is 0.0, as the D435 reports it. Every default and its source: docs/decisions/d435-sensor.md.

Which sensor the head camera renders through, and which frame: :mod:`sim.world.sensor`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from perception.camera import PinholeCamera
from sim.errors import InvalidInputError

PLAUSIBLE: dict[str, tuple[float, float, str]] = {
    # Each parameter's plausible range, beside the source of its default (docs/decisions/
    # d435-sensor.md, "Parameters"): wide enough for any D400-like stereo camera, narrow enough
    # that a unit slip (mm for m) or a typo that blinds the depth is refused, not rendered.
    "baseline_m": (0.01, 0.3, "stereo baselines from the D405's 18 mm and the D435's 50 mm "
                   "(Intel D400 datasheet) up to 30 cm rigs"),
    "depth_focal_length_px": (50.0, 5000.0, "the D435's 427 px at 848 px wide (rs-enumerate-"
                              "devices) from a 100 px wide image to a 4k narrow lens"),
    "depth_width_px": (64, 4096, "the D435's 848 px (Intel, Tuning depth cameras) from a "
                       "thumbnail to 4k"),
    "subpixel_rms_px": (0.01, 1.0, "Intel, Tuning depth cameras: below 0.1 px, near 0.05 on good "
                        "texture; a pixel of RMS is no stereo match"),
    "depth_unit_m": (1e-5, 0.01, "the D400's default 1 mm, from 0.01 mm up to 1 cm; a coarser "
                     "step rounds every object on the table into it"),
    "max_disparity_px": (16.0, 1024.0, "Intel, Tuning depth cameras: 126 px at disparity shift "
                         "0; a search of fewer than 16 px or more than 1024 px is no D400's"),
    "left_imager_x_m": (-0.2, 0.2, "the D435i's 15 mm (factory calibration, realsense-ros 701), "
                        "within a camera body"),
    "colour_snr_max_db": (10.0, 60.0, "the OV2740's 36 dB; past 60 dB no CMOS colour sensor's "
                          "full well reaches"),
    "hand_eye_translation_rms_m": (0.0, 0.05, "0.28 mm after calibration (§Calibration); 5 cm "
                                   "is a camera never calibrated"),
    "hand_eye_rotation_rms_rad": (0.0, math.radians(5.0), "0.25 deg after calibration "
                                  "(§Calibration); 5 deg is a camera never calibrated"),
}
"""Each D435 parameter's plausible range and why; :class:`D435Config` refuses a value outside."""


@dataclass(frozen=True)
class D435Config:
    """The sensor's parameters ([m], [px] of the D435's own imagers, [rad]); each default cited.

    Attributes:
        baseline_m: Left to right imager (stereo baseline).
        depth_focal_length_px: The depth imager's focal length at ``depth_width_px``.
        depth_width_px: The depth resolution the focal length and subpixel figure belong to.
        subpixel_rms_px: RMS disparity error of the stereo match.
        depth_unit_m: The depth image's step.
        max_disparity_px: The disparity search range (sets the minimum range).
        left_imager_x_m: Where the left imager (the depth origin) sits along the colour
            camera's x axis (image right); the right imager is ``baseline_m`` further.
        colour_distortion_k1_k2_p1_p2_k3: The colour lens's true distortion (rendered).
        colour_snr_max_db: The colour sensor's maximum signal-to-noise ratio (full scale).
        hand_eye_translation_rms_m: RMS of the camera's position error after calibration.
        hand_eye_rotation_rms_rad: RMS of its orientation error.

    """

    baseline_m: float = 0.050  # decision doc §Depth, "baseline"
    depth_focal_length_px: float = 427.26  # §Depth, "focal length"
    depth_width_px: int = 848  # §Depth, "resolution"
    subpixel_rms_px: float = 0.08  # §Depth, "subpixel"
    depth_unit_m: float = 0.001  # §Depth, "quantisation"
    max_disparity_px: float = 126.0  # §Depth, "minimum range"
    left_imager_x_m: float = 0.015  # §Depth, "colour to depth extrinsic"
    colour_distortion_k1_k2_p1_p2_k3: tuple[float, float, float, float, float] = (
        -0.0237, 0.0, 0.0, 0.0, 0.0)  # §Colour, "lens distortion"
    colour_snr_max_db: float = 36.0  # §Colour, "sensor noise"
    hand_eye_translation_rms_m: float = 0.00028  # §Calibration
    hand_eye_rotation_rms_rad: float = math.radians(0.25)  # §Calibration

    def __post_init__(self) -> None:
        for name, (low, high, why) in PLAUSIBLE.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not (
                    math.isfinite(value) and low <= value <= high):
                raise InvalidInputError(name, value, f"a number in [{low:g}, {high:g}] ({why})")
        if not isinstance(self.depth_width_px, int):
            raise InvalidInputError("depth_width_px", self.depth_width_px, "an integer")
        lens = self.colour_distortion_k1_k2_p1_p2_k3
        if not (isinstance(lens, tuple) and len(lens) == 5 and all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                for v in lens)):
            raise InvalidInputError("colour_distortion_k1_k2_p1_p2_k3", lens,
                                    "five finite numbers (k1, k2, p1, p2, k3)")

    @property
    def min_range_m(self) -> float:
        """Nearest depth the disparity search reaches: f B / max disparity (~0.17 m)."""
        return self.depth_focal_length_px * self.baseline_m / self.max_disparity_px

    @property
    def depth_tan_half_hfov(self) -> float:
        """Tangent of the depth imagers' half horizontal field of view (from f and width)."""
        return 0.5 * self.depth_width_px / self.depth_focal_length_px

    def depth_sigma_m(self, depth_m: np.ndarray) -> np.ndarray:
        """Intel's depth RMS error: Z^2 * subpixel / (f * B), at the native resolution."""
        return np.square(depth_m) * self.subpixel_rms_px / (
            self.depth_focal_length_px * self.baseline_m)


@dataclass(frozen=True)
class CalibrationError:
    """How the camera's true pose differs from its calibration (one per re-mounted camera).

    Attributes:
        translation_m: True position minus calibrated position (world frame).
        rotation_rad: Rotation vector from the calibrated to the true orientation, in the
            calibrated optical frame (x right, y down, z forward).

    """

    translation_m: tuple[float, float, float]
    rotation_rad: tuple[float, float, float]


def wide_camera_for(camera: PinholeCamera, margin_px: int = 2) -> PinholeCamera:
    """An ideal pinhole at ``camera``'s pose whose image covers every distorted pixel of it.

    Same focal length in pixels, the image grown on each side by the most the undistorted
    border reaches past it (the border sampled at half-pixel steps, corners included), plus
    ``margin_px`` for the bilinear footprint.
    """
    ideal = replace(camera, distortion_k1_k2_p1_p2_k3=(0.0, 0.0, 0.0, 0.0, 0.0))
    width, height = camera.width_px, camera.height_px
    us, vs = np.arange(-0.5, width, 0.5), np.arange(-1.5, height - 1.0, 0.5)
    border = np.concatenate([np.stack([us, np.full_like(us, vs[0])], 1),
                             np.stack([us, np.full_like(us, vs[-1])], 1),
                             np.stack([np.full_like(vs, us[0]), vs], 1),
                             np.stack([np.full_like(vs, us[-1]), vs], 1)])  # (N, 2)
    reach = ideal.project(np.asarray(camera.position_m) + camera.rays(border))  # (N, 2)
    pad_x = max(0, math.ceil(max(-0.5 - reach[:, 0].min(), reach[:, 0].max() - width + 0.5)))
    pad_y = max(0, math.ceil(max(-1.5 - reach[:, 1].min(), reach[:, 1].max() - height + 1.5)))
    pad_x, pad_y = pad_x + margin_px, pad_y + margin_px
    tan_x, tan_y = camera.tan_half_fov
    return replace(ideal, width_px=width + 2 * pad_x, height_px=height + 2 * pad_y,
                   horizontal_fov_deg=math.degrees(2 * math.atan(tan_x * (width + 2 * pad_x)
                                                                 / width)),
                   vertical_fov_deg=math.degrees(2 * math.atan(tan_y * (height + 2 * pad_y)
                                                               / height)))


@functools.lru_cache(maxsize=16)  # one map per camera: a run renders every frame with one
def _source_pixels(wide: PinholeCamera, camera: PinholeCamera) -> np.ndarray:
    """For each pixel of ``camera``, where the wide ideal image shows what it sees, (H, W, 2).

    Read-only: it is cached, as the undistortion it needs costs more than the resampling.
    """
    if (wide.position_m, wide.target_m, wide.up) != (camera.position_m, camera.target_m,
                                                     camera.up) or wide.is_distorted:
        raise InvalidInputError("wide_camera", wide, "an undistorted camera at the same pose")
    u, v = np.meshgrid(np.arange(camera.width_px), np.arange(camera.height_px))
    rays = camera.rays(np.stack([u.ravel(), v.ravel()], axis=1))  # (H W, 3)
    source = wide.project(np.asarray(camera.position_m) + rays)  # (H W, 2)
    if not (np.isfinite(source).all() and (source[:, 0] >= 0).all()
            and (source[:, 0] <= wide.width_px - 1).all() and (source[:, 1] >= 0).all()
            and (source[:, 1] <= wide.height_px - 1).all()):
        raise InvalidInputError("wide_camera", wide.image_size_px,
                                "an image covering every distorted pixel (see wide_camera_for)")
    source = source.reshape(camera.height_px, camera.width_px, 2)
    source.flags.writeable = False
    return source


def distort_image(rgb_wide: np.ndarray, wide_camera: PinholeCamera,
                  camera: PinholeCamera) -> np.ndarray:
    """The colour image ``camera``'s lens makes, from a wider ideal render: bilinear, uint8."""
    if np.shape(rgb_wide) != (wide_camera.height_px, wide_camera.width_px, 3):
        raise InvalidInputError("rgb_wide", np.shape(rgb_wide), "(H, W, 3) of wide_camera")
    source = _source_pixels(wide_camera, camera)  # (H, W, 2)
    u0 = np.minimum(np.floor(source[..., 0]).astype(int), wide_camera.width_px - 2)
    v0 = np.minimum(np.floor(source[..., 1]).astype(int), wide_camera.height_px - 2)
    du, dv = (source[..., 0] - u0)[..., None], (source[..., 1] - v0)[..., None]  # (H, W, 1)
    image = np.asarray(rgb_wide, dtype=float)
    mixed = ((1 - dv) * ((1 - du) * image[v0, u0] + du * image[v0, u0 + 1])
             + dv * ((1 - du) * image[v0 + 1, u0] + du * image[v0 + 1, u0 + 1]))  # (H, W, 3)
    return np.clip(np.rint(mixed), 0, 255).astype(np.uint8)


def distort_depth(depth_wide_m: np.ndarray, wide_camera: PinholeCamera,
                  camera: PinholeCamera) -> np.ndarray:
    """The depth image registered to the distorted colour image, nearest neighbour, float32.

    Nearest, not bilinear: blending a near and a far surface at an edge invents depths where
    no surface is (a floating skirt of points the planner would take for an obstacle).
    """
    if np.shape(depth_wide_m) != (wide_camera.height_px, wide_camera.width_px):
        raise InvalidInputError("depth_wide_m", np.shape(depth_wide_m), "(H, W) of wide_camera")
    source = np.rint(_source_pixels(wide_camera, camera)).astype(int)  # (H, W, 2)
    return np.asarray(depth_wide_m, dtype=np.float32)[source[..., 1], source[..., 0]]


def _hidden_from(depth_m: np.ndarray, focal_px: float, offset_m: float) -> np.ndarray:
    """Pixels whose surface a camera ``offset_m`` along x (image right) cannot see, (H, W).

    Per row (rectified stereo), the other camera sees pixel u at s = u - f b / Z; a surface is
    hidden when a nearer one lands at or past it there: for b > 0, some pixel to its right
    with a smaller s (a reversed running minimum). b < 0 is the mirror image.
    """
    if offset_m < 0.0:
        return _hidden_from(depth_m[:, ::-1], focal_px, -offset_m)[:, ::-1]
    valid = np.isfinite(depth_m) & (depth_m > 0.0)
    u = np.arange(depth_m.shape[1], dtype=float)
    s = np.where(valid, u - focal_px * offset_m / np.where(valid, depth_m, 1.0), np.inf)
    right_min = np.minimum.accumulate(s[:, ::-1], axis=1)[:, ::-1]  # min over u' >= u
    beyond = np.concatenate([right_min[:, 1:], np.full((len(s), 1), np.inf)], axis=1)
    return valid & (beyond < s - 1e-9)


def invalid_depth_edges(depth_m: np.ndarray, camera: PinholeCamera,
                        config: D435Config) -> np.ndarray:
    """Depth (H, W) with 0.0 where a stereo imager cannot see the surface (the shadow).

    The depth origin (left imager) and the right imager sit ``left_imager_x_m`` and
    ``left_imager_x_m + baseline_m`` to the colour camera's right, so the shadow falls on the
    far side left of each near edge, f * b * (1/Z_near - 1/Z_far) px wide, f this image's
    horizontal focal length (the disparity, scaled to this image by its f).
    """
    depth = np.asarray(depth_m, dtype=np.float32)
    focal_px = float(camera.K[0, 0])
    hidden = _hidden_from(depth, focal_px, config.left_imager_x_m) | _hidden_from(
        depth, focal_px, config.left_imager_x_m + config.baseline_m)
    return np.where(hidden, np.float32(0.0), depth)


def depth_noise(depth_m: np.ndarray, camera: PinholeCamera, rng: np.random.Generator,
                config: D435Config) -> np.ndarray:
    """What the D435 reports for a true depth image (H, W) [m]: float32, 0.0 where invalid.

    Gaussian noise of Intel's sigma(Z), then 1 mm steps; invalid (0.0) where the truth had no
    depth, nearer than the minimum range, or outside either imager's field of view (the
    left-edge band, f B / Z px wide in the depth image).
    """
    depth = np.asarray(depth_m, dtype=float)
    if depth.shape != (camera.height_px, camera.width_px):
        raise InvalidInputError("depth_m", depth.shape, f"shape ({camera.height_px}, "
                                f"{camera.width_px})")
    valid = np.isfinite(depth) & (depth > 0.0)
    z = np.where(valid, depth, 1.0)
    noisy = z + config.depth_sigma_m(z) * rng.standard_normal(z.shape)
    quantised = np.rint(noisy / config.depth_unit_m) * config.depth_unit_m
    x_over_z = _x_over_z(camera)  # (H, W)
    tan_half = config.depth_tan_half_hfov
    in_view = np.ones(z.shape, dtype=bool)
    for offset_m in (config.left_imager_x_m, config.left_imager_x_m + config.baseline_m):
        seen_x = x_over_z - offset_m / z
        in_view &= (seen_x >= -tan_half) & (seen_x <= tan_half)
    keep = valid & in_view & (z >= config.min_range_m) & (quantised > 0.0)
    return np.where(keep, quantised, 0.0).astype(np.float32)


@functools.lru_cache(maxsize=16)
def _x_over_z(camera: PinholeCamera) -> np.ndarray:
    """Each pixel's ray as x / z of the optical frame (undistorted), (H, W), read-only."""
    u, v = np.meshgrid(np.arange(camera.width_px), np.arange(camera.height_px))
    rays = camera.rays(np.stack([u.ravel(), v.ravel()], axis=1))  # (H W, 3)
    x_over_z = (rays @ camera.T_world_camera[:3, 0]).reshape(camera.height_px, camera.width_px)
    x_over_z.flags.writeable = False  # ray's z is 1
    return x_over_z


def colour_noise(rgb: np.ndarray, rng: np.random.Generator, config: D435Config) -> np.ndarray:
    """The image with shot-limited read noise: sigma = sqrt(I * 255) / SNR_max, uint8.

    At full scale the SNR is the sensor's maximum; below, noise falls as sqrt of the signal.
    """
    image = np.asarray(rgb, dtype=float)
    snr = 10.0 ** (config.colour_snr_max_db / 20.0)
    sigma = np.sqrt(np.maximum(image, 0.0) * 255.0) / snr
    return np.clip(np.rint(image + sigma * rng.standard_normal(image.shape)), 0, 255).astype(
        np.uint8)


def calibration_error(rng: np.random.Generator, config: D435Config) -> CalibrationError:
    """A seeded pose error: Gaussian per axis, RMS magnitude the published hand-eye accuracy."""
    translation = rng.standard_normal(3) * config.hand_eye_translation_rms_m / math.sqrt(3)
    rotation = rng.standard_normal(3) * config.hand_eye_rotation_rms_rad / math.sqrt(3)
    return CalibrationError(tuple(float(v) for v in translation),  # type: ignore[arg-type]
                            tuple(float(v) for v in rotation))  # type: ignore[arg-type]


def _rotation_matrix(rotation_vector: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotation (3, 3) of a rotation vector [rad]."""
    angle = float(np.linalg.norm(rotation_vector))
    if angle == 0.0:
        return np.eye(3)
    k = rotation_vector / angle
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * cross + (1 - math.cos(angle)) * cross @ cross


def true_camera(calibrated: PinholeCamera, error: CalibrationError) -> PinholeCamera:
    """The camera as it really stands (what the renderer uses); the model keeps ``calibrated``."""
    optical = calibrated.T_world_camera[:3, :3]
    rotation = optical @ _rotation_matrix(np.asarray(error.rotation_rad)) @ optical.T  # world
    position = np.asarray(calibrated.position_m) + np.asarray(error.translation_m)
    axis = rotation @ (np.asarray(calibrated.target_m) - np.asarray(calibrated.position_m))
    return replace(calibrated, position_m=tuple(position), target_m=tuple(position + axis),
                   up=tuple(rotation @ np.asarray(calibrated.up)))


__all__ = ["CalibrationError", "D435Config", "calibration_error", "colour_noise", "depth_noise",
           "distort_depth", "distort_image", "invalid_depth_edges", "true_camera",
           "wide_camera_for"]
