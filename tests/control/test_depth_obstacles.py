"""Depth points become height fields the checker uses: occupied where seen, the target apart."""

import coal
import numpy as np
import pinocchio as pin
import pytest

from control.collision import HeightField
from control.depth_obstacles import (
    DepthObstacleConfig,
    FingerBox,
    GraspRegion,
    OccludedSpace,
    depth_obstacles,
)
from control.errors import InvalidInputError

FINGERS = FingerBox(tip_beyond_tcp_m=0.02, length_m=0.05, half_width_m=0.01, thickness_m=0.01)
CONFIG = DepthObstacleConfig(FINGERS, x_range_m=(0.1, 1.0), y_range_m=(-0.5, 0.5))
CAMERA = np.array([0.0, 0.0, 0.6])
DOWN = np.diag([1.0, -1.0, -1.0])  # TCP z pointing down, fingers closing along world x


def block_surface(centre_xy, size_xy, height_m, spacing_m=(0.004, 0.004)):
    """Points a camera above sees of a block: its top face, on a grid (rows of an image)."""
    xs = np.arange(-size_xy[0] / 2, size_xy[0] / 2 + 1e-9, spacing_m[0]) + centre_xy[0]
    ys = np.arange(-size_xy[1] / 2, size_xy[1] / 2 + 1e-9, spacing_m[1]) + centre_xy[1]
    x, y = np.meshgrid(xs, ys)
    return np.stack([x, y, np.full_like(x, height_m)], axis=-1)  # (H, W, 3)


def image_of(*surfaces):
    """One (H, W, 3) image holding the surfaces side by side (NaN pads: no depth there)."""
    height = max(s.shape[0] for s in surfaces)
    padded = [np.pad(s, ((0, height - s.shape[0]), (0, 1), (0, 0)), constant_values=np.nan)
              for s in surfaces]
    return np.concatenate(padded, axis=1)


def touches(field: HeightField, centre, radius=0.002) -> bool:
    sphere = coal.Sphere(radius)
    request, result = coal.CollisionRequest(), coal.CollisionResult()
    placed = coal.Transform3s(np.eye(3), np.asarray(centre, float))
    shape_pose = coal.Transform3s(field.T_world_shape.rotation, field.T_world_shape.translation)
    return coal.collide(field.geometry(), shape_pose, sphere, placed, request, result) > 0


def test_a_seen_block_is_solid_from_the_table_to_its_top_and_free_around():
    tall = block_surface((0.5, 0.1), (0.06, 0.04), 0.08)
    low = block_surface((0.7, -0.1), (0.04, 0.04), 0.03)
    seen = depth_obstacles(image_of(tall, low), CAMERA, CONFIG)
    (field,) = seen.obstacles
    assert seen.target_obstacles == ()
    assert seen.points == tall[..., 0].size + low[..., 0].size
    assert seen.obstacle_cells >= 12 * 8 + 8 * 8
    for z in (0.01, 0.04, 0.075):  # under the seen top: filled down to the table
        assert touches(field, (0.5, 0.1, z))
    assert not touches(field, (0.5, 0.1, 0.095))  # above it
    assert not touches(field, (0.5, 0.2, 0.04))  # beside it (a cell of slope, then nothing)
    assert not touches(field, (0.6, 0.1, 0.04))
    assert touches(field, (0.7, -0.1, 0.02)) and not touches(field, (0.7, -0.1, 0.04))
    assert not touches(field, (0.5, -0.1, 0.06))  # rows run along +y: not mirrored
    assert not touches(field, (0.7, 0.1, 0.02))


def test_points_sparser_than_the_grid_leave_no_hole_and_the_outline_stays_tight():
    # 6 mm between rows, as the head camera's pixels fall on the table along y: more than a cell.
    seen = depth_obstacles(block_surface((0.5, 0.0), (0.06, 0.06), 0.05, (0.004, 0.006)),
                           CAMERA, CONFIG)
    (field,) = seen.obstacles
    inside = np.linspace(-0.028, 0.028, 15)
    assert all(touches(field, (0.5 + x, y, 0.045), radius=0.001) for x in inside for y in inside)
    for outside in ((0.535, 0.0), (0.465, 0.0), (0.5, 0.035), (0.5, -0.035)):  # 5 mm beyond
        assert not touches(field, (*outside, 0.045), radius=0.001), outside


def test_the_table_points_beyond_the_workspace_and_no_depth_are_dropped():
    table = block_surface((0.5, 0.0), (0.2, 0.2), 0.004)  # below min_height_m: the table
    outside = block_surface((1.3, 0.0), (0.05, 0.05), 0.1)  # beyond x_range_m
    blank = np.full((10, 10, 3), np.nan)
    seen = depth_obstacles(image_of(table, outside, blank), CAMERA, CONFIG)
    assert seen.points == 0 and seen.obstacles == () and seen.obstacle_cells == 0


def test_the_object_between_the_fingers_is_the_target_and_its_neighbour_an_obstacle():
    target = block_surface((0.5, 0.0), (0.03, 0.08), 0.03)
    neighbour = block_surface((0.5, 0.1), (0.05, 0.05), 0.09)
    grasp = GraspRegion(pin.SE3(DOWN, np.array([0.5, 0.0, 0.028])), opening_m=0.05)
    seen = depth_obstacles(image_of(target, neighbour), CAMERA, CONFIG, grasp)
    (obstacle,), (own,) = seen.obstacles, seen.target_obstacles
    # The whole target is the target's, also its ends beyond the fingers' box ...
    assert touches(own, (0.5, 0.035, 0.02)) and not touches(obstacle, (0.5, 0.035, 0.02))
    # ... and the neighbour stays an obstacle.
    assert touches(obstacle, (0.5, 0.1, 0.05)) and not touches(own, (0.5, 0.1, 0.05))
    assert seen.target_cells < seen.obstacle_cells + seen.target_cells


