"""The grip comes from what a model states: its type's catalog grasp, its opening, or a default."""

import math

import numpy as np
import pytest

from perception.interface import InvalidInputError as PerceptionInputError
from perception.interface import Target
from perception.objects.catalog import MAX_OPENING_M, catalog_names, get_object_spec
from perception.objects.grasps import grasp_pose
from perception.poses import Pose
from robots import get_robot
from robots.yumi import YUMI
from sim.errors import InvalidInputError
from sim.world.grip import DEFAULT_GRIP, GripSource, catalog_opening_m, grip_of

HERE = np.array([0.45, 0.0, 0.05])
YUMI_STROKE_M = YUMI.max_opening_m
"""The YuMi's hand: the one the catalog states its grasps for (CATALOG_GRIPPER)."""


def test_a_named_type_brings_its_catalog_grasp_and_symmetric_alternatives():
    bottle = get_object_spec("spray_bottle")
    grip = grip_of(Target(HERE, np.eye(3), object_type="spray_bottle"), YUMI_STROKE_M)
    assert grip.source is GripSource.OBJECT_TYPE and grip.spec is bottle
    assert grip.opening_m == bottle.grasp.opening_m
    assert grip.pregrasp_distance_m == bottle.grasp.pregrasp_distance_m
    grasp = grasp_pose(bottle, Pose.from_xy_yaw(0.45, 0.1, 0.3))
    turned = grip.alternatives(grasp)  # a bottle is the same from every side: the whole circle
    assert len(turned) == 17
    axis = grasp.position[:2] + 0.006 * grasp.rotation[:2, 2]  # the TCP stops 6 mm short of it
    bearings = [math.degrees(math.atan2(*(p.position[:2] - axis)[::-1])) for p in turned]
    first = math.degrees(math.atan2(*(grasp.position[:2] - axis)[::-1]))
    steps = [round(math.remainder(b - first, 360.0)) for b in bearings]
    assert steps == [20, -20, 40, -40, 60, -60, 80, -80, 100, -100, 120, -120, 140, -140, 160,
                     -160, 180]  # nearest the given grasp first
    sponge = grip_of(Target(HERE, np.eye(3), object_type="sponge"), YUMI_STROKE_M)
    assert sponge.alternatives(grasp) == ()
    assert grip.to_record() == {"source": "object_type", "object_type": "spray_bottle",
                                "opening_m": 0.05, "pregrasp_distance_m": 0.08}


def test_a_stated_opening_is_taken_and_overrides_the_types():
    stated = grip_of(Target(HERE, np.eye(3), opening_m=0.03), YUMI_STROKE_M)
    assert stated.opening_m == 0.03 and stated.source is GripSource.OPENING
    typed = grip_of(Target(HERE, np.eye(3), object_type="mug", opening_m=0.04), YUMI_STROKE_M)
    assert (typed.opening_m, typed.spec) == (0.04, get_object_spec("mug"))


def test_a_model_that_states_nothing_gets_the_default_that_opens_as_far_as_any_grasp():
    assert grip_of(Target(HERE, np.eye(3)), YUMI_STROKE_M) == DEFAULT_GRIP
    assert DEFAULT_GRIP.source is GripSource.DEFAULT and DEFAULT_GRIP.alternatives(
        Pose(HERE, np.eye(3))) == ()
    for name in catalog_names():
        grasp = get_object_spec(name).grasp
        assert grasp.opening_m <= DEFAULT_GRIP.opening_m == MAX_OPENING_M
        assert grasp.pregrasp_distance_m == DEFAULT_GRIP.pregrasp_distance_m


def test_an_unknown_type_or_an_impossible_opening_is_refused_by_name():
    with pytest.raises(InvalidInputError, match="target object_type = 'cup' is not allowed: one "
                       "of sponge, spray_bottle, mug, block, drink_can, notebook, marker, "
                       "glue_stick, bottle_twin, mug_twin, colour_twin or None"):
        grip_of(Target(HERE, np.eye(3), object_type="cup"), YUMI_STROKE_M)
    with pytest.raises(InvalidInputError, match=r"target opening_m = 0\.08 is not allowed: in "
                       r"\(0, 0\.05\] m, the gripper's stroke"):
        grip_of(Target(HERE, np.eye(3), opening_m=0.08), YUMI_STROKE_M)
    with pytest.raises(PerceptionInputError, match="opening_m = nan is not allowed"):
        Target(HERE, np.eye(3), opening_m=float("nan"))


def test_a_wider_hand_opens_fully_where_the_catalog_opens_the_yumis_fully():
    stroke_m = get_robot("panda").arms[0].gripper.max_opening_m
    assert stroke_m == 0.08
    for name in catalog_names():  # every catalog grasp opens the YuMi's hand fully
        grip = grip_of(Target(HERE, np.eye(3), object_type=name), stroke_m)
        assert grip.opening_m == stroke_m and grip.spec is get_object_spec(name)
    assert grip_of(Target(HERE, np.eye(3)), stroke_m).opening_m == stroke_m
    assert grip_of(Target(HERE, np.eye(3)), stroke_m).source is GripSource.DEFAULT
    assert grip_of(Target(HERE, np.eye(3), opening_m=0.07), stroke_m).opening_m == 0.07
    assert catalog_opening_m(0.03, stroke_m) == 0.03  # a narrower grasp keeps its width
    with pytest.raises(InvalidInputError, match=r"target opening_m = 0\.09 is not allowed: in "
                       r"\(0, 0\.08\] m, the gripper's stroke"):
        grip_of(Target(HERE, np.eye(3), opening_m=0.09), stroke_m)
