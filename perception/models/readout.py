"""The ray readout: a target's pose read off its attention point through the calibrated camera.

The KQV model's head (``KqvConfig.readout = "ray"``) gives per target a height, an offset and a
rotation from the attended feature; :class:`CameraRays` places the target where the ray through
the attention point meets that height, so the image-to-world mapping is the camera's, not
something 20 demonstrations must teach an MLP. A calibration that carries its lens's distortion
is read through it: rays are undistorted, projections distorted, differentiably.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple, TypeVar, cast

import torch
from torch import Tensor, nn

from perception.camera import Calibrations, PinholeCamera
from perception.interface import InvalidInputError
from perception.learning.learnable import ModelSpec
from perception.learning.torch_pieces import LabelScaler, normalised_to_pixels, pixels_to_normalised

UNDISTORT_STEPS = 6
"""Newton steps that undo the lens in the readout: a fixed count keeps it one graph for
autograd; from the distorted point, a lens as strong as the D435's converges in three."""


def undistorted(camera: PinholeCamera, x_d: Tensor, y_d: Tensor) -> tuple[Tensor, Tensor]:
    """The optical-frame point (x right, y down) the lens maps to ``(x_d, y_d)``.

    A tensor form of :meth:`~perception.camera.PinholeCamera.undistort`.
    """
    x, y = x_d, y_d
    for _ in range(UNDISTORT_STEPS):
        fx, fy = camera.distort(x, y)
        ex, ey = fx - x_d, fy - y_d
        (dxx, dxy), (dyx, dyy) = camera.distortion_jacobian(x, y)
        det = dxx * dyy - dxy * dyx
        x, y = x - (dyy * ex - dxy * ey) / det, y - (dxx * ey - dyx * ex) / det
    return x, y


