"""The paper's simulator scene: object sizes and poses, resting, labels, framing, rendering."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from sim.errors import InvalidInputError
from sim.world.paper_world import (
    PAPER_OBJECT_TYPES,
    PAPER_WORKSPACE_X_M,
    PAPER_WORKSPACE_Y_M,
    PaperWorld,
)

# The up axis of each mesh in its URDF frame: duck.obj lies on its side (y up), mug.obj is z-up.
MESH_UP = {"duck": (0.0, 1.0, 0.0), "mug": (0.0, 0.0, 1.0)}
YAWS_RAD = (0.0, 0.8, 2.5, -1.7)


@pytest.fixture(scope="module")
def world() -> Iterator[PaperWorld]:
    with PaperWorld() as w:
        yield w


def _aabb(world: PaperWorld, body: int) -> tuple[np.ndarray, np.ndarray]:
    low, high = world.client.getAABB(body)
    return np.array(low), np.array(high)


def _gap_to_table_m(world: PaperWorld, body: int) -> float:
    return min(p[8] for p in world.client.getClosestPoints(body, world.table_id, 0.05))


@pytest.mark.parametrize("object_type", PAPER_OBJECT_TYPES)
def test_objects_are_about_10_cm_wide_and_upright(world: PaperWorld, object_type: str) -> None:
    world.reset_scene()
    body = world.add_object(object_type, (0.03, -0.04), 0.0)
    low, high = _aabb(world, body)
    assert 0.08 <= max(high[:2] - low[:2]) <= 0.12
    if object_type in MESH_UP:
        _, quaternion = world.client.getBasePositionAndOrientation(body)
        rotation = np.array(world.client.getMatrixFromQuaternion(quaternion)).reshape(3, 3)
        assert rotation @ np.array(MESH_UP[object_type]) == pytest.approx([0, 0, 1], abs=1e-6)


@pytest.mark.parametrize("object_type", PAPER_OBJECT_TYPES)
@pytest.mark.parametrize("yaw_rad", YAWS_RAD)
def test_objects_rest_where_placed_and_stay(
    world: PaperWorld, object_type: str, yaw_rad: float
) -> None:
    world.reset_scene()
    body = world.add_object(object_type, (0.03, -0.04), yaw_rad)
    assert abs(_gap_to_table_m(world, body)) < 5e-4  # touching from the start
    placed = world.object_position_m(body)
    world.settle()
    settled = world.object_position_m(body)
    assert np.linalg.norm(settled - placed) < 1e-3  # nothing to settle: no drop, no roll
    assert np.linalg.norm(settled[:2] - np.array([0.03, -0.04])) < 0.01  # label = where placed
    # The box carries PyBullet's 2-3 mm collision margin below the mesh.
    assert abs(_aabb(world, body)[0][2]) < 0.0035
    for _ in range(240):  # 1 s
        world.client.stepSimulation()
    assert np.linalg.norm(world.object_position_m(body) - settled) < 0.002


@pytest.mark.parametrize("x", PAPER_WORKSPACE_X_M)
@pytest.mark.parametrize("y", PAPER_WORKSPACE_Y_M)
def test_an_object_at_each_workspace_corner_is_wholly_in_the_image(
    world: PaperWorld, x: float, y: float
) -> None:
    for object_type in PAPER_OBJECT_TYPES:
        for yaw_rad in YAWS_RAD:
            world.reset_scene()
            body = world.add_object(object_type, (x, y), yaw_rad)
            low, high = _aabb(world, body)
            corners = np.array([[a, b, c] for a in (low[0], high[0]) for b in (low[1], high[1])
                                for c in (low[2], high[2])])  # (8, 3)
            pixels = world.camera.project(corners)  # (8, 2)
            assert pixels.min() >= 0.0 and pixels.max() <= 127.0, (object_type, yaw_rad)


def test_image_left_is_world_plus_y(world: PaperWorld) -> None:
    left, right = world.camera.project(np.array([[0.0, 0.1, 0.0], [0.0, -0.1, 0.0]]))
    assert left[0] < 64.0 < right[0]


def test_render_and_darker_light(world: PaperWorld) -> None:
    world.reset_scene()
    world.add_object("mug", (0.0, 0.0), 0.0)
    bright, dim = world.render(), world.render(0.3)
    assert bright.shape == (128, 128, 3) and bright.dtype == np.uint8
    assert dim.mean() < 0.6 * bright.mean()


def test_unknown_type_lists_the_allowed_ones_and_reset_removes_objects(
    world: PaperWorld,
) -> None:
    with pytest.raises(InvalidInputError, match=r"object type = 'sponge' is not allowed: one "
                       r"of duck, soccer_ball, mug"):
        world.add_object("sponge", (0.0, 0.0), 0.0)
    body = world.add_object("mug", (0.0, 0.0), 0.0)
    world.reset_scene()
    assert world.objects == {}
    assert body not in {b for b in range(world.client.getNumBodies())
                        if world.client.getBodyUniqueId(b) == body}
