import numpy as np
import pytest

from sim.errors import InvalidInputError
from sim.paper_world import (
    PAPER_OBJECT_TYPES,
    PAPER_WORKSPACE_X_M,
    PAPER_WORKSPACE_Y_M,
    PaperWorld,
)


@pytest.fixture(scope="module")
def world():
    with PaperWorld() as w:
        yield w


@pytest.mark.parametrize("object_type", PAPER_OBJECT_TYPES)
def test_objects_stand_about_10_cm_wide_resting_and_still(world, object_type):
    world.reset_scene()
    body = world.add_object(object_type, (0.03, -0.04), 0.0)
    world.settle()
    low, high = (np.array(v) for v in world.client.getAABB(body))
    assert 0.08 <= max(high[:2] - low[:2]) <= 0.125
    # Resting on the table top; a convex mesh's bounding box carries PyBullet's ~3 mm margin.
    assert abs(low[2]) < 0.005
    before = world.object_position_m(body)
    assert np.linalg.norm(before[:2] - np.array([0.03, -0.04])) < 0.01  # label = where placed
    for _ in range(240):
        world.client.stepSimulation()
    assert np.linalg.norm(world.object_position_m(body) - before) < 0.002


def test_the_duck_stands_upright(world):
    world.reset_scene()
    body = world.add_object("duck", (0.0, 0.0), 0.0)
    low, high = (np.array(v) for v in world.client.getAABB(body))
    assert high[2] - low[2] > (high[1] - low[1])  # taller than deep: not lying on its side


@pytest.mark.parametrize("x", PAPER_WORKSPACE_X_M)
@pytest.mark.parametrize("y", PAPER_WORKSPACE_Y_M)
def test_an_object_at_each_workspace_corner_is_wholly_in_the_image(world, x, y):
    for object_type in PAPER_OBJECT_TYPES:
        world.reset_scene()
        body = world.add_object(object_type, (x, y), 0.8)
        low, high = world.client.getAABB(body)
        corners = np.array([[a, b, c] for a in (low[0], high[0]) for b in (low[1], high[1])
                            for c in (low[2], high[2])])
        pixels = world.camera.project(corners)
        assert pixels.min() >= 0.0 and pixels.max() <= 127.0


def test_render_and_darker_light(world):
    world.reset_scene()
    world.add_object("mug", (0.0, 0.0), 0.0)
    bright, dim = world.render(), world.render(0.3)
    assert bright.shape == (128, 128, 3) and bright.dtype == np.uint8
    assert dim.mean() < 0.6 * bright.mean()


def test_unknown_type_lists_the_allowed_ones_and_reset_removes_objects(world):
    with pytest.raises(InvalidInputError, match=r"object type = 'sponge' is not allowed: one "
                       r"of duck, soccer_ball, mug"):
        world.add_object("sponge", (0.0, 0.0), 0.0)
    world.add_object("mug", (0.0, 0.0), 0.0)
    world.reset_scene()
    assert world.objects == {}
