"""Looks applied to the world: colours, textures, the table, a lamp's colour, a moved mount."""

from __future__ import annotations

import math

import numpy as np
import pytest

from perception.objects.catalog import SPONGE, get_object_spec
from robots.yumi import YUMI
from sim.errors import InvalidInputError
from sim.world.head_camera import CameraConfig, HeadCamera, camera_config
from sim.world.lighting import Lighting
from sim.world.looks import (
    LightLook,
    MountOffset,
    ObjectLook,
    kelvin_rgb,
    lighting_for,
    moved_camera,
    planck_xy,
    rgb_from_hex,
)
from sim.world.textures import SIZE_PX, TextureKind, texture_file, texture_image
from sim.world.yumi_world import World

WHERE = (0.47, 0.0)


def picture(look: ObjectLook | None = None, table: str | None = None,
            lighting: Lighting | None = None, config: CameraConfig | None = None) -> np.ndarray:
    with World(robot=YUMI) as world:
        world.add_object(SPONGE, WHERE, 0.0, look)
        if table is not None:
            world.dress_table(table)
        camera = HeadCamera(camera_config(YUMI) if config is None else config)  # the YuMi's
        return camera.render(world.client, lighting)


@pytest.fixture(scope="module")
def today() -> np.ndarray:
    return picture()


def sponge_pixels(image: np.ndarray, today: np.ndarray) -> np.ndarray:
    """The pixels where an empty table differs from today's picture: the sponge's."""
    with World(robot=YUMI) as world:
        empty = HeadCamera(camera_config(YUMI)).render(world.client)
    return np.abs(today.astype(int) - empty).sum(axis=2) > 30


def test_the_catalog_look_is_todays_picture(today):
    assert np.array_equal(picture(ObjectLook()), today)
    assert np.array_equal(picture(table="wood"), today)


def test_a_colourway_paints_each_part(today):
    # Each part its own colour: the sponge's yellow body red, its green scourer blue. Parts
    # swapped, or one colour for both, fails (issue 79: both parts had taken the same pink).
    mask = sponge_pixels(today, today)
    body = mask & (today[..., 0].astype(int) > today[..., 2].astype(int) + 60)  # yellow today
    pad = mask & (today[..., 1].astype(int) > today[..., 0].astype(int) + 20)  # green today
    assert body.sum() > 20 and pad.sum() > 20
    painted = picture(ObjectLook(("#e01010", "#1010e0"))).astype(int)
    assert (painted[body][:, 0] > painted[body][:, 2] + 40).mean() > 0.9  # the body red
    assert (painted[pad][:, 2] > painted[pad][:, 0] + 40).mean() > 0.9  # the pad blue
    assert np.array_equal(painted[~mask], today[~mask])  # only the sponge changed


def test_a_texture_patterns_the_colour(today):
    mask = sponge_pixels(today, today)
    plain = picture(ObjectLook(("#ffd700", "#ffd700")))
    striped = picture(ObjectLook(("#ffd700", "#ffd700"), TextureKind.STRIPES, 3))
    assert striped[mask].astype(float).std(axis=0).sum() > plain[mask].astype(float).std(
        axis=0).sum() + 10


def test_a_table_look_changes_the_table_not_the_sponge(today):
    black = picture(table="black")
    mask = sponge_pixels(today, today)
    assert black[~mask].mean() < today[~mask].mean() - 80
    with pytest.raises(InvalidInputError, match="table look = 'granite' is not allowed"):
        picture(table="granite")


def test_a_warm_lamp_renders_warmer_than_daylight(today):
    base = camera_config(YUMI).lighting
    warm = picture(lighting=lighting_for(base, LightLook(36.87, 63.43, 2700.0, 0.6, 0.5)))
    red_over_blue = (warm[..., 0].mean() / warm[..., 2].mean(),
                     today[..., 0].mean() / today[..., 2].mean())
    assert red_over_blue[0] > red_over_blue[1] * 1.2


def test_the_drawn_default_light_is_the_cameras_own(today):
    base = camera_config(YUMI).lighting
    same = lighting_for(base, LightLook(math.degrees(math.atan2(0.3, 0.4)),
                                        math.degrees(math.atan2(1.0, 0.5)), None, 0.6, 0.5))
    assert np.allclose(np.asarray(same.direction) / np.linalg.norm(same.direction),
                       np.asarray(base.direction) / np.linalg.norm(base.direction))
    assert np.abs(picture(lighting=same).astype(int) - today).max() <= 2


def test_the_planckian_locus_meets_the_cie_illuminants():
    # CIE 15:2004: illuminant A (2856 K) at (0.4476, 0.4074); D65's CCT 6504 K near (0.3127,
    # 0.3290), which lies 0.003 off the locus (a daylight, not a black body).
    assert np.allclose(planck_xy(2856.0), (0.4476, 0.4074), atol=1e-3)
    assert np.allclose(planck_xy(6504.0), (0.3135, 0.3237), atol=1e-3)
    assert kelvin_rgb(6504.0) == pytest.approx((1.0, 1.0, 1.0))
    warm, cold = kelvin_rgb(2700.0), kelvin_rgb(9000.0)
    assert warm[0] == 1.0 and warm[2] < 0.5 and cold[2] == 1.0 and cold[0] < 1.0
    with pytest.raises(InvalidInputError, match=r"colour_temperature_k = 1000\.0 is not allowed"):
        kelvin_rgb(1000.0)


def test_a_moved_mount_moves_what_the_camera_sees():
    config = camera_config(YUMI)
    point = np.array([[0.47, 0.0, 0.0]])
    still = HeadCamera(config).project(point)[0]
    assert moved_camera(config, None) is config
    shifted = HeadCamera(moved_camera(config, MountOffset((0.0, 0.02, 0.0), 0.0, 0.0))
                         ).project(point)[0]
    assert shifted[0] > still[0] + 2  # the camera moved left (+y): the point moves right
    tilted = HeadCamera(moved_camera(config, MountOffset((0.0, 0.0, 0.0), 0.0,
                                                         math.radians(3.0)))).project(point)[0]
    assert tilted[1] < still[1] - 3  # the camera looks further down: the point rises


def test_textures_are_seeded_files_in_the_patterns_range(tmp_path, monkeypatch):
    monkeypatch.setenv("GVA_TEXTURES", str(tmp_path))
    for kind in (TextureKind.PRINT, TextureKind.STRIPES, TextureKind.NOISE):
        image = texture_image(kind, 2)
        assert image.shape == (SIZE_PX, SIZE_PX, 3) and image.min() >= 114 and image.max() == 255
        assert np.array_equal(image, texture_image(kind, 2))
        assert not np.array_equal(image, texture_image(kind, 3))
        assert texture_file(kind, 2).parent == tmp_path
    with pytest.raises(InvalidInputError, match="texture variant = 8 is not allowed"):
        texture_image(TextureKind.PRINT, 8)


def test_a_look_with_the_wrong_number_of_colours_is_refused():
    with World(robot=YUMI) as world, pytest.raises(InvalidInputError, match=r"mug look colours = "
                                         r"\['#000000', '#ffffff'\] is not allowed: 1 colours"):
        world.add_object(get_object_spec("mug"), WHERE, 0.0, ObjectLook(("#000000", "#ffffff")))
    assert rgb_from_hex("#FF8000") == (1.0, 128 / 255, 0.0)
