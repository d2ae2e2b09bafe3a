"""Lens distortion in the calibrated camera: project and rays inverse, zeros bit-identical."""

from __future__ import annotations

import json

import numpy as np
import pytest

from perception.camera import PinholeCamera, RgbdFrame
from perception.errors import InvalidInputError

LENS = (-0.0237, 0.01, 0.0005, -0.0003, 0.002)


def _camera(distortion: tuple[float, ...] = (0.0,) * 5) -> PinholeCamera:
    return PinholeCamera((0.09, 0.0, 0.52), (0.49, 0.0, 0.0), (0.0, 0.0, 1.0), 37.0, 58.0,
                         128, 128, distortion)  # type: ignore[arg-type]


def _old_project(camera: PinholeCamera, points: np.ndarray) -> np.ndarray:
    """The ideal pinhole's arithmetic as it was before distortion existed."""
    local = (points - np.asarray(camera.position_m)) @ camera.world_from_camera
    depth = np.where(-local[:, 2] > 1e-9, -local[:, 2], np.nan)
    tan_x, tan_y = camera.tan_half_fov
    return np.stack(camera.ndc_to_pixels(local[:, 0] / depth / tan_x,
                                         local[:, 1] / depth / tan_y), axis=1)


def _old_rays(camera: PinholeCamera, pixels: np.ndarray) -> np.ndarray:
    ndc_x, ndc_y = camera.pixels_to_ndc(pixels[:, 0], pixels[:, 1])
    tan_x, tan_y = camera.tan_half_fov
    local = np.stack([ndc_x * tan_x, ndc_y * tan_y, -np.ones(len(pixels))], axis=1)
    return local @ camera.world_from_camera.T


def test_zero_distortion_is_bit_identical_to_the_pinhole() -> None:
    camera, rng = _camera(), np.random.default_rng(1)
    points = rng.uniform([0.2, -0.3, -0.1], [0.7, 0.3, 0.3], (1000, 3))
    pixels = rng.uniform(-5.0, 133.0, (1000, 2))
    assert np.array_equal(camera.project(points), _old_project(camera, points))
    assert np.array_equal(camera.rays(pixels), _old_rays(camera, pixels))
    assert "distortion_k1_k2_p1_p2_k3" not in camera.to_json()


def test_rays_and_project_are_inverse_to_a_micro_pixel() -> None:
    camera = _camera(LENS)
    u, v = np.meshgrid(np.linspace(-0.5, 127.5, 33), np.linspace(-1.5, 126.5, 33))
    pixels = np.stack([u.ravel(), v.ravel()], axis=1)
    back = camera.project(np.asarray(camera.position_m) + 0.6 * camera.rays(pixels))
    assert np.abs(back - pixels).max() < 1e-6


def test_distortion_moves_the_corners_not_the_centre() -> None:
    ideal, bent = _camera(), _camera((-0.0237, 0.0, 0.0, 0.0, 0.0))
    centre = np.asarray(ideal.position_m) + ideal.rays(np.array([[64.0, 63.0]]))
    corner = np.asarray(ideal.position_m) + ideal.rays(np.array([[0.0, 0.0]]))
    assert np.abs(bent.project(centre) - ideal.project(centre)).max() < 1e-9
    shift = bent.project(corner) - ideal.project(corner)
    assert 0.4 < np.linalg.norm(shift) < 1.5 and shift[0, 0] > 0 and shift[0, 1] > 0  # barrel


def test_record_round_trips_and_old_records_load() -> None:
    camera = _camera(LENS)
    record = json.loads(json.dumps(camera.to_json()))
    assert PinholeCamera.from_json(record) == camera
    old = _camera().to_json()
    assert PinholeCamera.from_json(old).distortion_k1_k2_p1_p2_k3 == (0.0,) * 5


@pytest.mark.parametrize("coefficients", [(float("nan"), 0, 0, 0, 0), (0.1, 0.2),
                                          (-2.0, 0.0, 0.0, 0.0, 0.0)])
def test_bad_coefficients_name_the_field(coefficients: tuple[float, ...]) -> None:
    with pytest.raises(InvalidInputError, match="distortion_k1_k2_p1_p2_k3"):
        _camera(coefficients)


def test_a_pixel_without_a_measurement_is_an_unknown_ray_and_one_seeing_nothing_is_not():
    camera = _camera((-0.0237, 0.0, 0.0, 0.0, 0.0))
    depth = np.full((camera.height_px, camera.width_px), 0.6, dtype=np.float32)
    depth[5, 7] = 0.0  # no measurement: unknown
    depth[9, 2] = np.inf  # nothing within range: free
    frame = RgbdFrame(np.zeros((*depth.shape, 3), np.uint8), depth, camera)
    rays = frame.unknown_rays()
    assert rays.shape == (1, 3)
    np.testing.assert_allclose(rays, camera.rays(np.array([[7.0, 5.0]])))
    assert np.isnan(frame.points_world()[5, 7]).all() and np.isnan(frame.points_world()[9, 2]).all()
