"""The ray readout: a target's pose read off its attention point through the calibrated camera.

The KQV model's head (``KqvConfig.readout = "ray"``) gives per target a height, an offset and a
rotation from the attended feature; :class:`CameraRays` places the target where the ray through
the attention point meets that height, so the image-to-world mapping is the camera's, not
something 20 demonstrations must teach an MLP. A calibration that carries its lens's distortion
is read through it: rays are undistorted, projections distorted, differentiably.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from perception.camera import PinholeCamera
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
        if (camera.height_px, camera.width_px) != (spec.image_height_px, spec.image_width_px):
            raise InvalidInputError("camera", f"{camera.width_px} x {camera.height_px} px",
                                    f"the images' {spec.image_width_px} x "
                                    f"{spec.image_height_px} px for readout 'ray'")
        self.camera = camera
        tangents = torch.tensor(camera.tan_half_fov, dtype=torch.float32)  # (2,)
        basis = torch.tensor(camera.world_from_camera, dtype=torch.float32)  # (3, 3)
        origin = torch.tensor(camera.position_m, dtype=torch.float32)  # (3,)
        self.register_buffer("tangents", tangents, persistent=False)  # rebuilt from the spec
        self.register_buffer("basis", basis, persistent=False)
        self.register_buffer("origin", origin, persistent=False)

    def read(self, coords: Tensor, out: Tensor, scaler: LabelScaler) -> tuple[Tensor, Tensor]:
        """Targets from points (B, q, 2) in [-1, 1] and head outputs (B, q, 4): height, offset.

        Returns positions (B, q, 3) in the scaler's units and the turns (B, q, 3, 3) about z
        toward each point's bearing, which take the head's rotations to the world frame.
        """
        camera = self.camera
        pixels = normalised_to_pixels(coords, camera.height_px, camera.width_px)  # (B, q, 2)
        ndc_x, ndc_y = camera.pixels_to_ndc(pixels[..., 0], pixels[..., 1])  # (B, q) each
        x, y = ndc_x * self.tangents[0], ndc_y * self.tangents[1]  # y up
        if camera.is_distorted:
            x, y_down = undistorted(camera, x, -y)  # the lens works in the optical frame
            y = -y_down
        local = torch.stack([x, y, -torch.ones_like(x)], dim=-1)  # (B, q, 3), camera frame
        direction = local @ self.basis.T  # (B, q, 3), world frame
        centre = out.new_tensor(scaler.centre_m)  # (3,)
        height_m = centre[2] + scaler.scale_m * out[..., 0]  # (B, q)
        down = direction[..., 2].clamp(max=-1e-3)  # (B, q); rays that miss the plane do not
        point = self.origin + direction * ((height_m - self.origin[2]) / down)[..., None]
        bearing = torch.atan2(point[..., 1], point[..., 0])  # (B, q)
        cos, sin, zero, one = (bearing.cos(), bearing.sin(), torch.zeros_like(bearing),
                               torch.ones_like(bearing))
        turn = torch.stack([cos, -sin, zero, sin, cos, zero, zero, zero, one],
                           dim=-1).unflatten(-1, (3, 3))  # (B, q, 3, 3) about z
        offset_m = scaler.scale_m * (turn @ out[..., 1:4, None])[..., 0]  # (B, q, 3)
        positions = (point + offset_m - centre) / scaler.scale_m  # (B, q, 3)
        return positions, turn

    def project(self, points_m: Tensor) -> Tensor:
        """Where world points (..., 3) [m] appear: normalised image (x, y) in [-1, 1], (..., 2).

        The inverse of the ray: a target's grasp point projected so, the point its attention
        should sit on (:attr:`~perception.models.kqv_config.KqvConfig.point_loss_weight`).
        Points behind the camera stay finite (their depth is clamped to 1 mm).
        """
        camera = self.camera
        local = (points_m - self.origin) @ self.basis  # (..., 3), camera frame
        depth = (-local[..., 2]).clamp(min=1e-3)  # (...)
        x, y = local[..., 0] / depth, local[..., 1] / depth  # y up
        if camera.is_distorted:
            x, y_down = camera.distort(x, -y)  # the lens works in the optical frame
            y = -y_down
        u_px, v_px = camera.ndc_to_pixels(x / self.tangents[0], y / self.tangents[1])
        return pixels_to_normalised(torch.stack([u_px, v_px], dim=-1), camera.height_px,
                                    camera.width_px)  # (..., 2)