def test_a_part_of_the_target_split_off_above_the_fingers_is_still_the_target():
    """A tall target grasped from the side, its face cut in two by the arm in view (no depth
    there): the part above the fingers' box is a cluster of its own, and still the target's."""
    side = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # approach along +x
    ys = np.arange(-0.02, 0.02 + 1e-9, 0.004)
    zs = np.concatenate([np.arange(0.01, 0.08, 0.004), np.arange(0.13, 0.17, 0.004)])  # a gap
    y, z = np.meshgrid(ys, zs)
    face = np.stack([np.full_like(y, 0.5), y, z], axis=-1)  # the face towards the camera
    grasp = GraspRegion(pin.SE3(side, np.array([0.5, 0.0, 0.05])), opening_m=0.05)
    seen = depth_obstacles(face, np.array([0.0, 0.0, 0.3]), CONFIG, grasp)
    assert seen.obstacles == ()
    (own,) = seen.target_obstacles
    assert touches(own, (0.5, 0.0, 0.15))


def test_a_grasp_that_closes_on_nothing_leaves_every_object_an_obstacle():
    block = block_surface((0.5, 0.0), (0.03, 0.08), 0.03)
    grasp = GraspRegion(pin.SE3(DOWN, np.array([0.5, 0.2, 0.028])), opening_m=0.05)
    seen = depth_obstacles(block, CAMERA, CONFIG, grasp)
    assert seen.target_obstacles == () and seen.target_cells == 0 and len(seen.obstacles) == 1


def test_occupied_hidden_space_fills_the_shadow_behind_a_tall_object():
    tall = block_surface((0.5, 0.0), (0.02, 0.02), 0.15)
    free = depth_obstacles(tall, CAMERA, CONFIG)
    hidden = depth_obstacles(tall, CAMERA, DepthObstacleConfig(
        FINGERS, CONFIG.x_range_m, CONFIG.y_range_m, occluded=OccludedSpace.OCCUPIED))
    assert free.hidden_points == 0 and hidden.hidden_points > 0
    # The camera at x = 0 sees the top at x = 0.5 m, 15 cm up; its rays go on to the table
    # at x = 0.5 * 0.6 / 0.45 = 0.667 m, 10 cm behind at 3.75 cm: hidden, so occupied.
    behind = (0.6, 0.0, 0.03)
    assert touches(hidden.obstacles[0], behind) and not touches(free.obstacles[0], behind)


def test_a_pixel_without_a_measurement_is_free_space_or_an_obstacle_as_the_config_says():
    block = block_surface((0.5, 0.2), (0.03, 0.03), 0.05)
    # a stereo shadow: the camera at (0, 0, 0.6) looked at (0.5, 0.0, 0.02) and got no depth
    dark = np.array([[0.5, 0.0, 0.02]]) - CAMERA
    grasp = GraspRegion(pin.SE3(DOWN, np.array([0.5, 0.2, 0.028])), opening_m=0.05)
    free = depth_obstacles(block, CAMERA, CONFIG, grasp, unknown_rays_world=dark)
    occupied = depth_obstacles(block, CAMERA, DepthObstacleConfig(
        FINGERS, CONFIG.x_range_m, CONFIG.y_range_m, occluded=OccludedSpace.OCCUPIED),
        grasp, unknown_rays_world=dark)
    assert free.unknown_rays == occupied.unknown_rays == 1 and free.obstacles == ()
    assert free.to_record()["unknown_rays"] == 1
    # unseen, so occupied along its whole stretch through the workspace, never the target's
    on_ray = CAMERA + 0.9 * dark[0]  # 2 cm above the table on that ray
    assert touches(occupied.obstacles[0], on_ray)
    assert not any(touches(field, on_ray) for field in occupied.target_obstacles)
    assert occupied.points == free.points  # no point comes from a pixel without depth
    with pytest.raises(InvalidInputError, match="unknown_rays_world"):
        depth_obstacles(block, CAMERA, CONFIG, unknown_rays_world=np.array([[0.0, np.nan, 1.0]]))


def test_bad_input_names_the_field():
    with pytest.raises(InvalidInputError, match=r"points_world = 'shape \(5, 3\)' is not "
                       r"allowed: shape \(H, W, 3\)"):
        depth_obstacles(np.zeros((5, 3)), CAMERA, CONFIG)
    with pytest.raises(InvalidInputError, match="camera_position_m"):
        depth_obstacles(np.zeros((2, 2, 3)), np.array([0.0, np.nan, 1.0]), CONFIG)
    with pytest.raises(InvalidInputError, match=r"x_range_m = \(1\.0, 0\.1\) is not allowed"):
        DepthObstacleConfig(FINGERS, x_range_m=(1.0, 0.1), y_range_m=(-0.5, 0.5))
    with pytest.raises(InvalidInputError, match=r"cell_m = 0\.0 is not allowed"):
        DepthObstacleConfig(FINGERS, (0.1, 1.0), (-0.5, 0.5), cell_m=0.0)
    with pytest.raises(InvalidInputError, match="heights_m"):
        HeightField("bad", (0.0, 0.0), 0.01, np.array([[0.0, -1.0], [0.0, 0.0]]))
