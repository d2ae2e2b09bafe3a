"""Benchmark: our IK (control.ik) against PyBullet's calculateInverseKinematics, per robot.

Both solvers get the same targets (the TCP poses of random in-limit arm configurations, seeded),
the same start (the robot's home: the YuMi's by default, ``--robot panda`` the Panda's) and the
same bar: position error <= 0.5 mm, rotation error
<= 0.01 rad and every joint within its limits, all checked with Pinocchio's forward kinematics.
PyBullet gets target position and orientation, the joint limits and ranges for its null space,
restPoses = home, 200 iterations and a 1e-6 residual threshold. Its timing covers the
calculateInverseKinematics call only (resetting the start state is not counted); ours covers
the whole ArmIk.solve. ``--pink`` adds pin-pink's QP IK (pip install pin-pink quadprog) wrapped
in the same restart policy, for the comparison that chose the method.

Usage:
    python benchmarks/bench_ik.py --n 1000 --seed 0 [--robot panda] [--out FILE] [--pink]

(default record ``benchmarks/results/ik.json``, for the Panda ``ik-panda.json``).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin
import pybullet
from results_file import record_path, write_record

from control.ik import ArmIk, IkOptions
from control.robot_model import RobotModel
from robots import ROBOT_NAMES, get_robot
from robots.description import ArmDescription, RobotDescription

POSITION_OK_M = 5e-4
ROTATION_OK_RAD = 0.01
BULLET_SETTINGS = {"maxNumIterations": 200, "residualThreshold": 1e-6}

Solver = Callable[[pin.SE3], np.ndarray]  # target -> full configuration (nq,)


def random_targets(robot: RobotModel, arm: ArmDescription, home: np.ndarray, n: int, seed: int
                   ) -> list[pin.SE3]:
    """TCP poses of ``n`` random in-limit configurations of one arm, the other joints at home."""
    rng = np.random.default_rng(seed)
    index = robot.joint_indices(arm.joints)
    q = home.copy()
    targets = []
    for _ in range(n):
        q[index] = rng.uniform(robot.lower_rad[index], robot.upper_rad[index])
        targets.append(robot.frame_pose(q, arm.tcp_frame))
    return targets


class BulletIk:
    """PyBullet's IK on the same URDF, every call started from home."""

    def __init__(self, robot: RobotModel, description: RobotDescription) -> None:
        self.robot = robot
        self.client = pybullet.connect(pybullet.DIRECT)
        self.body = pybullet.loadURDF(
            str(description.urdf_path), useFixedBase=True, physicsClientId=self.client
        )
        self.link_of: dict[str, int] = {}
        self.joint_of: dict[str, int] = {}
        for index in range(pybullet.getNumJoints(self.body, physicsClientId=self.client)):
            info = pybullet.getJointInfo(self.body, index, physicsClientId=self.client)
            self.link_of[info[12].decode()] = index
            if info[2] != pybullet.JOINT_FIXED:
                self.joint_of[info[1].decode()] = index
        # PyBullet's IK answers for every movable joint, in joint index order.
        self.dof_index = robot.joint_indices(self.joint_of)  # (nq,) pybullet -> Pinocchio q
        self.home = robot.q_from_dict(description.home)
        self.null_space = {
            "lowerLimits": robot.lower_rad[self.dof_index].tolist(),
            "upperLimits": robot.upper_rad[self.dof_index].tolist(),
            "jointRanges": (robot.upper_rad - robot.lower_rad)[self.dof_index].tolist(),
            "restPoses": self.home[self.dof_index].tolist(),
        }
        self.elapsed_s = 0.0

    def close(self) -> None:
        """Disconnects the client, so no later world in this process meets it."""
        pybullet.disconnect(physicsClientId=self.client)

    def solver(self, arm: ArmDescription) -> Solver:
        """Return the IK of one arm's TCP; ``elapsed_s`` then holds each call's time in [s]."""
        link = self.link_of[arm.tcp_frame]

        def solve(T_world_target: pin.SE3) -> np.ndarray:
            # Start from home through the simulation state: passing currentPositions instead
            # puts the answer off by the base link's inertial offset (0.28 m on this URDF).
            for name, index in self.joint_of.items():
                pybullet.resetJointState(self.body, index, self.home[self.robot.joint_index(name)],
                                         physicsClientId=self.client)
            quaternion_xyzw = pin.Quaternion(T_world_target.rotation).coeffs().tolist()
            started = time.perf_counter()
            answer = pybullet.calculateInverseKinematics(
                self.body, link, T_world_target.translation.tolist(), quaternion_xyzw,
                physicsClientId=self.client, **self.null_space, **BULLET_SETTINGS,
            )
            self.elapsed_s = time.perf_counter() - started
            q = self.home.copy()
            q[self.dof_index] = answer
            return q

        return solve


