import json

import numpy as np
import pytest

from experiments.cli import main
from harness.inputs.trial_settings import TrialSettings
from harness.run_loop import run_trials
from perception.interface import (
    NO_CONDITION,
    Condition,
    ConditionKind,
    Prediction,
    Target,
)
from perception.objects.catalog import OBJECT_TYPES, get_object_spec
from robots.yumi import YUMI
from sim.errors import InvalidInputError, TargetNotFoundError
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task
from sim.trials.oracle import OraclePerception
from sim.trials.planner_setup import ObstacleSource
from sim.trials.trial_runner import TrialRunner
from sim.world.head_camera import HeadCamera, camera_config
from sim.world.yumi_world import World


@pytest.fixture(scope="module")
def world():
    with World(robot=YUMI) as w:
        yield w


def test_oracle_returns_the_canonical_grasp(world):
    """The oracle's grasp is the catalog's, worked out by hand, on the object it was asked for.

    Among a sponge, a bottle, a mug and a sponge-shaped block (a distractor, never a target),
    the type, the side and the catalog order each single out the sponge. Its yaw points the
    object's +y to the robot's right, so the canonical grasp is the half-turned one.
    """
    world.reset_scene()
    yaw = 2.74
    bottle = world.add_object(get_object_spec("spray_bottle"), (0.38, 0.1), 0.3)
    mug = world.add_object(get_object_spec("mug"), (0.52, 0.14), 1.0)
    sponge = world.add_object(get_object_spec("sponge"), (0.42, -0.1), yaw)  # added third
    world.add_object(get_object_spec("block"), (0.52, -0.2), 0.2)  # rightmost of all
    # The sponge's TCP: the footprint's centre, 2.8 cm up; approach straight down; the fingers
    # close along the object's -y, (sin yaw, -cos yaw) = (0.39, 0.92): to the robot's left.
    closing = np.array([np.sin(yaw), -np.cos(yaw), 0.0])
    down = np.array([0.0, 0.0, -1.0])
    hand = np.column_stack([closing, np.cross(down, closing), down])
    assert closing[1] > 0.9 and np.allclose(hand[:, 1], [0.92044, -0.39088, 0.0], atol=1e-4)
    oracle = OraclePerception(world, HeadCamera(camera_config(YUMI)))
    oracle.candidates = (sponge, bottle, mug)  # as a trial sets them: the block is no target
    image = np.zeros((128, 128, 3), np.uint8)
    asked = {
        "type": oracle.predict(image, Condition(ConditionKind.OBJECT_TYPE, "sponge",
                                                OBJECT_TYPES)),
        "side": oracle.predict(image, Condition(ConditionKind.SIDE, "right", ("left", "right"))),
    }
    for how, prediction in asked.items():
        (target,) = prediction.targets
        assert target.object_type == "sponge", how
        np.testing.assert_allclose(target.position_m, [0.42, -0.1, 0.028], atol=1e-6)
        np.testing.assert_allclose(target.rotation, hand, atol=1e-6)
        assert prediction.attention_px.shape == (1, 2)
    every = oracle.predict(image)  # no condition: every target, in catalog order
    assert [t.object_type for t in every.targets] == ["sponge", "spray_bottle", "mug"]
    np.testing.assert_allclose(every.targets[0].position_m, [0.42, -0.1, 0.028], atol=1e-6)
    np.testing.assert_allclose(every.targets[0].rotation, hand, atol=1e-6)
    np.testing.assert_allclose(every.targets[1].position_m[2], 0.07, atol=1e-6)  # bottle: side
    assert every.attention_px.shape == (3, 2)


def test_oracle_names_a_missing_object(world):
    world.reset_scene()
    world.add_object(get_object_spec("sponge"), (0.42, -0.1), 0.0)
    oracle = OraclePerception(world, HeadCamera(camera_config(YUMI)))
    mug = Condition(ConditionKind.OBJECT_TYPE, "mug", OBJECT_TYPES)
    with pytest.raises(TargetNotFoundError, match="object_type = 'mug' names no object in the "
                       r"scene \(present: sponge\)"):
        oracle.predict(np.zeros((128, 128, 3), np.uint8), mug)


def test_scenes_are_seeded_and_test_scenes_differ_from_training(tmp_path):
    task = load_task("single")
    a = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, 5)
    assert a == sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, 5)
    assert a != sample_scene(task, YUMI_SCENE, 0, SeedStream.TRAIN, 5)
    assert a != sample_scene(task, YUMI_SCENE, 1, SeedStream.TEST, 5)


def test_unknown_model_and_task_are_refused_with_the_allowed_names():
    with pytest.raises(InvalidInputError, match="model = 'kqv9' is not allowed: one of oracle, "
                       r"oracle-view, a checkpoint folder \(gva train writes one\), "
                       r"'package.module:Class', the name an installed package registers in "
                       r"'gva.models', or ws://HOST:PORT of a gva serve server"):
        TrialSettings(model="kqv9", task="single")
    with pytest.raises(InvalidInputError, match=r"task = 'juggle' is not allowed: one of multiple, "
                       r"selected-position, selected-position-text, selected-type, "
                       r"selected-type-image, selected-type-moved, selected-type-text, single, "
                       r"single-moved, or the path of a \.toml file"):
        TrialSettings(model="oracle", task="juggle")


