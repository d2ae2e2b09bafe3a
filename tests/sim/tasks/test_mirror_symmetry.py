"""The collector's mirror-symmetry record: when a task's demonstrations may be mirrored."""

import dataclasses

import numpy as np
import pytest

from perception.objects.catalog import (
    DISTRACTOR_TYPES,
    OBJECT_TYPES,
    SPRAY_BOTTLE,
    Primitive,
    get_object_spec,
)
from perception.objects.grasps import grasp_pose
from perception.poses import Pose
from robots.yumi import YUMI
from sim.tasks.mirror_symmetry import MIRROR_Y, mirror_symmetric, object_is_mirror_symmetric
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task, task_from_toml
from sim.world.head_camera import CameraConfig, camera_config

CATALOG = OBJECT_TYPES + DISTRACTOR_TYPES


@pytest.mark.parametrize("name", CATALOG)
def test_the_mirrored_canonical_grasp_is_the_canonical_grasp_of_the_mirrored_object(name):
    spec = get_object_spec(name)
    assert object_is_mirror_symmetric(spec)
    rng = np.random.default_rng(0)
    for _ in range(200):
        x, y, yaw = rng.uniform(0.40, 0.55), rng.uniform(-0.2, 0.2), rng.uniform(-np.pi, np.pi)
        grasp = grasp_pose(spec, Pose.from_xy_yaw(x, y, yaw))
        mirrored = grasp_pose(spec, Pose.from_xy_yaw(x, -y, -yaw))
        np.testing.assert_allclose(mirrored.position, MIRROR_Y @ grasp.position, atol=1e-9)
        expected = MIRROR_Y @ grasp.rotation @ MIRROR_Y
        twin = expected @ np.diag([-1.0, -1.0, 1.0])  # the gripper's half turn: the same grasp
        assert min(np.abs(mirrored.rotation - r).max() for r in (expected, twin)) < 1e-6


def test_an_object_with_a_part_off_its_mirror_plane_is_not_symmetric():
    nozzle = SPRAY_BOTTLE.primitives[4]
    aside = Primitive(nozzle.kind, nozzle.size_m, (0.041, 0.005, 0.166), nozzle.rgba)
    bottle = dataclasses.replace(SPRAY_BOTTLE, primitives=(*SPRAY_BOTTLE.primitives[:4], aside,
                                                           *SPRAY_BOTTLE.primitives[5:]))
    assert not object_is_mirror_symmetric(bottle)


def test_the_papers_tasks_may_be_mirrored_and_others_are_refused_with_reason():
    camera = camera_config(YUMI)
    papers = ("single", "multiple", "selected-type", "selected-position")
    assert all(mirror_symmetric(load_task(name), YUMI_SCENE, camera) for name in papers)
    assert mirror_symmetric(load_task("selected-type-text"), YUMI_SCENE, camera)
    # A sentence that names a side is mirrored by what it names (kqv swaps the side's row).
    assert mirror_symmetric(load_task("selected-position-text"), YUMI_SCENE, camera)
    two_sponges = task_from_toml('name = "two"\n[objects]\nchoose = "same_type"\ncount = 2')
    assert not mirror_symmetric(two_sponges, YUMI_SCENE, camera)  # targets ordered by y
    left_half = task_from_toml('name = "left"\n[placement]\ny_m = [0.0, 0.2]')
    assert not mirror_symmetric(left_half, YUMI_SCENE, camera)
    aside = CameraConfig.for_mount(YUMI.camera, position_m=(0.09, 0.05, 0.52))
    assert not mirror_symmetric(load_task("single"), YUMI_SCENE, aside)