def pink_solver(robot: RobotModel, arm_spec: ArmDescription, home: np.ndarray) -> Solver:
    """pin-pink's differential IK iterated to the target, with ArmIk's restart policy."""
    import pink  # optional: pip install pin-pink quadprog
    from pink.limits import ConfigurationLimit
    from pink.tasks import FrameTask

    opts, frame = IkOptions(), arm_spec.tcp_frame
    arm = set(arm_spec.joints)
    locked = [j for j in range(1, robot.model.njoints) if robot.model.names[j] not in arm]
    model = pin.buildReducedModel(robot.model, locked, home)
    index = robot.joint_indices(model.names[j] for j in range(1, model.njoints))
    limits = [ConfigurationLimit(model, config_limit_gain=opts.limit_gain)]
    task = FrameTask(frame, position_cost=1.0, orientation_cost=opts.rotation_weight_m,
                     lm_damping=opts.damping)
    weight = np.array([1.0] * 3 + [opts.rotation_weight_m] * 3)  # (6,) -> [m], as ArmIk

    def task_target() -> pin.SE3:
        return task.transform_target_to_world

    def attempt(q: np.ndarray) -> tuple[bool, float, np.ndarray]:
        """One descent: (reached, squared weighted error [m^2], reduced q)."""
        configuration = pink.Configuration(model, model.createData(), q)
        best_cost, since_best = math.inf, 0
        for _ in range(opts.max_iterations + 1):
            error = task.compute_error(configuration)  # (6,) body twist to the target
            T_world_frame = configuration.get_transform_frame_to_world(frame)
            position_m = np.linalg.norm(T_world_frame.translation - task_target().translation)
            weighted = error * weight
            cost = float(weighted @ weighted)
            if (position_m <= opts.position_tolerance_m
                    and np.linalg.norm(error[3:]) <= opts.rotation_tolerance_rad):
                return True, cost, configuration.q
            if cost < 0.98 * best_cost:
                best_cost, since_best = cost, 0
            else:
                since_best += 1
                if since_best >= opts.stall_iterations:
                    break
            velocity = pink.solve_ik(configuration, [task], 1.0, solver="quadprog", limits=limits,
                                     safety_break=False)
            configuration.integrate_inplace(velocity, 1.0)
        return False, cost, configuration.q

    def solve(T_world_target: pin.SE3) -> np.ndarray:
        task.set_target(T_world_target)
        rng = np.random.default_rng(0)
        best_cost, best_q = math.inf, home[index]
        for restart in range(opts.max_restarts + 1):
            start = home[index] if restart == 0 else rng.uniform(model.lowerPositionLimit,
                                                                model.upperPositionLimit)
            reached, cost, q = attempt(start)
            if reached or cost < best_cost:
                best_cost, best_q = cost, q
            if reached:
                break
        q_full = home.copy()
        q_full[index] = best_q
        return q_full

    return solve


def ours_solver(ik: ArmIk, q_start: np.ndarray) -> Solver:
    """Return ArmIk.solve from ``q_start`` as a target -> configuration function."""
    return lambda T_world_target: ik.solve(T_world_target, q_start).q


