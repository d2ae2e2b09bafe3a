"""Drive a gva task through Gymnasium: ``gva/Pick-v0``, one step per pick.

    python examples/06_gymnasium.py

Five episodes of ``selected-type`` on the test scenes of seed 0, the same scenes as trials 0-4
of ``gva trials --task selected-type --seed 0``. The policy here is the oracle's grasp (it
reads the simulator's truth); yours maps the observation (the head camera's RGB, depth [m], K,
T_world_camera, the joints and the condition) to a grasp: the TCP position [m] and its x and y
axes in the world, optionally the object type.
"""

from __future__ import annotations

import gymnasium
import numpy as np

from sim.envs.episodes import oracle_policy, run_episode


def main() -> None:
    env = gymnasium.make("sim.envs:gva/Pick-v0", task="selected-type")  # imports sim.envs
    observation, _ = env.reset(seed=0, options={"index": 0})
    print("observation:", {key: getattr(value, "shape", value) for key, value in
                           observation.items()})
    print("the condition, one-hot over", env.unwrapped.object_types, "->",
          observation["condition"]["vector"])
    print("an action:", {key: np.round(value, 3) for key, value in
                         env.unwrapped.oracle_action().items()})
    for index in range(5):
        episode = run_episode(env, oracle_policy(env), seed=0, index=index)
        print(f"scene {index}: reward {episode.reward:.0f} of {episode.targets}, "
              f"{episode.outcome}: {episode.reason}")
    env.close()


if __name__ == "__main__":
    main()