def test_cli_reports_bad_input_in_one_line(tmp_path, capsys):
    assert main(["trials", "--task", "juggle", "--out", str(tmp_path)]) == 2
    assert "error: task = 'juggle' is not allowed: one of multiple" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["trials", "--n", "0", "--out", str(tmp_path)])


def changed_oracle_trial(change, task="single", index=0):
    """One trial of test scene ``index`` with the oracle's targets changed by ``change``."""
    class Changed(OraclePerception):
        def predict(self, image, condition=NO_CONDITION):
            return Prediction(tuple(change(t) for t in super().predict(image, condition).targets))

    spec = load_task(task)
    with TrialRunner(spec, Changed, robot=YUMI) as runner:
        return runner.run(sample_scene(spec, YUMI_SCENE, 0, SeedStream.TEST, index), index, 0,
                          "changed")


def test_unreachable_prediction_is_a_recorded_outcome():
    record = changed_oracle_trial(lambda t: Target(t.position_m + np.array([0.8, 0.0, 0.0]),
                                                   t.rotation))
    assert record.outcome.value == "ik_unreachable"
    assert "no in-limit IK solution" in record.reason
    assert record.position_error_m == pytest.approx(0.8, abs=1e-6)


def test_a_rounded_rotation_is_picked_and_a_wrong_one_is_a_recorded_outcome():
    def float32_rounded(rotation):  # off by a few 1e-6, as a network's output can be
        shear = np.eye(3) + 3e-6 * np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
        return (rotation @ shear).astype(np.float32)

    outcomes = {name: changed_oracle_trial(lambda t, c=change: Target(t.position_m,
                                                                      c(t.rotation)))
                for name, change in (("rounded", float32_rounded),
                                     ("sheared", lambda r: r + 0.05))}
    assert outcomes["rounded"].outcome.value == "success", outcomes["rounded"].reason
    assert outcomes["sheared"].outcome.value == "perception_failed"
    assert "target 1 of 1: rotation" in outcomes["sheared"].reason
    assert "R Rᵀ = I within 0.0001" in outcomes["sheared"].reason


TRUTH_ACCESSORS = ("object_pose", "object_spec", "object_bottom_z_m", "objects")
CLIENT_TRUTH = ("getBasePositionAndOrientation", "getAABB", "getContactPoints",
                "getClosestPoints", "getOverlappingObjects", "getCollisionShapeData",
                "getVisualShapeData", "getBaseVelocity", "getDynamicsInfo")


@pytest.fixture
def sealed_planning(monkeypatch):
    """Every pick's plan phase runs with the simulator's truth accessors failing.

    The world's object pose, type and shape accessors, and PyBullet's own ways to read a body,
    raise inside :meth:`TrialRunner.plan_pick`; the camera and the robot's joints still work.
    Returns the list of reads that were tried.
    """
    reads: list[str] = []
    planning = []

    def guarded(name, original):
        def read(*args, **kwargs):
            if planning:
                reads.append(name)
                raise RuntimeError(f"{name} read the true scene during planning")
            return original(*args, **kwargs)
        return read

    for name in TRUTH_ACCESSORS:
        original = getattr(World, name)
        if isinstance(original, property):
            monkeypatch.setattr(World, name, property(guarded(name, original.fget)))
        else:
            monkeypatch.setattr(World, name, guarded(name, original))
    plan_pick = TrialRunner.plan_pick

    def sealed(self, *args, **kwargs):
        client = self.world.client
        for name in CLIENT_TRUTH:  # an instance attribute hides BulletClient's forwarding
            setattr(client, name, guarded(name, getattr(client, name)))
        planning.append(True)
        try:
            return plan_pick(self, *args, **kwargs)
        finally:
            planning.clear()
            for name in CLIENT_TRUTH:
                delattr(client, name)

    monkeypatch.setattr(TrialRunner, "plan_pick", sealed)
    return reads


@pytest.mark.slow
@pytest.mark.parametrize(("task", "index"), [("multiple", 0), ("selected-type", 1)])
def test_planning_reads_nothing_of_the_true_scene(sealed_planning, task, index):
    spec = load_task(task)
    with TrialRunner(spec, robot=YUMI) as runner:
        record = runner.run(sample_scene(spec, YUMI_SCENE, 0, SeedStream.TEST, index), index, 0,
                            "oracle")
    assert sealed_planning == []
    assert record.outcome.value == "success", record.reason
    assert all(p["obstacles"]["source"] == "depth" for p in record.picks)
    assert all(p["obstacles"]["target_cells"] > 0 for p in record.picks)  # the camera saw it


