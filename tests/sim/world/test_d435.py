"""The D435-like sensor: lens remap agrees with the calibration, depth noise, holes, pose error."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from perception.camera import PinholeCamera
from sim.world.d435 import (
    D435Config,
    calibration_error,
    colour_noise,
    depth_noise,
    distort_depth,
    distort_image,
    invalid_depth_edges,
    true_camera,
    wide_camera_for,
)

CONFIG = D435Config()


def _camera(distortion: tuple[float, ...] = CONFIG.colour_distortion_k1_k2_p1_p2_k3,
            horizontal_fov_deg: float = 58.0) -> PinholeCamera:
    return PinholeCamera((0.09, 0.0, 0.52), (0.49, 0.0, 0.0), (0.0, 0.0, 1.0), 37.0,
                         horizontal_fov_deg, 128, 128, distortion)  # type: ignore[arg-type]


@pytest.mark.parametrize("k1", [CONFIG.colour_distortion_k1_k2_p1_p2_k3[0], -0.08])
def test_remapped_dots_land_where_the_calibration_projects_them(k1: float) -> None:
    camera = _camera((k1, 0.0, 0.0, 0.0, 0.0))
    wide = wide_camera_for(camera)
    targets = np.array([[5.0, 4.0], [122.0, 4.0], [5.0, 121.0], [122.0, 121.0], [64.0, 63.0],
                        [30.0, 90.0]])  # corners and inside, (N, 2)
    points = np.asarray(camera.position_m) + 0.55 * camera.rays(targets)  # world, (N, 3)
    u, v = np.meshgrid(np.arange(wide.width_px), np.arange(wide.height_px))
    image = np.zeros((wide.height_px, wide.width_px))
    for cu, cv in wide.project(points):  # a sub-pixel Gaussian dot per point
        image += 255.0 * np.exp(-((u - cu) ** 2 + (v - cv) ** 2) / (2 * 1.2**2))
    rgb = np.repeat(np.clip(image, 0, 255)[..., None], 3, axis=2).astype(np.uint8)
    seen = distort_image(rgb, wide, camera)[..., 0].astype(float)
    uu, vv = np.meshgrid(np.arange(128), np.arange(128))
    for expected in camera.project(points):
        window = (np.abs(uu - expected[0]) < 5) & (np.abs(vv - expected[1]) < 5)
        weight = np.where(window, seen, 0.0)
        found = np.array([(weight * uu).sum(), (weight * vv).sum()]) / weight.sum()
        assert np.linalg.norm(found - expected) < 0.5 * (0.5 if k1 > -0.05 else 1.0), expected
    ideal = dataclasses.replace(camera, distortion_k1_k2_p1_p2_k3=(0.0,) * 5)
    if k1 < -0.05:  # the test can tell a lens from none: the corners move by more than 0.5 px
        assert np.linalg.norm(ideal.project(points[:1]) - camera.project(points[:1])) > 0.5


def test_depth_remap_is_nearest_neighbour() -> None:
    camera = _camera((-0.08, 0.0, 0.0, 0.0, 0.0))
    wide = wide_camera_for(camera)
    depth = np.where(np.arange(wide.width_px) < wide.width_px // 2, 0.7, 0.4)
    out = distort_depth(np.tile(depth, (wide.height_px, 1)), wide, camera)
    assert out.dtype == np.float32 and set(np.unique(out)) <= {np.float32(0.7), np.float32(0.4)}


@pytest.mark.parametrize("depth_m", [0.45, 0.65])
def test_depth_noise_on_a_flat_target_matches_intels_sigma(depth_m: float) -> None:
    camera = _camera()
    rng = np.random.default_rng(7)
    measured = np.concatenate([depth_noise(np.full((128, 128), depth_m), camera, rng, CONFIG)
                               .ravel() for _ in range(4)])
    assert (measured > 0).all()
    expected = float(CONFIG.depth_sigma_m(np.array(depth_m)))
    assert abs(measured.std() / expected - 1.0) < 0.15
    assert abs(measured.mean() - depth_m) < 0.2e-3


def test_depth_is_quantised_to_a_millimetre_and_invalid_is_zero() -> None:
    camera = _camera()
    depth = np.full((128, 128), 0.5)
    depth[:10] = 0.1  # nearer than the minimum range (0.17 m)
    depth[10:20, :5], depth[20:30, :5], depth[30:40, :5] = np.nan, np.inf, 0.0
    out = depth_noise(depth, camera, np.random.default_rng(0), CONFIG)
    assert out.dtype == np.float32 and np.isfinite(out).all() and (out >= 0).all()
    assert (out[:10] == 0).all() and (out[10:40, :5] == 0).all() and (out[40:] > 0).all()
    millimetres = out[40:].astype(float) * 1000
    assert np.abs(millimetres - np.rint(millimetres)).max() < 1e-3


def test_left_band_is_invalid_where_the_right_imager_cannot_see() -> None:
    camera = _camera(horizontal_fov_deg=100.0)  # wider than the depth imagers (89.6 deg)
    out = depth_noise(np.full((128, 128), 0.3), camera, np.random.default_rng(0), CONFIG)
    rays = camera.rays(np.stack([np.arange(128.0), np.full(128, 63.0)], axis=1))
    x_over_z = rays @ camera.T_world_camera[:3, 0]
    right_imager = x_over_z - (CONFIG.left_imager_x_m + CONFIG.baseline_m) / 0.3
    left_imager = x_over_z - CONFIG.left_imager_x_m / 0.3
    tan = CONFIG.depth_tan_half_hfov
    expected = (right_imager >= -tan) & (left_imager <= tan)
    assert not expected[0] and expected[64]
    np.testing.assert_array_equal(out[63] > 0, expected)
    assert (depth_noise(np.full((128, 128), 0.45), _camera(), np.random.default_rng(0),
                        CONFIG) > 0).all()  # the head camera's crop never sees the band


def test_stereo_shadow_falls_left_of_a_near_edge() -> None:
    camera = _camera()
    near_right = np.full((8, 128), 0.7, dtype=np.float32)
    near_right[:, 64:] = 0.4
    out = invalid_depth_edges(near_right, camera, CONFIG)
    width = camera.K[0, 0] * (CONFIG.left_imager_x_m + CONFIG.baseline_m) * (1 / 0.4 - 1 / 0.7)
    zeros = np.flatnonzero(out[0] == 0)
    assert zeros.max() == 63 and abs(len(zeros) - width) <= 1.0
    assert (out[:, 64:] == 0.4).all() and (out[:, : 63 - int(width) - 1] == 0.7).all()
    assert (invalid_depth_edges(near_right[:, ::-1], camera, CONFIG) > 0).all()  # far side right


def test_colour_noise_follows_the_snr() -> None:
    rgb = np.full((128, 128, 3), 128, dtype=np.uint8)
    noisy = colour_noise(rgb, np.random.default_rng(0), CONFIG)
    expected = np.sqrt(128 * 255.0) / 10 ** (CONFIG.colour_snr_max_db / 20)
    assert noisy.dtype == np.uint8 and abs(noisy.astype(float).std() / expected - 1) < 0.1
    assert np.array_equal(noisy, colour_noise(rgb, np.random.default_rng(0), CONFIG))


def test_calibration_error_is_seeded_and_of_the_published_size() -> None:
    errors = [calibration_error(np.random.default_rng(seed), CONFIG) for seed in range(2000)]
    assert calibration_error(np.random.default_rng(3), CONFIG) == errors[3]
    translation = np.array([e.translation_m for e in errors])
    rotation = np.array([e.rotation_rad for e in errors])
    rms_t = np.sqrt((translation**2).sum(axis=1).mean())
    rms_r = np.sqrt((rotation**2).sum(axis=1).mean())
    assert abs(rms_t / CONFIG.hand_eye_translation_rms_m - 1) < 0.1
    assert abs(rms_r / CONFIG.hand_eye_rotation_rms_rad - 1) < 0.1


def test_true_camera_moves_by_the_error() -> None:
    camera = _camera()
    error = calibration_error(np.random.default_rng(0), CONFIG)
    moved = true_camera(camera, error)
    np.testing.assert_allclose(np.subtract(moved.position_m, camera.position_m),
                               error.translation_m, atol=1e-15)
    relative = camera.T_world_camera[:3, :3].T @ moved.T_world_camera[:3, :3]
    angle = np.arccos(np.clip((np.trace(relative) - 1) / 2, -1, 1))
    assert abs(angle - np.linalg.norm(error.rotation_rad)) < 1e-9
    point = np.array([[0.45, 0.1, 0.02]])
    assert 0.0 < np.linalg.norm(moved.project(point) - camera.project(point)) < 5.0