class CameraRays(nn.Module):
    """The ray readout: a target's pose from its attention point, through the calibrated camera.

    The head's output per target begins ``(height, offset (3))`` in network units; the target is
    where the point's ray meets the plane z = height, plus the offset, which, like the grasp's
    rotation the head gives after them, is expressed in the frame turned about z toward that
    point's bearing from the world origin (the robot base).

    Each sample is read through its own calibration where one is given (``cameras``: a trial
    frame's, a dataset sample's): a camera bumped and re-calibrated after training then costs
    nothing, since the ray through a pixel is the camera's to say, not the weights'. Without
    one, through the camera the model was trained with (the spec's), to the bit as before.
    """

    tangents: Tensor  # (2,) tan of the half fields of view, horizontal and vertical
    basis: Tensor  # (3, 3) world from camera
    origin: Tensor  # (3,) the optical centre [m]

    def __init__(self, spec: ModelSpec) -> None:
        super().__init__()
        camera = spec.camera
        if camera is None:
            raise InvalidInputError("readout", "ray", "'mlp' or 'auto' for a dataset that "
                                    "records no camera")
        self.image_px = (spec.image_height_px, spec.image_width_px)
        self.camera = check_calibration(camera, *self.image_px)
        tangents, basis, origin = _geometry(camera, torch.device("cpu"))
        self.register_buffer("tangents", tangents, persistent=False)  # rebuilt from the spec
        self.register_buffer("basis", basis, persistent=False)
        self.register_buffer("origin", origin, persistent=False)

    def read(self, coords: Tensor, out: Tensor, scaler: LabelScaler,
             cameras: Calibrations = None, range_m: Tensor | None = None
             ) -> tuple[Tensor, Tensor]:
        """Targets from points (B, q, 2) in [-1, 1] and head outputs (B, q, 4): height, offset.

        ``cameras``: each sample's calibration (B of them), or None: the spec's for all.
        ``range_m`` (B, q): where the frame's depth measures how far along the optical axis the
        attended surface lies (:func:`attended_range`; NaN where it measured nothing), the
        point is there on the ray instead of at the head's height. Returns positions (B, q, 3)
        in the scaler's units and the turns (B, q, 3, 3) about z toward each point's bearing,
        which take the head's rotations to the world frame.
        """
        def one(camera: PinholeCamera, rows: slice | Tensor) -> tuple[Tensor, Tensor]:
            return self._read(camera, self._tensors(camera, coords.device), coords[rows],
                              out[rows], scaler, None if range_m is None else range_m[rows])

        return _per_camera(one, self.camera, cameras, len(coords))

    def project(self, points_m: Tensor, cameras: Calibrations = None) -> Tensor:
        """Where world points (B, ..., 3) [m] appear: normalised (x, y) in [-1, 1], (B, ..., 2).

        The inverse of the ray: a target's grasp point projected so, the point its attention
        should sit on (:attr:`~perception.models.kqv_config.KqvConfig.point_loss_weight`).
        Points behind the camera stay finite (their depth is clamped to 1 mm). ``cameras`` as
        :meth:`read` takes them (one per leading row of ``points_m``).
        """
        def one(camera: PinholeCamera, rows: slice | Tensor) -> tuple[Tensor]:
            return (self._project(camera, self._tensors(camera, points_m.device),
                                  points_m[rows]),)

        return _per_camera(one, self.camera, cameras, len(points_m))[0]

    def _tensors(self, camera: PinholeCamera, device: torch.device) -> _Geometry:
        """The tensors of ``camera``: the spec's buffers for the spec's own (bit-identical)."""
        if camera == self.camera:
            return _Geometry(self.tangents, self.basis, self.origin)
        return _geometry(check_calibration(camera, *self.image_px), device)

    @staticmethod
    def _read(camera: PinholeCamera, geometry: _Geometry, coords: Tensor, out: Tensor,
              scaler: LabelScaler, range_m: Tensor | None = None) -> tuple[Tensor, Tensor]:
        """:meth:`read` through one camera."""
        tangents, basis, origin = geometry
        pixels = normalised_to_pixels(coords, camera.height_px, camera.width_px)  # (B, q, 2)
        ndc_x, ndc_y = camera.pixels_to_ndc(pixels[..., 0], pixels[..., 1])  # (B, q) each
        x, y = ndc_x * tangents[0], ndc_y * tangents[1]  # y up
        if camera.is_distorted:
            x, y_down = undistorted(camera, x, -y)  # the lens works in the optical frame
            y = -y_down
        local = torch.stack([x, y, -torch.ones_like(x)], dim=-1)  # (B, q, 3), camera frame
        direction = local @ basis.T  # (B, q, 3), world frame
        centre = out.new_tensor(scaler.centre_m)  # (3,)
        height_m = centre[2] + scaler.scale_m * out[..., 0]  # (B, q)
        down = direction[..., 2].clamp(max=-1e-3)  # (B, q); rays that miss the plane do not
        point = origin + direction * ((height_m - origin[2]) / down)[..., None]
        if range_m is not None:  # a unit of ``direction`` is a metre along the optical axis
            measured = torch.isfinite(range_m)[..., None]  # (B, q, 1)
            point = torch.where(measured, origin + direction * range_m.nan_to_num()[..., None],
                                point)
        bearing = torch.atan2(point[..., 1], point[..., 0])  # (B, q)
        cos, sin, zero, one = (bearing.cos(), bearing.sin(), torch.zeros_like(bearing),
                               torch.ones_like(bearing))
        turn = torch.stack([cos, -sin, zero, sin, cos, zero, zero, zero, one],
                           dim=-1).unflatten(-1, (3, 3))  # (B, q, 3, 3) about z
        offset_m = scaler.scale_m * (turn @ out[..., 1:4, None])[..., 0]  # (B, q, 3)
        positions = (point + offset_m - centre) / scaler.scale_m  # (B, q, 3)
        return positions, turn

    @staticmethod
    def _project(camera: PinholeCamera, geometry: _Geometry, points_m: Tensor) -> Tensor:
        """:meth:`project` through one camera."""
        tangents, basis, origin = geometry
        local = (points_m - origin) @ basis  # (..., 3), camera frame
        depth = (-local[..., 2]).clamp(min=1e-3)  # (...)
        x, y = local[..., 0] / depth, local[..., 1] / depth  # y up
        if camera.is_distorted:
            x, y_down = camera.distort(x, -y)  # the lens works in the optical frame
            y = -y_down
        u_px, v_px = camera.ndc_to_pixels(x / tangents[0], y / tangents[1])
        return pixels_to_normalised(torch.stack([u_px, v_px], dim=-1), camera.height_px,
                                    camera.width_px)  # (..., 2)