def test_the_seal_catches_a_planner_that_reads_the_truth(sealed_planning):
    task = load_task("single")
    with TrialRunner(task, obstacles=ObstacleSource.TRUTH, robot=YUMI) as runner:
        record = runner.run(sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, 0), 0, 0, "x")
    assert sealed_planning == ["objects"]
    assert record.outcome.value == "error"
    assert "objects read the true scene during planning" in record.reason


def test_a_record_keeps_the_grip_and_obstacles_the_planner_was_given():
    kind = sample_scene(load_task("single"), YUMI_SCENE, 0, SeedStream.TEST, 0).objects[0]
    typed = changed_oracle_trial(lambda t: t)
    silent = changed_oracle_trial(lambda t: Target(t.position_m, t.rotation))  # no type said
    assert typed.grip == {"source": "object_type", "object_type": kind.object_type,
                          "opening_m": 0.05, "pregrasp_distance_m": 0.08}
    assert silent.grip == {"source": "default", "object_type": None, "opening_m": 0.05,
                           "pregrasp_distance_m": 0.08}
    assert silent.outcome.value == typed.outcome.value == "success", silent.reason
    assert typed.obstacles["source"] == "depth" and typed.obstacles["points"] > 100
    assert typed.obstacles["target_cells"] > 0 and typed.obstacles["obstacle_cells"] == 0


def test_a_type_outside_the_catalog_is_the_models_recorded_failure():
    record = changed_oracle_trial(lambda t: Target(t.position_m, t.rotation, "teapot"))
    assert record.outcome.value == "perception_failed"
    assert "target object_type = 'teapot' is not allowed: one of sponge" in record.reason
    assert record.predicted is not None and record.position_error_m < 1e-6


@pytest.mark.slow
def test_oracle_trials_succeed_and_resume(tmp_path):
    settings = TrialSettings("oracle", "single", n=4, seed=0)
    first = run_trials(TrialSettings("oracle", "single", n=2, seed=0), tmp_path, progress=False)
    assert first.n == 2
    summary = run_trials(settings, tmp_path, progress=False)  # resumes: runs trials 2 and 3 only
    lines = (tmp_path / "trials.jsonl").read_text().splitlines()
    assert [json.loads(line)["index"] for line in lines] == [0, 1, 2, 3]
    assert summary.successes == 4, [json.loads(line)["reason"] for line in lines]
    stored = json.loads((tmp_path / "summary.json").read_text())
    assert stored["successes"] == 4 and stored["n"] == 4
    assert stored["settings"]["obstacles"]["source"] == "depth"
    assert stored["settings"]["obstacles"]["depth"]["cell_m"] == 0.005
    run = json.loads((tmp_path / "run.json").read_text())
    assert run["obstacles"] == stored["settings"]["obstacles"]


def test_grasp_of_a_missing_object_is_a_recorded_outcome():
    class AsksFor(OraclePerception):
        def __init__(self, object_type, *args):
            super().__init__(*args)
            self.condition = Condition(ConditionKind.OBJECT_TYPE, object_type, OBJECT_TYPES)

        def predict(self, image, condition=None):
            return super().predict(image, self.condition)

    task = load_task("single")
    scene = sample_scene(task, YUMI_SCENE, 0, SeedStream.TEST, 0)
    with TrialRunner(task, robot=YUMI) as runner:
        missing = next(t for t in OBJECT_TYPES if t != scene.objects[0].object_type)
        runner.model = AsksFor(missing, runner.world, runner.camera)
        record = runner.run(scene, 0, 0, "asks-for")
    assert record.outcome.value == "perception_failed"
    assert f"object_type = '{missing}' names no object in the scene" in record.reason


@pytest.mark.slow
def test_multiple_picks_every_target_after_a_fresh_image(tmp_path):
    summary = run_trials(TrialSettings("oracle", "multiple", n=1, seed=0), tmp_path,
                         progress=False)
    (line,) = (tmp_path / "trials.jsonl").read_text().splitlines()
    record = json.loads(line)
    assert record["outcome"] == "success", record["reason"]
    assert [p["target"] for p in record["picks"]] == ["sponge", "spray_bottle", "mug"]
    assert all(p["outcome"] == "success" for p in record["picks"])
    assert summary.per_object == {t: {"attempted": 1, "picked": 1}
                                  for t in ("mug", "sponge", "spray_bottle")}


@pytest.mark.slow
def test_a_users_task_file_runs_without_code(tmp_path):
    task = tmp_path / "two-mugs.toml"
    task.write_text('name = "two-mugs-dim"\n[objects]\nchoose = "same_type"\ncount = 1\n'
                    '[lighting]\nbrightness = 0.4\n[distractors]\ntypes = ["mug"]\n')
    assert main(["trials", "--task", str(task), "--n", "2", "--out", str(tmp_path / "run"),
                 "--no-progress"]) == 0
    records = [json.loads(x) for x in (tmp_path / "run" / "trials.jsonl").read_text().splitlines()]
    assert [r["outcome"] for r in records] == ["success", "success"]
    assert all(len(r["objects"]) == 2 and r["objects"][1]["distractor"] for r in records)
