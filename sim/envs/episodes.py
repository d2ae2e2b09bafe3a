"""One episode of ``gva/Pick-v0`` driven by a policy, as a named result.

What a user's evaluation loop does, written once: the example, the checks and the tests run
their episodes through it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium

Policy = Callable[[dict[str, Any]], dict[str, Any]]
"""Maps an observation to an action (a grasp) of ``gva/Pick-v0``."""


@dataclass(frozen=True)
class Episode:
    """How one episode went.

    Args:
        seed, index: The test scene it ran on.
        targets: How many targets the scene had.
        reward: The episode's total reward: the targets picked.
        picks: Each pick's outcome, in order (``TrialOutcome`` values).
        outcome, reason: The trial's outcome and why, as ``gva trials`` records them.

    """

    seed: int
    index: int
    targets: int
    reward: float
    picks: tuple[str, ...]
    outcome: str
    reason: str


def run_episode(env: gymnasium.Env[Any, Any], policy: Policy, seed: int, index: int) -> Episode:
    """Resets ``env`` to test scene ``index`` of ``seed`` and steps ``policy`` until the end."""
    observation, info = env.reset(seed=seed, options={"index": index})
    reward, picks, done = 0.0, list[str](), False
    targets = int(info["targets"])
    while not done:
        observation, step_reward, terminated, truncated, info = env.step(policy(observation))
        reward += float(step_reward)
        picks.append(info["outcome"])
        done = terminated or truncated
    return Episode(seed, index, targets, reward, tuple(picks), info["trial_outcome"],
                   info["trial_reason"])


def oracle_policy(env: gymnasium.Env[Any, Any]) -> Policy:
    """The oracle's grasps for ``env``'s current pick (it reads the simulator's truth)."""
    pick_env = env.unwrapped
    return lambda _observation: pick_env.oracle_action()  # type: ignore[attr-defined]
