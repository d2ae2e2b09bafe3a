import numpy as np
import pinocchio as pin
import pytest

from control.collision import CollisionChecker, Obstacle, ShapeKind
from control.errors import InvalidInputError
from robots import yumi


def box(name: str, size, centre) -> Obstacle:
    return Obstacle(name, ShapeKind.BOX, size, pin.SE3(np.eye(3), np.asarray(centre, float)))


def test_home_is_free_of_self_collision(yumi_checker, yumi_home):
    yumi_checker.set_obstacles([])
    assert not yumi_checker.check(yumi_home).in_collision
    clearance, _ = yumi_checker.clearance_m(yumi_home)
    assert clearance > 0.01


def test_arms_crossing_at_zero_pose_collide(yumi_checker, yumi_model):
    # The fact sheet warns the flanges meet at the all-zero pose (§4).
    yumi_checker.set_obstacles([])
    report = yumi_checker.check(np.zeros(yumi_model.nq), stop_at_first=False)
    assert report.in_collision
    assert any("_l" in a + b and "_r" in a + b for a, b in report.pairs)


def test_obstacle_at_the_gripper_is_reported_by_name(yumi_checker, yumi_model, yumi_home):
    tcp = yumi_model.frame_pose(yumi_home, yumi.TCP_FRAME["r"]).translation
    yumi_checker.set_obstacles([box("crate", (0.1, 0.1, 0.1), tcp)])
    report = yumi_checker.check(yumi_home, stop_at_first=False)
    assert report.in_collision
    assert {b for _, b in report.pairs} == {"crate"}
    assert all(a.startswith("gripper_r") for a, _ in report.pairs)
    assert "vs crate" in report.describe()


def test_table_under_the_body_is_not_a_collision(yumi_checker, yumi_home):
    # The body stands on the table: fixed links are never checked against obstacles.
    yumi_checker.set_obstacles([box("table", (1.5, 1.0, 0.05), (0.35, 0.0, -0.025))])
    assert not yumi_checker.check(yumi_home).in_collision


def test_path_check_reports_first_colliding_sample(yumi_checker, yumi_model, yumi_home):
    tcp = yumi_model.frame_pose(yumi_home, yumi.TCP_FRAME["r"]).translation
    yumi_checker.set_obstacles([box("crate", (0.1, 0.1, 0.1), tcp)])
    far = yumi_home.copy()
    far[yumi_model.joint_index("yumi_joint_2_r")] += 1.5  # raise the arm away from the crate
    assert not yumi_checker.check(far).in_collision
    path = [far, far, yumi_home]
    assert yumi_checker.check_path(path).sample_index == 2


def test_bad_obstacle_and_margin_are_refused(yumi_model):
    message = r"obstacle 'slab' size = \(0\.1, 0\.1\) is not allowed: 3 positive"
    with pytest.raises(InvalidInputError, match=message):
        Obstacle("slab", ShapeKind.BOX, (0.1, 0.1), pin.SE3.Identity())
    with pytest.raises(InvalidInputError, match=r"margin_m = -0\.01 is not allowed"):
        CollisionChecker(yumi_model, yumi.URDF_PATH, margin_m=-0.01)


def test_duplicate_obstacle_names_are_refused(yumi_checker):
    twice = [box("cup", (0.1, 0.1, 0.1), (0.5, 0, 0)), box("cup", (0.1, 0.1, 0.1), (0.6, 0, 0))]
    with pytest.raises(InvalidInputError, match="obstacle names"):
        yumi_checker.set_obstacles(twice)


def test_the_broad_phase_answers_as_the_distances_do_margin_included(yumi_checker, yumi_model,
                                                                     yumi_home):
    """The broad phase culls pairs by their boxes: a configuration closer than the margin to a
    box, or to itself, must still count, and one just outside it must not."""
    rng = np.random.default_rng(5)
    yumi_checker.set_obstacles(
        [box("table", (1.2, 1.2, 0.04), (0.6, 0.0, -0.02))]
        + [box(f"box{k}", tuple(rng.uniform(0.03, 0.1, 3)),
               (rng.uniform(0.3, 0.6), rng.uniform(-0.3, 0.3), rng.uniform(0.05, 0.3)))
           for k in range(6)])
    lower, upper = yumi_model.model.lowerPositionLimit, yumi_model.model.upperPositionLimit
    counted = {"within the margin": 0, "free": 0, "touching": 0}
    for _ in range(3000):
        q = np.clip(yumi_home + rng.normal(scale=0.6, size=yumi_model.nq), lower, upper)
        distance_m, _ = yumi_checker.clearance_m(q)
        if abs(distance_m - yumi_checker.margin_m) < 1e-5 or abs(distance_m) < 1e-5:
            continue  # on a boundary, where the two computations may round apart
        assert yumi_checker.check(q).in_collision == (distance_m < yumi_checker.margin_m)
        counted["touching" if distance_m < 0 else "within the margin"
                if distance_m < yumi_checker.margin_m else "free"] += 1
    assert min(counted.values()) >= 20, counted  # each case was met


def test_the_broad_phase_skips_what_ignoring_skips(yumi_checker, yumi_model, yumi_home):
    tcp = yumi_model.frame_pose(yumi_home, yumi.TCP_FRAME["r"]).translation
    yumi_checker.set_obstacles([box("crate", (0.1, 0.1, 0.1), tcp), box("far", (0.1, 0.1, 0.1),
                                                                          (0.5, 0.0, 0.8))])
    assert yumi_checker.check(yumi_home).in_collision
    with yumi_checker.ignoring(["crate"]):
        assert not yumi_checker.check(yumi_home).in_collision
    assert yumi_checker.check(yumi_home).pairs[0][1] == "crate"
