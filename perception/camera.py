"""The pinhole geometry of the camera a dataset was taken with: world points to pixels and back.

A dataset's metadata records its camera (``camera``: where it is, where it looks, its field of
view and image size, plus lighting that geometry ignores). :class:`PinholeCamera` is that record's
geometry, with the conventions of OpenGL's ``gluLookAt`` and ``gluPerspective`` (which PyBullet's
``computeViewMatrix`` and ``computeProjectionMatrixFOV`` follow) and of the images: pixel
``(u, v)``, u right and v down, integer coordinates at pixel centres (``image[v, u]``). The
simulator projects with it (:meth:`sim.world.head_camera.HeadCamera.project`), and a perception
model may read positions off it: a calibrated camera is what a real robot has too.
:class:`RgbdFrame` is one image of such a camera with its depth, as an RGB-D camera (the YuMi's
RealSense D435) gives it; :meth:`PinholeCamera.points_from_depth` turns the depth into points in
the world.

A real lens bends rays: ``distortion_k1_k2_p1_p2_k3`` holds OpenCV's Brown-Conrady coefficients
(radial k1, k2, k3; tangential p1, p2) on the normalised coordinates x = X/Z, y = Y/Z of the
optical frame (:attr:`PinholeCamera.T_world_camera`, x right, y down). ``project`` distorts,
``rays`` undistorts; all zeros (the default) is the ideal pinhole, computed exactly as before
the field existed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from perception.errors import InvalidInputError

_DISTORTION = "distortion_k1_k2_p1_p2_k3"
_FIELDS = ("position_m", "target_m", "up", "vertical_fov_deg", "horizontal_fov_deg",
           "width_px", "height_px", _DISTORTION)
_OPTIONAL = ("horizontal_fov_deg", _DISTORTION)  # None: square px; absent: no distortion
_REQUIRED = tuple(name for name in _FIELDS if name not in _OPTIONAL)
_NO_DISTORTION = (0.0, 0.0, 0.0, 0.0, 0.0)
# Undistortion is Newton's method from the distorted point: quadratic convergence takes a 1.5 %
# lens from ~1e-2 to below 1e-12 (normalised; < 1e-9 px at any focal length here) in 4 steps.
_UNDISTORT_MAX_STEPS = 12
_UNDISTORT_TOLERANCE = 1e-13
# Monotonicity is checked over the image and this much beyond it (the wide render's margin).
_DISTORTION_CHECK_SPAN = 1.25


def _floats(value: Any) -> tuple[float, ...]:
    """``value``'s numbers as floats, or () unless it is a list or tuple of real numbers only.

    A record from elsewhere (a served request) may hold strings or None where numbers belong:
    those are refused by the caller's check, by name, not by ``float``'s own exception.
    """
    if not isinstance(value, list | tuple) or not all(
            isinstance(v, int | float | np.floating | np.integer) and not isinstance(v, bool)
            for v in value):
        return ()
    return tuple(float(v) for v in value)


@dataclass(frozen=True)
class PinholeCamera:
    """A camera's geometry (world frame, [m] and [deg]); see the module docstring.

    Args:
        position_m: Optical centre.
        target_m: A point on the optical axis.
        up: The world direction that appears up in the image.
        vertical_fov_deg: Vertical field of view.
        horizontal_fov_deg: Horizontal field of view; None: square pixels (the horizontal field
            follows the image's aspect).
        width_px: Image width.
        height_px: Image height.
        distortion_k1_k2_p1_p2_k3: OpenCV's Brown-Conrady coefficients (k1, k2, p1, p2, k3) on
            the normalised coordinates of the optical frame; zeros: an ideal pinhole.

    """

    position_m: tuple[float, float, float]
    target_m: tuple[float, float, float]
    up: tuple[float, float, float]
    vertical_fov_deg: float
    horizontal_fov_deg: float | None
    width_px: int
    height_px: int
    distortion_k1_k2_p1_p2_k3: tuple[float, float, float, float, float] = _NO_DISTORTION

    def __post_init__(self) -> None:
        for name in ("position_m", "target_m", "up"):
            value = getattr(self, name)
            vector = _floats(value)
            if len(vector) != 3 or not all(math.isfinite(v) for v in vector):
                raise InvalidInputError(name, value, "three finite numbers")
            object.__setattr__(self, name, vector)
        for name in ("vertical_fov_deg", "horizontal_fov_deg"):
            value = getattr(self, name)
            if value is None and name == "horizontal_fov_deg":
                continue
            if not isinstance(value, int | float) or not 0.0 < value < 180.0:
                raise InvalidInputError(name, value, "a field of view in (0, 180) deg")
        for name in ("width_px", "height_px"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise InvalidInputError(name, value, "an integer >= 1")
        axis = np.subtract(self.target_m, self.position_m)
        if np.linalg.norm(axis) < 1e-6:
            raise InvalidInputError("target_m", self.target_m, "a point away from position_m")
        if np.linalg.norm(np.cross(axis, self.up)) < 1e-6 * np.linalg.norm(axis):
            raise InvalidInputError("up", self.up, "a direction not along the optical axis")
        self._check_distortion()

    def _check_distortion(self) -> None:
        """Five finite coefficients whose distortion is one-to-one over the image (and beyond)."""
        value = self.distortion_k1_k2_p1_p2_k3
        coefficients = _floats(value)
        if len(coefficients) != 5 or not all(math.isfinite(v) for v in coefficients):
            raise InvalidInputError(_DISTORTION, value, "five finite numbers (k1, k2, p1, p2, k3)")
        object.__setattr__(self, _DISTORTION, coefficients)
        if not self.is_distorted:
            return
        tan_x, tan_y = self.tan_half_fov
        grid = np.linspace(-_DISTORTION_CHECK_SPAN, _DISTORTION_CHECK_SPAN, 81)
        x, y = np.meshgrid(grid * tan_x, grid * tan_y)
        (dxx, dxy), (dyx, dyy) = self.distortion_jacobian(x, y)
        k1, k2, _, _, k3 = coefficients
        r2 = x * x + y * y
        radial_slope = 1 + 3 * k1 * r2 + 5 * k2 * r2**2 + 7 * k3 * r2**3  # d(r R(r)) / dr
        if not ((dxx * dyy - dxy * dyx > 0.0).all() and (radial_slope > 0.0).all()):
            raise InvalidInputError(
                _DISTORTION, coefficients, "a distortion that is monotonic over the image and "
                f"{_DISTORTION_CHECK_SPAN - 1:.0%} beyond it (it folds the image there)")

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> PinholeCamera:
        """The geometry of a recorded camera (a dataset's ``metadata.camera``); extras ignored."""
        if not isinstance(data, Mapping):
            raise InvalidInputError("camera", type(data).__name__, "a mapping")
        missing = [name for name in _REQUIRED if name not in data]
        if missing:
            raise InvalidInputError("camera", f"without {', '.join(missing)}",
                                    f"a camera record with {', '.join(_FIELDS)}")
        values: dict[str, Any] = {name: data.get(name) for name in _FIELDS
                                  if name in data or name not in _OPTIONAL}
        values.setdefault("horizontal_fov_deg", None)
        return cls(**values)

    @classmethod
    def from_record(cls, data: Mapping[str, Any]) -> PinholeCamera | None:
        """As :meth:`from_json`, but None for a record without the geometry.

        A synthetic dataset's record, for one, is empty: its model simply has no camera.
        """
        return cls.from_json(data) if all(name in data for name in _REQUIRED) else None

    def to_json(self) -> dict[str, Any]:
        """JSON-able fields, as :meth:`from_json` reads them.

        The distortion is written only when there is one, so an ideal camera's record is the
        same as before the field existed.
        """
        names = _FIELDS if self.is_distorted else tuple(n for n in _FIELDS if n != _DISTORTION)
        return {name: list(v) if isinstance(v := getattr(self, name), tuple) else v
                for name in names}

    @property
    def is_distorted(self) -> bool:
        """Whether the lens distorts (any coefficient non-zero)."""
        return any(v != 0.0 for v in self.distortion_k1_k2_p1_p2_k3)

    def distort(self, x: Any, y: Any) -> tuple[Any, Any]:
        """Normalised coordinates of the optical frame (x right, y down) through the lens.

        Plain arithmetic: numpy arrays and torch tensors alike (a model's readout distorts).
        """
        k1, k2, p1, p2, k3 = self.distortion_k1_k2_p1_p2_k3
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        return (x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y)

    def undistort(self, x_d: np.ndarray, y_d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The inverse of :meth:`distort`, by Newton's method (converged to 1e-13, see above)."""
        x, y = np.array(x_d, dtype=float), np.array(y_d, dtype=float)
        for _ in range(_UNDISTORT_MAX_STEPS):
            fx, fy = self.distort(x, y)
            ex, ey = fx - x_d, fy - y_d
            if not (np.nanmax(np.abs(ex), initial=0.0) > _UNDISTORT_TOLERANCE
                    or np.nanmax(np.abs(ey), initial=0.0) > _UNDISTORT_TOLERANCE):
                break
            (dxx, dxy), (dyx, dyy) = self.distortion_jacobian(x, y)
            det = dxx * dyy - dxy * dyx
            x, y = x - (dyy * ex - dxy * ey) / det, y - (dxx * ey - dyx * ex) / det
        return x, y

    def distortion_jacobian(self, x: Any, y: Any) -> tuple[tuple[Any, Any], tuple[Any, Any]]:
        """((dxd/dx, dxd/dy), (dyd/dx, dyd/dy)) of :meth:`distort` (numpy or torch alike)."""
        k1, k2, p1, p2, k3 = self.distortion_k1_k2_p1_p2_k3
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        slope = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r2
        return ((radial + 2.0 * x * x * slope + 2.0 * p1 * y + 6.0 * p2 * x,
                 2.0 * x * y * slope + 2.0 * p1 * x + 2.0 * p2 * y),
                (2.0 * x * y * slope + 2.0 * p1 * x + 2.0 * p2 * y,
                 radial + 2.0 * y * y * slope + 6.0 * p1 * y + 2.0 * p2 * x))

    @property
    def tan_half_fov(self) -> tuple[float, float]:
        """Tangents of the half fields of view, (horizontal, vertical)."""
        vertical = math.tan(math.radians(self.vertical_fov_deg) / 2)
        if self.horizontal_fov_deg is None:
            return vertical * self.width_px / self.height_px, vertical
        return math.tan(math.radians(self.horizontal_fov_deg) / 2), vertical

    @property
    def world_from_camera(self) -> np.ndarray:
        """Rotation (3, 3): the camera's right, up and backward axes (columns) in the world.

        OpenGL's convention: the camera looks along its -z.
        """
        forward = np.subtract(self.target_m, self.position_m)
        forward = forward / np.linalg.norm(forward)
        right = np.cross(forward, self.up)
        right = right / np.linalg.norm(right)
        return np.stack([right, np.cross(right, forward), -forward], axis=1)

    @property
    def image_size_px(self) -> tuple[int, int]:
        """(width, height) of the camera's images [px]."""
        return self.width_px, self.height_px

    @property
    def K(self) -> np.ndarray:
        """The intrinsic matrix (3, 3), OpenCV's convention, for this module's pixels.

        ``K @ p_camera / p_camera[2]`` is the pixel (u, v, 1) of a point in the optical frame
        of :attr:`T_world_camera`; it equals :meth:`project` for an undistorted camera (with
        distortion, OpenCV's convention: K applies to the distorted normalised coordinates).
        """
        tan_x, tan_y = self.tan_half_fov
        u0, v0 = self.ndc_to_pixels(0.0, 0.0)
        return np.array([[0.5 * self.width_px / tan_x, 0.0, u0],
                         [0.0, 0.5 * self.height_px / tan_y, v0],
                         [0.0, 0.0, 1.0]])

    @property
    def T_world_camera(self) -> np.ndarray:
        """The camera's pose in the world (4, 4): its optical frame, OpenCV's (and ROS's).

        x right and y down in the image, z forward along the optical axis; the origin at the
        optical centre.
        """
        right, up, backward = self.world_from_camera.T
        transform = np.eye(4)
        transform[:3, :3] = np.stack([right, -up, -backward], axis=1)
        transform[:3, 3] = self.position_m
        return transform

    def project(self, points_world: np.ndarray) -> np.ndarray:
        """Pixel coordinates (u right, v down) of world points, (N, 3) -> (N, 2).

        Points at or behind the optical centre's plane get NaN. The lens distortion applies.
        """
        points = np.atleast_2d(np.asarray(points_world, dtype=float))
        if points.ndim != 2 or points.shape[1] != 3:
            raise InvalidInputError("points_world", np.shape(points_world), "shape (N, 3)")
        local = (points - np.asarray(self.position_m)) @ self.world_from_camera  # (N, 3)
        depth = np.where(-local[:, 2] > 1e-9, -local[:, 2], np.nan)  # (N,)
        tan_x, tan_y = self.tan_half_fov
        if not self.is_distorted:  # the ideal pinhole's arithmetic, unchanged to the last bit
            ndc_x, ndc_y = local[:, 0] / depth / tan_x, local[:, 1] / depth / tan_y
            return np.stack(self.ndc_to_pixels(ndc_x, ndc_y), axis=1)
        x_d, y_d = self.distort(local[:, 0] / depth, -local[:, 1] / depth)  # optical frame, y down
        return np.stack(self.ndc_to_pixels(x_d / tan_x, -y_d / tan_y), axis=1)

    def ndc_to_pixels(self, ndc_x: Any, ndc_y: Any) -> tuple[Any, Any]:
        """Normalised device coordinates (x right, y up, [-1, 1] at the image's edges) to pixels.

        Works on numpy arrays and torch tensors alike. PyBullet's software renderer samples
        column i at x = i and rasterises rows bottom-up before flipping them; the offsets here
        put its pixel centres on integers (checked against rendered markers: within 0.3 px).
        """
        return (ndc_x + 1.0) * 0.5 * self.width_px, (1.0 - ndc_y) * 0.5 * self.height_px - 1.0

    def pixels_to_ndc(self, u_px: Any, v_px: Any) -> tuple[Any, Any]:
        """The inverse of :meth:`ndc_to_pixels`."""
        return 2.0 * u_px / self.width_px - 1.0, 1.0 - 2.0 * (v_px + 1.0) / self.height_px

    def rays(self, points_px: np.ndarray) -> np.ndarray:
        """World directions (N, 3), not normalised, of the rays through pixels (N, 2).

        The ray through pixel p is ``position_m + t * rays(p)`` for t > 0; t = 1 reaches the
        plane one unit in front of the camera. The lens distortion is undone.
        """
        points = np.atleast_2d(np.asarray(points_px, dtype=float))
        if points.ndim != 2 or points.shape[1] != 2:
            raise InvalidInputError("points_px", np.shape(points_px), "shape (N, 2)")
        ndc_x, ndc_y = self.pixels_to_ndc(points[:, 0], points[:, 1])
        tan_x, tan_y = self.tan_half_fov
        if self.is_distorted:
            x, y = self.undistort(ndc_x * tan_x, -ndc_y * tan_y)  # optical frame, y down
            local = np.stack([x, -y, -np.ones(len(points))], axis=1)
        else:  # the ideal pinhole's arithmetic, unchanged to the last bit
            local = np.stack([ndc_x * tan_x, ndc_y * tan_y, -np.ones(len(points))], axis=1)
        return local @ self.world_from_camera.T  # (N, 3)

    def points_from_depth(self, depth_m: np.ndarray) -> np.ndarray:
        """World points (H, W, 3) of a depth image (H, W) of this camera; NaN where no depth.

        Depth is the distance along the optical axis [m] (a RealSense's depth image, not the
        length of the ray); a pixel without a return holds 0, NaN or inf.
        """
        depth = np.asarray(depth_m, dtype=float)
        if depth.shape != (self.height_px, self.width_px):
            raise InvalidInputError("depth_m", f"shape {depth.shape}",
                                    f"shape ({self.height_px}, {self.width_px})")
        u_px, v_px = np.meshgrid(np.arange(self.width_px), np.arange(self.height_px))
        rays = self.rays(np.stack([u_px.ravel(), v_px.ravel()], axis=1))  # (H W, 3)
        valid = np.isfinite(depth) & (depth > 0.0)
        along = np.where(valid, depth, np.nan).reshape(-1, 1)  # (H W, 1)
        points = np.asarray(self.position_m) + along * rays  # (H W, 3)
        return points.reshape(self.height_px, self.width_px, 3)


@dataclass(frozen=True, eq=False)
class RgbdFrame:
    """One RGB-D image and the calibrated camera that took it.

    Args:
        rgb: (H, W, 3) uint8 colour image, row 0 at the top.
        depth_m: (H, W) float32 depth along the optical axis [m]. Two kinds of "none": 0 is
            no measurement (a RealSense's invalid pixel: a stereo shadow, too near; what lies
            along that ray is unknown), inf is nothing within the camera's range (the ray is
            free as far as it reaches).
        camera: The camera's geometry (intrinsics and pose in the world).
        robot_mask: (H, W) bool, the pixels that show the robot itself, which a self-filtered
            frame blanked (no depth, the table's colour): what the robot knows its own body
            hides. None: a frame not self-filtered.

    """

    rgb: np.ndarray  # (H, W, 3) uint8
    depth_m: np.ndarray  # (H, W) float32
    camera: PinholeCamera
    robot_mask: np.ndarray | None = None  # (H, W) bool

    def __post_init__(self) -> None:
        size = (self.camera.height_px, self.camera.width_px)
        if not isinstance(self.rgb, np.ndarray) or self.rgb.dtype != np.uint8 or \
                self.rgb.shape != (*size, 3):
            raise InvalidInputError("rgb", f"{getattr(self.rgb, 'dtype', '')} "
                                    f"{np.shape(self.rgb)}", f"uint8 of shape ({size[0]}, "
                                    f"{size[1]}, 3)")
        if np.shape(self.depth_m) != size:
            raise InvalidInputError("depth_m", f"shape {np.shape(self.depth_m)}",
                                    f"shape {size}")
        if self.robot_mask is not None and (
                np.shape(self.robot_mask) != size
                or getattr(self.robot_mask, "dtype", None) != np.bool_):
            raise InvalidInputError("robot_mask", f"{getattr(self.robot_mask, 'dtype', '')} "
                                    f"{np.shape(self.robot_mask)}", f"None or bool of shape {size}")

    def points_world(self) -> np.ndarray:
        """The depth image's points in the world, (H, W, 3); NaN where no depth."""
        return self.camera.points_from_depth(self.depth_m)

    def unknown_rays(self) -> np.ndarray:
        """World directions (K, 3) of the rays of the pixels without a measurement (depth 0).

        A planner that treats unseen space as occupied needs them: nothing is known along
        them (:mod:`control.depth_obstacles`).
        """
        v_px, u_px = np.nonzero(np.asarray(self.depth_m) == 0.0)
        if not len(u_px):
            return np.zeros((0, 3))
        return self.camera.rays(np.stack([u_px, v_px], axis=1).astype(float))


Calibrations = Sequence[PinholeCamera] | None
"""Each image's calibration, in batch order (a trial frame's, a dataset sample's), for a model
that reads positions through the camera (``ModelInput.CAMERA``); None: the camera it was trained
with."""
