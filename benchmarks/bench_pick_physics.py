"""Benchmark: where a pick's physics time goes, against PyBullet's own floor (issue 76).

A trial is mostly physics steps (a profile of ``gva trials --model oracle --task multiple``:
about 70 % of its time in ``World.step``). This measures, on this machine:

- **the picks**: ``--n`` oracle trials of ``--task`` at each of ``--seeds``, every PyBullet call
  that a step makes timed where it happens (``stepSimulation``, the motor commands, the
  sliding belt's velocity calls): steps per pick, physics steps per second of wall time, the
  mean ``stepSimulation`` [ms], and the rest of ``World.step`` (its Python and motor calls);
- **the floor**, each a median of ``--repeats`` runs of ``--steps`` steps: the robot alone
  holding still (its motors set once, then through ``World.step`` with the per-step motor
  commands), the table with three objects and the robot taken out (awake, then asleep), the
  robot with the three objects resting (awake, asleep), and that last at half the solver
  iterations (what the iterations cost; a change of physics, so not one to make lightly).

Physics is not changed by any of this; the trials' outcomes are printed beside the timings, so
a record shows the picks it timed. Run on a quiet machine for the issue's numbers.

Usage:
    python benchmarks/bench_pick_physics.py [--task multiple] [--seeds 0] [--n 4]
        [--steps 480] [--repeats 3] [--out benchmarks/results/pick_physics.json]
        [--residual-threshold X] [--iterations N] [--pyramid-friction] [--mug-on-its-bottom]

The last four are candidates that change contact physics, measured here before any is adopted.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import statistics
import tempfile
import time
from collections import Counter, defaultdict
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import pybullet
from pybullet_utils import bullet_client
from results_file import add_out_option, write_record

from harness.inputs.trial_settings import TrialSettings
from harness.run_loop import run_trials
from perception.objects.catalog import MUG, get_object_spec
from perception.objects.object_spec import ObjectSpec
from robots.yumi import YUMI
from sim.trials import execution
from sim.world.sim_robot import SimRobot
from sim.world.world_config import WorldConfig
from sim.world.yumi_world import World

TIMED_CALLS = ("stepSimulation", "setJointMotorControlArray", "setJointMotorControl2",
               "getBaseVelocity", "resetBaseVelocity")
"""The PyBullet calls a :meth:`World.step` makes, each timed where it is called."""
RESTING = (("sponge", (0.35, 0.1)), ("spray_bottle", (0.4, -0.1)), ("mug", (0.3, 0.0)))
"""Three objects resting on the table, as ``bench_trials.py`` places them."""


@dataclass
class CallTimes:
    """Calls and seconds per timed PyBullet function, while :func:`timed_calls` is on."""

    calls: Counter[str]
    seconds: defaultdict[str, float]
    phase: list[str]  # the pick phase now running (one entry, set by :func:`labelled_phases`)
    phase_steps: Counter[str]
    phase_seconds: defaultdict[str, float]


@contextlib.contextmanager
def timed_calls() -> Iterator[CallTimes]:
    """Times :data:`TIMED_CALLS` wherever a world's ``BulletClient`` makes them.

    The timer wraps what ``BulletClient.__getattr__`` hands out (the call already bound to the
    client's id), not the ``pybullet`` module: a client only binds its id to a builtin, so a
    module-level wrapper would send every timed call to the process's first client, which is
    another world's whenever one is still connected (a test run before this one).
    """
    times = CallTimes(Counter(), defaultdict(float), ["other"], Counter(), defaultdict(float))
    resolve = bullet_client.BulletClient.__getattr__

    def timed(name: str, call: Callable[..., Any]) -> Callable[..., Any]:
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            started = time.perf_counter()
            try:
                return call(*args, **kwargs)
            finally:
                seconds = time.perf_counter() - started
                times.seconds[name] += seconds
                times.calls[name] += 1
                if name == "stepSimulation":
                    times.phase_seconds[times.phase[0]] += seconds
                    times.phase_steps[times.phase[0]] += 1
        return wrapper

    def resolve_timed(client: bullet_client.BulletClient, name: str) -> Any:
        attribute = resolve(client, name)
        return timed(name, attribute) if name in TIMED_CALLS else attribute

    bullet_client.BulletClient.__getattr__ = resolve_timed
    try:
        yield times
    finally:
        bullet_client.BulletClient.__getattr__ = resolve


PHASES = ("approach", "close", "lift", "hold", "other")
"""A pick's phases as :func:`labelled_phases` names them: the arm's path to the grasp with the
contact watch on (approach and descent), the fingers closing, the lift with the target held,
the 1 s hold, and the rest (the settle of each scene, setting a picked object aside)."""


ATTRIBUTES = {"track": "track", "close": "_close", "hold": "_hold"}
"""Where each phase's call lives (``SimRobot.track``, ``execution._close``, ``._hold``)."""


@contextlib.contextmanager
def labelled_phases(times: CallTimes) -> Iterator[None]:
    """Labels each step with its pick phase (:data:`PHASES`) while the trials run.

    Wraps what a pick calls for each phase (``SimRobot.track`` with or without its contact
    watch, and the execution's close and hold), each restored after; nothing else changes.
    """
    originals: dict[str, Callable[..., Any]] = {
        "track": SimRobot.track, "close": execution._close, "hold": execution._hold}

    def within(label: str | Callable[..., str], call: Callable[..., Any]) -> Callable[..., Any]:
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            outer = times.phase[0]
            times.phase[0] = label if isinstance(label, str) else label(*args, **kwargs)
            try:
                return call(*args, **kwargs)
            finally:
                times.phase[0] = outer
        return wrapper

    def track_phase(*args: Any, **kwargs: Any) -> str:
        watched = kwargs.get("on_step", args[4] if len(args) > 4 else None) is not None
        return "approach" if watched else "lift"

    owners = {"track": SimRobot, "close": execution, "hold": execution}
    labels: dict[str, str | Callable[..., str]] = {"track": track_phase, "close": "close",
                                                   "hold": "hold"}
    for name, call in originals.items():
        setattr(owners[name], ATTRIBUTES[name], within(labels[name], call))
    try:
        yield
    finally:
        for name, call in originals.items():
            setattr(owners[name], ATTRIBUTES[name], call)


@dataclass(frozen=True)
class PickPhysics:
    """The timed picks: counts, steps, and where a step's wall time went."""

    task: str
    seeds: tuple[int, ...]
    trials: int
    picks: int
    outcomes: dict[str, int]
    wall_s: float
    steps: int
    steps_per_pick: float
    physics_steps_per_s: float  # steps over the trials' whole wall time
    step_simulation_ms: float  # mean of one stepSimulation call
    step_simulation_share: float  # of the trials' wall time
    motor_and_belt_calls_ms_per_step: float  # the other timed calls, per step
    calls: dict[str, int]
    phases: dict[str, dict[str, float]]  # per phase: steps a pick, ms a step, share


def pick_physics(task: str, seeds: tuple[int, ...], n: int) -> PickPhysics:
    """``n`` oracle trials of ``task`` per seed, their PyBullet calls timed."""
    outcomes: Counter[str] = Counter()
    picks = 0
    with timed_calls() as times, labelled_phases(times):
        started = time.perf_counter()
        for seed in seeds:
            with tempfile.TemporaryDirectory() as folder:
                run_trials(TrialSettings("oracle", task, n, seed), folder, progress=False)
                for line in (Path(folder) / "trials.jsonl").open(encoding="utf-8"):
                    record = json.loads(line)
                    outcomes[record["outcome"]] += 1
                    picks += max(len(record.get("picks") or ()), 1)
        wall_s = time.perf_counter() - started
    steps = times.calls["stepSimulation"]
    other_s = sum(s for name, s in times.seconds.items() if name != "stepSimulation")
    return PickPhysics(
        task, seeds, n * len(seeds), picks, dict(outcomes), round(wall_s, 2), steps,
        round(steps / picks, 1), round(steps / wall_s, 1),
        round(times.seconds["stepSimulation"] / steps * 1e3, 4),
        round(times.seconds["stepSimulation"] / wall_s, 3),
        round(other_s / steps * 1e3, 4), dict(times.calls),
        {phase: {"steps_a_pick": round(times.phase_steps[phase] / picks, 1),
                 "step_simulation_ms": round(times.phase_seconds[phase] /
                                             max(times.phase_steps[phase], 1) * 1e3, 4),
                 "share": round(times.phase_seconds[phase] / times.seconds["stepSimulation"], 3)}
         for phase in PHASES})


@contextlib.contextmanager
def solver_settings(residual_threshold: float | None, iterations: int | None,
                    cone_friction: bool | None = None) -> Iterator[None]:
    """Every world built meanwhile gets these PyBullet solver settings: a candidate, measured.

    ``solverResidualThreshold``, ``numSolverIterations`` and ``enableConeFriction`` (False:
    the pyramid of two friction directions) as given (None: the world's own; the floor's
    half-iterations row then reads ``iterations`` too). A change of contact physics: what it
    buys is measured here; adopting one needs the oracle's counts and the grasp tolerance map
    re-measured (issue 76).
    """
    build = World._build

    def built(world: World) -> None:
        build(world)
        if residual_threshold is not None:
            world.client.setPhysicsEngineParameter(solverResidualThreshold=residual_threshold)
        if iterations is not None:
            world.client.setPhysicsEngineParameter(numSolverIterations=iterations)
        if cone_friction is not None:
            world.client.setPhysicsEngineParameter(enableConeFriction=int(cone_friction))

    World._build = built  # type: ignore[method-assign, assignment]
    try:
        yield
    finally:
        World._build = build  # type: ignore[method-assign]


def mug_on_its_bottom() -> ObjectSpec:
    """The catalog's mug with its twelve wall boxes 1 mm off the table: it rests on its bottom.

    A candidate collision shape (issue 76): today the mug stands on the wall's twelve boxes,
    four contact points each with the table (48 of a scene's 50 resting contacts), solved at
    every step the mug is awake. Here its bottom disc (6 mm, 71 mm across) touches instead, as
    a real mug's foot does; the wall is as tall above the table, the mass and grasp the same.
    """
    ring, rest = MUG.primitives[:12], MUG.primitives[12:]
    raised = tuple(replace(p, size_m=(p.size_m[0], p.size_m[1], p.size_m[2] - 0.001),
                           position_m=(p.position_m[0], p.position_m[1],
                                       0.001 + (p.size_m[2] - 0.001) / 2)) for p in ring)
    bottom = replace(rest[0], position_m=(0.0, 0.0, rest[0].size_m[2] / 2))
    return replace(MUG, primitives=(*raised, bottom, *rest[1:]))


@contextlib.contextmanager
def mug_candidate(on: bool) -> Iterator[None]:
    """While on, every world makes the mug's collision shape :func:`mug_on_its_bottom`'s.

    Its look (the visual shapes) stays the catalog's, so what the camera sees is unchanged.
    """
    if not on:
        yield
        return
    shape_ids = World._shape_ids
    candidate = mug_on_its_bottom()

    def shapes(world: World, spec: ObjectSpec) -> tuple[int, int]:
        if spec.name != "mug":
            return shape_ids(world, spec)
        _, visual = shape_ids(world, spec)
        collision, _ = shape_ids(world, candidate)
        return collision, visual

    World._shape_ids = shapes  # type: ignore[method-assign, assignment]
    try:
        yield
    finally:
        World._shape_ids = shape_ids  # type: ignore[method-assign]


def median_step_ms(step: Callable[[int], None], steps: int, repeats: int) -> float:
    """Median over ``repeats`` of one step's wall time [ms], ``step(steps)`` timed whole."""
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        step(steps)
        times.append((time.perf_counter() - started) / steps * 1e3)
    return round(statistics.median(times), 4)


def robot_alone_ms(steps: int, repeats: int) -> dict[str, float]:
    """The robot holding still, no objects: raw steps, then :meth:`World.step` (motors each)."""
    with World(robot=YUMI) as world:
        world.step(60)

        def raw(count: int) -> None:
            for _ in range(count):
                world.client.stepSimulation()
        return {"step_simulation_ms": median_step_ms(raw, steps, repeats),
                "world_step_ms": median_step_ms(world.step, steps, repeats)}


def objects_alone_ms(steps: int, repeats: int, sleeping: bool) -> float:
    """The table and the three objects resting with the robot taken out: raw steps."""
    with World(WorldConfig(object_sleeping=sleeping), robot=YUMI) as world:
        for name, xy in RESTING:
            world.add_object(get_object_spec(name), xy, 0.3)
        world.step(60)
        world.sleep_resting_objects()
        world.client.removeBody(world.robot.body_id)

        def raw(count: int) -> None:
            for _ in range(count):
                world.client.stepSimulation()
        return median_step_ms(raw, steps, repeats)


def robot_and_objects_ms(steps: int, repeats: int, config: WorldConfig) -> float:
    """The robot with the three objects resting (asleep where ``config`` lets them sleep)."""
    with World(config, robot=YUMI) as world:
        for name, xy in RESTING:
            world.add_object(get_object_spec(name), xy, 0.3)
        world.step(60)
        world.sleep_resting_objects()
        return median_step_ms(world.step, steps, repeats)


def measure(args: argparse.Namespace) -> tuple[PickPhysics, dict[str, Any]]:
    """The picks, then the floor."""
    picks = pick_physics(args.task, tuple(args.seeds), args.n)
    awake, asleep = WorldConfig(object_sleeping=False), WorldConfig()
    floor = {
        "robot_alone": robot_alone_ms(args.steps, args.repeats),
        "objects_alone_awake_ms": objects_alone_ms(args.steps, args.repeats, False),
        "objects_alone_asleep_ms": objects_alone_ms(args.steps, args.repeats, True),
        "robot_and_objects_awake_ms": robot_and_objects_ms(args.steps, args.repeats, awake),
        "robot_and_objects_asleep_ms": robot_and_objects_ms(args.steps, args.repeats, asleep),
        "robot_and_objects_awake_half_solver_iterations_ms": robot_and_objects_ms(
            args.steps, args.repeats,
            replace(awake, solver_iterations=awake.solver_iterations // 2)),
    }
    return picks, floor


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="multiple")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--n", type=int, default=4)
    parser.add_argument("--steps", type=int, default=480)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--residual-threshold", type=float, default=None,
                        help="PyBullet's solverResidualThreshold for every world (a candidate)")
    parser.add_argument("--iterations", type=int, default=None,
                        help="PyBullet's numSolverIterations for every world (a candidate)")
    parser.add_argument("--pyramid-friction", action="store_true",
                        help="PyBullet's enableConeFriction off in every world (a candidate)")
    parser.add_argument("--mug-on-its-bottom", action="store_true",
                        help="the mug's collision shape resting on its bottom disc, not on its "
                        "wall's twelve boxes (a candidate; its look unchanged)")
    add_out_option(parser, "pick_physics")
    args = parser.parse_args(argv)
    load_before = os.getloadavg()
    with solver_settings(args.residual_threshold, args.iterations,
                         False if args.pyramid_friction else None), \
            mug_candidate(args.mug_on_its_bottom):
        picks, floor = measure(args)
    record = {
        "machine": {"cpu_count": os.cpu_count(), "python": platform.python_version(),
                    "processor": platform.processor() or platform.machine(),
                    "pybullet": pybullet.getAPIVersion()},
        "load_average_1_5_15min_before": [round(v, 2) for v in load_before],
        "load_average_1_5_15min_after": [round(v, 2) for v in os.getloadavg()],
        "command": "python benchmarks/bench_pick_physics.py " + " ".join(
            f"--{k.replace('_', '-')}" + ("" if isinstance(v, bool) else
                                          f" {' '.join(map(str, v)) if isinstance(v, list) else v}")
            for k, v in vars(args).items() if k != "out" and v not in (None, False)),
        "picks": asdict(picks), "floor": floor,
    }
    print(f"{picks.task}: {picks.trials} trials, {picks.picks} picks ({picks.outcomes}), "
          f"{picks.steps_per_pick:.0f} steps a pick; {picks.physics_steps_per_s:.0f} physics "
          f"steps/s of wall time; stepSimulation {picks.step_simulation_ms:.3f} ms, "
          f"{100 * picks.step_simulation_share:.0f} % of the wall time")
    for phase, numbers in picks.phases.items():
        print(f"  {phase:8s} {numbers['steps_a_pick']:7.1f} steps a pick, "
              f"{numbers['step_simulation_ms']:.3f} ms a step, "
              f"{100 * numbers['share']:4.1f} % of the steps' time")
    print("floor [ms a step]: " + json.dumps(floor))
    write_record(args.out, record)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
