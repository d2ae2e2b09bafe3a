"""Benchmark: re-targeting the YuMi's right arm from a moving state (control.retarget).

Each case is a reachable moving state, an inner sample of a rest-to-rest segment between two
random in-limit configurations (seeded), and a new random in-limit goal. Timed on one thread:
``retarget`` (ruckig's plan from the state plus sampling at ``--dt``, validation included),
``stop`` from the same state, and, for reference, ``plan_segment`` from rest at the state's
positions to the same goal (the offline planner). Cases ruckig's motion would take beyond a
position limit raise RetargetError; they are counted, not timed.

Usage:
    python benchmarks/bench_retarget.py --n 500 --seed 0 [--out benchmarks/results/retarget.json]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections.abc import Callable

import numpy as np
import ruckig
from results_file import add_out_option, write_record

from control.retarget import JointState, RetargetError, retarget, stop, trajectory_state
from control.robot_model import RobotModel
from control.trajectory import JointLimits, plan_segment
from robots import yumi


def random_cases(
    limits: JointLimits, n: int, seed: int, dt_s: float
) -> list[tuple[JointState, np.ndarray]]:
    """``n`` (moving state, goal) pairs: inner samples of random segments, random goals."""
    rng = np.random.default_rng(seed)
    cases = []
    for _ in range(n):
        a, b = rng.uniform(limits.lower, limits.upper), rng.uniform(limits.lower, limits.upper)
        executed = plan_segment(a, b, limits, dt_s)
        k = int(rng.integers(1, executed.times_s.size - 1))
        cases.append((trajectory_state(executed, k), rng.uniform(limits.lower, limits.upper)))
    return cases


def timed_ms(call: Callable[[], object]) -> float | None:
    """Wall time of ``call`` in [ms], or None where it raised RetargetError."""
    started = time.perf_counter()
    try:
        call()
    except RetargetError:
        return None
    return (time.perf_counter() - started) * 1e3


def summary(times_ms: list[float | None]) -> dict[str, float | int]:
    done = np.array([t for t in times_ms if t is not None])
    return {"median_ms": float(np.median(done)), "p95_ms": float(np.percentile(done, 95)),
            "max_ms": float(done.max()), "refused": len(times_ms) - done.size}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=500, help="state/goal pairs")
    parser.add_argument("--seed", type=int, default=0, help="seed of the pairs")
    parser.add_argument("--dt", type=float, default=1 / 240, help="sampling step in [s]")
    add_out_option(parser, "retarget")
    args = parser.parse_args()

    robot = RobotModel.from_urdf(yumi.URDF_PATH)
    limits = JointLimits.from_robot(robot, yumi.ARM_JOINTS["r"], yumi.MAX_ACCELERATION_RAD_S2,
                                    yumi.MAX_JERK_RAD_S3)
    cases = random_cases(limits, args.n, args.seed, args.dt)
    load_before = os.getloadavg()[0]
    results = {
        "retarget": summary([timed_ms(lambda s=s, g=g: retarget(s, g, limits, args.dt))
                             for s, g in cases]),
        "stop": summary([timed_ms(lambda s=s: stop(s, limits, args.dt)) for s, _ in cases]),
        "plan_segment_from_rest": summary([
            timed_ms(lambda s=s, g=g: plan_segment(s.positions, g, limits, args.dt))
            for s, g in cases]),
    }
    durations_s = [retarget(s, g, limits, args.dt).duration_s for s, g in cases]
    print(f"{'what':24} {'median':>9} {'p95':>9} {'max':>9} {'refused':>8}")
    for name, s in results.items():
        print(f"{name:24} {s['median_ms']:7.3f}ms {s['p95_ms']:7.3f}ms {s['max_ms']:7.3f}ms "
              f"{s['refused']:>5}/{args.n}")
    print(f"re-targeted motions: median {np.median(durations_s):.3f} s long")
    report = {
        "benchmark": "retarget",
        "arm": "r",
        "n": args.n,
        "seed": args.seed,
        "dt_s": args.dt,
        "results": results,
        "median_retarget_duration_s": float(np.median(durations_s)),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                    "python": platform.python_version(), "ruckig": ruckig.__version__,
                    "threads": 1, "load_average_1min_before": round(load_before, 2),
                    "load_average_1min_after": round(os.getloadavg()[0], 2)},
    }
    write_record(args.out, report)


if __name__ == "__main__":
    main()
