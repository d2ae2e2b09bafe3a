"""Does a grasp get in ``gva/Pick-v0`` what it gets in a trial? The oracle, 30 scenes, two tasks.

    python benchmarks/check_gym_env.py [--n 30] [--out benchmarks/results/gym_env_oracle.json]

For each task, the oracle's grasps drive one env over test scenes 0..n-1 of seed 0, and
``gva trials --model oracle --seed 0`` (the trial runner, in this process) runs the same scenes;
the record holds both counts, the trials whose outcome or reason differ, and the seconds per
episode against those per trial (the env's overhead).
"""

from __future__ import annotations

import argparse
import time

import gymnasium
from results_file import add_out_option, write_record

from robots.yumi import YUMI
from sim.envs.episodes import oracle_policy, run_episode
from sim.tasks.task_toml import load_task
from sim.trials.trial_runner import TrialRunner
from sim.trials.trial_scenes import trial_scene


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=30, help="test scenes per task (30)")
    parser.add_argument("--tasks", default="single,selected-type", help="comma-separated")
    add_out_option(parser, "gym_env_oracle")
    args = parser.parse_args()
    record: dict[str, object] = {"benchmark": "gym_env_oracle", "seed": 0, "n": args.n}
    for task in args.tasks.split(","):
        started = time.perf_counter()
        spec = load_task(task)
        with TrialRunner(spec, robot=YUMI) as runner:
            trials = [runner.run(trial_scene(spec, 0, i), i, 0, "oracle") for i in range(args.n)]
        trial_s = time.perf_counter() - started
        env = gymnasium.make("sim.envs:gva/Pick-v0", task=task)
        started = time.perf_counter()
        episodes = [run_episode(env, oracle_policy(env), 0, i)
                    for i in range(args.n)]
        env_s = time.perf_counter() - started
        env.close()
        differ = [i for i, (t, e) in enumerate(zip(trials, episodes, strict=True))
                  if (t.outcome.value, t.reason) != (e.outcome, e.reason)]
        record[task] = {
            "trials_succeeded": sum(t.outcome.value == "success" for t in trials),
            "env_succeeded": sum(e.outcome == "success" for e in episodes),
            "differ": differ, "s_per_trial": trial_s / args.n, "s_per_episode": env_s / args.n,
        }
        print(task, record[task], flush=True)
    write_record(args.out, record)


if __name__ == "__main__":
    main()