def measure(robot: RobotModel, frame: str, solve: Solver, targets: list[pin.SE3],
            clock: Callable[[], float] | None = None) -> dict[str, float]:
    """Success rate, error percentiles and time per solve of one solver on one arm."""
    position_m, rotation_rad, within, times_s = [], [], [], []
    for T_target in targets:
        started = time.perf_counter()
        q = solve(T_target)
        times_s.append(clock() if clock is not None else time.perf_counter() - started)
        T_reached = robot.frame_pose(q, frame)
        position_m.append(float(np.linalg.norm(T_reached.translation - T_target.translation)))
        R_reached_target = T_reached.rotation.T @ T_target.rotation
        rotation_rad.append(float(np.linalg.norm(pin.log3(R_reached_target))))
        within.append(robot.within_limits(q))
    p, r, w = np.array(position_m), np.array(rotation_rad), np.array(within)
    return {
        "success_rate": float(np.mean((p <= POSITION_OK_M) & (r <= ROTATION_OK_RAD) & w)),
        "within_limits_rate": float(np.mean(w)),
        "median_position_error_m": float(np.median(p)),
        "p95_position_error_m": float(np.percentile(p, 95)),
        "median_rotation_error_rad": float(np.median(r)),
        "p95_rotation_error_rad": float(np.percentile(r, 95)),
        "median_time_s": float(np.median(times_s)),
        "p95_time_s": float(np.percentile(times_s, 95)),
    }


def print_table(results: dict[str, dict[str, dict[str, float]]]) -> None:
    """One row per arm and solver, errors in [mm] and [mrad], times in [ms]."""
    print(f"{'arm':5} {'solver':9} {'success':>8} {'in-lim':>7} {'pos med':>9} {'pos p95':>9} "
          f"{'rot med':>9} {'rot p95':>9} {'t med':>8} {'t p95':>8} {'t/pyb':>6}")
    for side, by_solver in results.items():
        bullet_s = by_solver["pybullet"]["median_time_s"]
        for name, s in by_solver.items():
            mm = [s[f"{k}_position_error_m"] * 1e3 for k in ("median", "p95")]
            mrad = [s[f"{k}_rotation_error_rad"] * 1e3 for k in ("median", "p95")]
            ms = [s[f"{k}_time_s"] * 1e3 for k in ("median", "p95")]
            print(f"{side:5} {name:9} {s['success_rate']:8.1%} {s['within_limits_rate']:7.1%} "
                  f"{mm[0]:7.4f}mm {mm[1]:7.3f}mm {mrad[0]:6.3f}mrd {mrad[1]:6.3f}mrd "
                  f"{ms[0]:6.3f}ms {ms[1]:6.2f}ms {s['median_time_s'] / bullet_s:6.3f}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1000, help="target poses per arm")
    parser.add_argument("--seed", type=int, default=0, help="seed of the target poses")
    parser.add_argument("--robot", choices=ROBOT_NAMES, default="yumi")
    parser.add_argument("--out", type=Path, help="the record (default "
                        "benchmarks/results/ik.json; ik-<robot>.json for another robot)")
    parser.add_argument("--pink", action="store_true", help="also run pin-pink (optional)")
    args = parser.parse_args(argv)

    description = get_robot(args.robot)
    out = args.out or record_path("ik" if args.robot == "yumi" else f"ik-{args.robot}")
    robot = RobotModel.from_urdf(description.urdf_path, description.srdf_path)
    home = robot.q_from_dict(description.home)
    bullet = BulletIk(robot, description)
    try:
        results: dict[str, dict[str, dict[str, float]]] = {}
        for arm in description.arms:
            targets = random_targets(robot, arm, home, args.n, args.seed)
            ik = ArmIk(robot, arm.joints, arm.tcp_frame)
            frame = arm.tcp_frame
            results[arm.name] = {
                "ours": measure(robot, frame, ours_solver(ik, home), targets),
                "pybullet": measure(robot, frame, bullet.solver(arm), targets,
                                    clock=lambda: bullet.elapsed_s),
            }
            if args.pink:
                results[arm.name]["pink"] = measure(robot, frame, pink_solver(robot, arm, home),
                                                    targets)
    finally:
        bullet.close()
    print_table(results)
    report = {
        "benchmark": "ik",
        "robot": args.robot,
        "n_per_arm": args.n,
        "seed": args.seed,
        "success_bar": {"position_m": POSITION_OK_M, "rotation_rad": ROTATION_OK_RAD,
                        "within_limits": True},
        "ours_options": {k: v for k, v in vars(IkOptions()).items()},
        "pybullet_settings": {**BULLET_SETTINGS, "null_space": "limits, ranges, restPoses=home"},
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                    "python": platform.python_version(), "pinocchio": pin.__version__},
        "results": results,
    }
    write_record(out, report)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
