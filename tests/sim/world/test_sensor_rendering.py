"""The head camera through its sensor: ideal frames as before, D435 frames seeded and true-posed."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pybullet
import pytest
from scipy import ndimage

from robots import yumi
from robots.yumi import YUMI
from sim.errors import InvalidInputError
from sim.world.d435 import D435Config
from sim.world.head_camera import CameraConfig, HeadCamera, camera_config
from sim.world.lighting import Lighting
from sim.world.sensor import SensorConfig, SensorKind, SensorSeed
from sim.world.yumi_world import World

MOUNT = YUMI.camera
"""The YuMi head camera's mount: the camera these tests render through."""
HEAD = camera_config(YUMI)
"""The YuMi head camera (its mount, the D435-like image)."""

RADIUS_M = 0.012
SPOTS_PX = ((64.0, 64.0), (14.0, 108.0), (112.0, 16.0))  # the centre and two far corners
D435 = SensorConfig(SensorKind.D435)
# A sensor whose mount and lens are far off and whose noise is the least a D435's could be
# (sim.world.d435.PLAUSIBLE: 0.01 px, 60 dB; depth noise 0.1 mm, colour 0.2 levels), so both
# show in pixels.
OFF = SensorConfig(SensorKind.D435, D435Config(
    hand_eye_translation_rms_m=0.01, hand_eye_rotation_rms_rad=math.radians(2.0),
    colour_distortion_k1_k2_p1_p2_k3=(-0.1, 0.0, 0.0, 0.0, 0.0), subpixel_rms_px=0.01,
    colour_snr_max_db=60.0))


def _on_table(uv: tuple[float, float], height_m: float) -> np.ndarray:
    """The point at ``height_m`` the calibrated camera sees at pixel ``uv``."""
    nominal = HEAD.pinhole
    ray = nominal.rays(np.array([uv]))[0]
    origin = np.asarray(nominal.position_m)
    return origin + ray * (height_m - origin[2]) / ray[2]


@pytest.fixture(scope="module")
def world():
    """The yumi world at HOME with a red ball at the centre and near two corners of the image."""
    world = World(robot=YUMI)
    world.reset_scene(yumi.HOME)
    centres = np.array([_on_table(uv, 0.03) for uv in SPOTS_PX])
    for centre in centres:
        shape = world.client.createVisualShape(pybullet.GEOM_SPHERE, radius=RADIUS_M,
                                               rgbaColor=[1, 0, 0, 1])
        world.client.createMultiBody(baseMass=0, baseVisualShapeIndex=shape,
                                     basePosition=list(centre))
    world.centres = centres
    yield world
    world.close()


def _old_frame(camera: HeadCamera, client, light: Lighting) -> tuple[np.ndarray, np.ndarray]:
    """The frame as HeadCamera.render_rgbd made it before sensors existed (its code, verbatim)."""
    c = camera.config
    _, _, rgba, buffer, _ = client.getCameraImage(
        c.width_px, c.height_px, camera.view_matrix, camera.projection_matrix,
        lightDirection=list(light.direction), lightColor=[light.brightness] * 3,
        lightAmbientCoeff=light.ambient_coeff * light.brightness,
        lightDiffuseCoeff=light.diffuse_coeff, lightSpecularCoeff=light.specular_coeff,
        shadow=int(light.shadows), renderer=pybullet.ER_TINY_RENDERER)
    image = np.asarray(rgba, dtype=np.uint8).reshape(c.height_px, c.width_px, 4)
    buffer = np.asarray(buffer, dtype=np.float64).reshape(c.height_px, c.width_px)
    with np.errstate(divide="ignore"):
        depth = c.far_m * c.near_m / (c.far_m - (c.far_m - c.near_m) * buffer)
    return image[:, :, :3], np.where(buffer >= 1.0, np.inf, depth).astype(np.float32)


def _blobs(mask: np.ndarray) -> np.ndarray:
    """Centroids (u, v) of the balls ``mask`` shows, sorted as SPOTS_PX is (nearest spot)."""
    labels, count = ndimage.label(mask)
    assert count == len(SPOTS_PX)
    found = np.array([(u, v) for v, u in ndimage.center_of_mass(mask, labels,
                                                                range(1, count + 1))])
    order = [int(np.argmin(np.linalg.norm(found - np.array(spot), axis=1))) for spot in SPOTS_PX]
    return found[order]


def _red_blobs(rgb: np.ndarray) -> np.ndarray:
    """Centroids (u, v) of the red balls in a colour image."""
    image = rgb.astype(int)
    return _blobs((image[..., 0] > 150) & (image[..., 1] < 60) & (image[..., 2] < 60))


def test_the_ideal_sensor_renders_bit_for_bit_as_before(world):
    dim = Lighting(brightness=0.5)
    for camera in (HeadCamera(HEAD), HeadCamera(HEAD, sensor=SensorConfig())):
        for light, seed in ((None, None), (dim, SensorSeed(4, 1, 2, 1))):
            frame = camera.render_rgbd(world.client, light, seed)  # an ideal one ignores seeds
            rgb, depth = _old_frame(camera, world.client, light or camera.config.lighting)
            assert np.array_equal(frame.rgb, rgb) and frame.rgb.dtype == np.uint8
            assert np.array_equal(frame.depth_m, depth) and frame.depth_m.dtype == np.float32
            assert frame.camera == camera.pinhole == HEAD.pinhole