def attended_range(heatmaps: Tensor, depths_m: Tensor) -> Tensor:
    """How far along the optical axis each head's attended surface lies: (B, q) [m], NaN: unknown.

    The heatmap-weighted mean of the frame's depth (B, H, W) over the pixels that measured one
    (a D435 gives 0 in its holes and stereo shadows, an ideal camera inf where it sees nothing):
    the range the camera measures at the attention, its noise averaged over the attended
    pixels. A head whose heatmap (B, q, h, w) weighs less than :data:`RANGE_MIN_WEIGHT` on
    measured pixels gets NaN, and is read at its head's height instead.
    """
    height, width = heatmaps.shape[-2:]
    valid = (torch.isfinite(depths_m) & (depths_m > 0)).to(heatmaps.dtype)[:, None]  # (B,1,H,W)
    depth = torch.where(valid > 0, depths_m[:, None].to(heatmaps.dtype), 0.0)  # (B, 1, H, W)
    cell_valid = nn.functional.adaptive_avg_pool2d(valid, (height, width))  # (B, 1, h, w)
    cell_sum = nn.functional.adaptive_avg_pool2d(depth, (height, width))  # (B, 1, h, w)
    weight = (heatmaps * cell_valid).sum(dim=(-2, -1))  # (B, q)
    total = (heatmaps * cell_sum).sum(dim=(-2, -1))  # (B, q): sum of M x mean depth x share
    return torch.where(weight >= RANGE_MIN_WEIGHT, total / weight.clamp(min=RANGE_MIN_WEIGHT),
                       torch.nan)


RANGE_MIN_WEIGHT = 0.5
"""The least share of a heatmap on pixels with depth for its range to be read off them: below
it, the attention lies mostly on holes (a D435's shadow beside a tall object) and one stray
pixel would decide the range."""


class _Geometry(NamedTuple):
    """One camera's geometry as the readout computes with it."""

    tangents: Tensor  # (2,) tan of the half fields of view, horizontal and vertical
    basis: Tensor  # (3, 3) world from camera
    origin: Tensor  # (3,) the optical centre [m]


def _geometry(camera: PinholeCamera, device: torch.device) -> _Geometry:
    return _Geometry(torch.tensor(camera.tan_half_fov, dtype=torch.float32, device=device),
                     torch.tensor(camera.world_from_camera, dtype=torch.float32, device=device),
                     torch.tensor(camera.position_m, dtype=torch.float32, device=device))


def check_calibration(camera: Any, height_px: int, width_px: int) -> PinholeCamera:
    """``camera`` if it calibrates the model's ``height_px`` x ``width_px`` images, else an error.

    Its pose and lens may be any (a camera moved and re-calibrated); its image size must be the
    model's, whose attention points are pixels of that image.
    """
    if not isinstance(camera, PinholeCamera):
        raise InvalidInputError("camera", type(camera).__name__, "a PinholeCamera (a frame's "
                                "calibration)")
    if (camera.height_px, camera.width_px) != (height_px, width_px):
        raise InvalidInputError("camera", f"{camera.width_px} x {camera.height_px} px",
                                f"the images' {width_px} x {height_px} px for readout 'ray'")
    return camera


_Parts = TypeVar("_Parts", bound=tuple[Tensor, ...])


def _per_camera(read: Callable[[PinholeCamera, slice | Tensor], _Parts], own: PinholeCamera,
                cameras: Calibrations, batch: int) -> _Parts:
    """``read`` through each sample's camera, grouped: one call per distinct calibration.

    A batch seen through one camera (every frame of a still mount, or ``cameras`` None: the
    model's ``own``) is one call over all rows; otherwise the rows of each camera are read
    together and put back in batch order.
    """
    if cameras is None:
        return read(own, slice(None))
    if len(cameras) != batch:
        raise InvalidInputError("cameras", f"{len(cameras)} calibrations",
                                f"one per sample of the batch ({batch})")
    rows: dict[PinholeCamera, list[int]] = {}
    for index, camera in enumerate(cameras):
        rows.setdefault(camera, []).append(index)
    if len(rows) == 1:
        return read(cameras[0], slice(None))
    order = [index for indices in rows.values() for index in indices]
    back = torch.empty(batch, dtype=torch.long)
    back[order] = torch.arange(batch)
    parts = [read(camera, torch.tensor(indices)) for camera, indices in rows.items()]
    return cast(_Parts, tuple(torch.cat(group)[back.to(group[0].device)]
                              for group in zip(*parts, strict=True)))
