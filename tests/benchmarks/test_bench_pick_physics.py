"""benchmarks/bench_pick_physics.py times a pick's physics and PyBullet's floor beside it."""

from __future__ import annotations

import json

import pybullet
import pytest
from benchmark_scripts import load_benchmark
from pybullet_utils import bullet_client


def test_the_picks_steps_are_counted_and_timed_and_the_floor_measured(tmp_path):
    bench = load_benchmark("bench_pick_physics")
    out = tmp_path / "pick_physics.json"
    resolve = bullet_client.BulletClient.__getattr__
    stray = pybullet.connect(pybullet.DIRECT)  # another client first, as a test before may leave
    try:
        assert bench.main(["--task", "single", "--n", "1", "--steps", "5", "--repeats", "1",
                           "--out", str(out)]) == 0
    finally:
        pybullet.disconnect(stray)
    record = json.loads(out.read_text())
    picks = record["picks"]
    assert picks["trials"] == picks["picks"] == 1 and sum(picks["outcomes"].values()) == 1
    assert picks["steps"] == picks["calls"]["stepSimulation"] > 500  # a pick is 4-6 s at 240 Hz
    assert 0 < picks["step_simulation_share"] < 1 and picks["step_simulation_ms"] > 0
    phases = picks["phases"]  # every step of a successful pick falls in one phase
    assert sum(p["steps_a_pick"] for p in phases.values()) == picks["steps_per_pick"]
    assert all(phases[name]["steps_a_pick"] > 0 for name in ("approach", "close", "lift", "hold"))
    assert phases["hold"]["steps_a_pick"] == 240  # 1 s at 240 Hz
    assert sum(p["share"] for p in phases.values()) == pytest.approx(1.0, abs=0.01)
    assert set(record["floor"]) == {
        "robot_alone", "objects_alone_awake_ms", "objects_alone_asleep_ms",
        "robot_and_objects_awake_ms", "robot_and_objects_asleep_ms",
        "robot_and_objects_awake_half_solver_iterations_ms"}
    assert bullet_client.BulletClient.__getattr__ is resolve  # the timers are taken off


def test_a_solver_candidate_reaches_every_world_built_meanwhile_and_no_other():
    bench = load_benchmark("bench_pick_physics")
    with bench.solver_settings(1e-5, 7), bench.World(robot=bench.YUMI) as world:
        assert world.client.getPhysicsEngineParameters()["numSolverIterations"] == 7
    with bench.World(robot=bench.YUMI) as world:
        assert world.client.getPhysicsEngineParameters()["numSolverIterations"] == 100


def test_the_mug_candidate_rests_on_its_bottom_looks_the_same_and_is_taken_off_after():
    bench = load_benchmark("bench_pick_physics")
    mug = bench.get_object_spec("mug")
    candidate = bench.mug_on_its_bottom()
    lowest = [p.position_m[2] - p.size_m[2] / 2 for p in candidate.primitives]
    assert min(lowest[:12]) == pytest.approx(0.001)  # the wall off the table
    assert lowest[12] == pytest.approx(0.0)  # the bottom disc on it
    assert (candidate.mass_kg, candidate.grasp) == (mug.mass_kg, mug.grasp)
    with bench.mug_candidate(True), bench.World(robot=bench.YUMI) as world:
        body = world.add_object(mug, (0.35, 0.0), 0.0)
        world.step(120)
        contacts = world.client.getContactPoints(body, world.table_id)
        assert 0 < len(contacts) <= 8  # the disc's, not the wall's 48
        looks = world.client.getVisualShapeData(body)  # the catalog's look, wall to the floor
        assert len(looks) == len(mug.primitives)
        assert [shape[3][2] for shape in looks[:12]] == pytest.approx(  # the wall's boxes
            [p.size_m[2] for p in mug.primitives[:12]])
        world.client.changeDynamics(body, -1, activationState=pybullet.ACTIVATION_STATE_WAKE_UP)
    with bench.World(robot=bench.YUMI) as world:
        body = world.add_object(mug, (0.35, 0.0), 0.0)
        world.step(120)
        assert len(world.client.getContactPoints(body, world.table_id)) > 8  # the catalog's


def test_pyramid_friction_reaches_the_worlds_built_meanwhile(monkeypatch):
    bench = load_benchmark("bench_pick_physics")
    settings: list[dict] = []  # PyBullet does not report the setting back: its calls are read
    resolve = bullet_client.BulletClient.__getattr__

    def spy(client, name):
        call = resolve(client, name)
        if name != "setPhysicsEngineParameter":
            return call

        def recorded(**kwargs):
            settings.append(kwargs)
            return call(**kwargs)
        return recorded

    monkeypatch.setattr(bullet_client.BulletClient, "__getattr__", spy)
    with bench.solver_settings(None, None, cone_friction=False), bench.World(robot=bench.YUMI):
        assert {"enableConeFriction": 0} in settings
    settings.clear()
    with bench.World(robot=bench.YUMI):
        assert settings and not any("enableConeFriction" in kwargs for kwargs in settings)