def test_d435_frames_are_the_same_for_a_seed_and_differ_for_another(world):
    seed = SensorSeed(seed=0, stream=1, index=2, frame=0)
    first = HeadCamera(HEAD, sensor=D435).render_rgbd(world.client, seed=seed)
    again = HeadCamera(HEAD, sensor=D435).render_rgbd(world.client, seed=seed)  # a fresh camera
    assert np.array_equal(first.rgb, again.rgb) and np.array_equal(first.depth_m, again.depth_m)
    for other in (replace(seed, frame=1), replace(seed, index=3), replace(seed, stream=0)):
        frame = HeadCamera(HEAD, sensor=D435).render_rgbd(world.client, seed=other)
        assert not np.array_equal(frame.rgb, first.rgb)
        assert not np.array_equal(frame.depth_m, first.depth_m)
    camera = HeadCamera(HEAD, sensor=D435)
    assert camera.mount_error(0) == camera.mount_error(0) != camera.mount_error(1)
    assert camera.true_camera(0) != camera.true_camera(1)


def test_d435_depth_is_the_sensors_millimetres_with_zero_where_it_has_none(world):
    frame = HeadCamera(HEAD, sensor=D435).render_rgbd(world.client, seed=SensorSeed())
    depth = frame.depth_m.astype(float)
    valid = depth > 0.0
    assert np.isfinite(depth).all() and 0.9 < valid.mean() < 1.0  # shadows left of the balls
    assert np.allclose(depth[valid] * 1000.0, np.rint(depth[valid] * 1000.0), atol=1e-3)


def test_a_d435_frame_needs_its_seed(world):
    with pytest.raises(InvalidInputError, match=r"seed = None is not allowed: a SensorSeed"):
        HeadCamera(HEAD, sensor=D435).render_rgbd(world.client)


def test_the_frame_keeps_the_calibration_while_the_image_follows_the_true_camera(world):
    camera = HeadCamera(HEAD, sensor=OFF)
    frame = camera.render_rgbd(world.client, seed=SensorSeed(seed=3))
    nominal, true = frame.camera, camera.true_camera(3)
    assert nominal == HEAD.pinhole and not nominal.is_distorted  # factory: zeros
    assert true.is_distorted and true.position_m != nominal.position_m
    seen = _red_blobs(frame.rgb)  # (3, 2)
    through_true = true.project(world.centres)
    assert np.abs(seen - through_true).max() < 0.5  # the true pose and lens, to the subpixel
    off_px = np.linalg.norm(nominal.project(world.centres) - seen, axis=1)
    assert (off_px > 2.0).all()  # the calibration is off by the mount error (a few px here)
    assert np.allclose(off_px, np.linalg.norm(nominal.project(world.centres) - through_true,
                                              axis=1), atol=0.5)
    lensless = replace(true, distortion_k1_k2_p1_p2_k3=(0.0,) * 5).project(world.centres)
    bent_px = np.linalg.norm(lensless[1:] - seen[1:], axis=1)  # the corners, by the lens
    assert (bent_px > 1.0).all()
    assert (bent_px > 2.0 * np.linalg.norm(through_true[1:] - seen[1:], axis=1)).all()
    # depth from the true pose too: the ball's near side along the true optical axis
    v, u = np.rint(through_true[0, ::-1]).astype(int)
    along_axis = (world.centres[0] - true.position_m) @ true.T_world_camera[:3, 2]
    assert abs(frame.depth_m[v, u] - (along_axis - RADIUS_M)) < 0.002


def _near_blobs(depth_m: np.ndarray, table_m: np.ndarray) -> np.ndarray:
    """Centroids (u, v) of what stands 1 cm or more off the table in ``depth_m``."""
    return _blobs((depth_m > 0.0) & (depth_m < table_m - 0.01))


def test_d435_depth_lines_up_with_its_distorted_colour_through_the_lens(world):
    """Each ball's depth blob lies where its colour blob is, at the corners too (issue 65).

    The lens (k1 = -0.1 here) moves the corner balls by pixels; a depth image registered by
    anything but the same lens map (a central crop of the wide render, say) lands them apart.
    """
    camera = HeadCamera(HEAD, sensor=OFF)
    frame = camera.render_rgbd(world.client, seed=SensorSeed(seed=3))
    true = camera.true_camera(3)
    rays = true.rays(np.array([(u, v) for v in range(true.height_px)
                               for u in range(true.width_px)], dtype=float))  # (H W, 3)
    axis = true.T_world_camera[:3, 2]
    origin = np.asarray(true.position_m)
    table_m = ((-origin[2] / rays[:, 2])[:, None] * rays @ axis).reshape(
        true.height_px, true.width_px)  # the table plane's depth along the axis, per pixel
    colour, depth = _red_blobs(frame.rgb), _near_blobs(frame.depth_m, table_m)
    assert np.abs(colour - depth).max() < 0.75, (colour, depth)


def test_the_camera_record_names_the_sensor_and_its_parameters():
    ideal, d435 = HeadCamera(HEAD).record(), HeadCamera(HEAD, sensor=OFF).record()
    assert ideal["sensor"] == {"sensor": "ideal"}
    assert d435["sensor"]["sensor"] == "d435" and d435["sensor"]["subpixel_rms_px"] == 0.01
    assert d435["sensor"]["colour_distortion_k1_k2_p1_p2_k3"] == [-0.1, 0.0, 0.0, 0.0, 0.0]
    assert CameraConfig.from_json(d435) == HEAD  # the config reads past the sensor


def test_a_lens_that_folds_the_image_is_refused_by_field():
    folding = SensorConfig(SensorKind.D435, D435Config(
        colour_distortion_k1_k2_p1_p2_k3=(-2.0, 0.0, 0.0, 0.0, 0.0)))
    with pytest.raises(InvalidInputError, match=r"camera\.colour_distortion_k1_k2_p1_p2_k3 = "
                       r"\(-2\.0, 0\.0, 0\.0, 0\.0, 0\.0\) is not allowed: a distortion"):
        HeadCamera(HEAD, sensor=folding)
