"""One episode of ``gva/Pick-v0`` driven by a policy, as a named result.

What a user's evaluation loop does, written once: the example, the checks and the tests run
their episodes through it, with the oracle's grasps (:func:`oracle_policy`) or any model's
that ``gva trials --model`` takes (:func:`model_policy`: a checkpoint, a plug-in, a served one).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np

from perception.camera import RgbdFrame
from perception.interface import NO_CONDITION, Condition, ConditionKind
from sim.envs.pick_env import PickEnv
from sim.errors import InvalidInputError
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_in_scene import condition_choices
from sim.trials.trial_models import checked_model

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


def model_policy(env: gymnasium.Env[Any, Any], model: str, model_class: str | None = None,
                 allow_sensor_change: bool = False) -> Policy:
    """The grasps of a model ``gva trials --model`` takes, for ``env``'s current pick.

    ``model``: a checkpoint folder (``model_class``: the class that loads it, if unregistered),
    ``package.module:Class`` or an installed plug-in's name, ``ws://HOST:PORT`` (a model ``gva
    serve`` serves), or ``oracle`` (:func:`oracle_policy`). It is checked against the env's
    task and robot as ``gva trials`` checks it. Each observation becomes the model's frame (its
    RGB and depth, taken by :meth:`PickEnv.camera`, whose ``K`` and ``T_world_camera`` are the
    observation's) and condition (:func:`observed_condition`); the prediction becomes the
    action as a trial reads it (:meth:`PickEnv.action_of`). A model that gives no prediction
    (its server down) raises, naming why: an env step needs an action.
    """
    if model == "oracle":
        return oracle_policy(env)
    pick_env = _pick_env(env)
    built = checked_model(model, pick_env.task, pick_env.description, model_class,
                          allow_sensor_change)

    def policy(observation: dict[str, Any]) -> dict[str, Any]:
        camera = pick_env.camera()
        for key, value in (("K", camera.K), ("T_world_camera", camera.T_world_camera)):
            if not np.allclose(observation[key], value):
                raise InvalidInputError(f"observation[{key!r}]", np.asarray(
                    observation[key]).tolist(), "the env's current camera's (an observation "
                    "of this env, unchanged)")
        frame = RgbdFrame(observation["rgb"], observation["depth_m"], camera)
        prediction = built.predict_frame(frame, observed_condition(env, observation))
        return pick_env.action_of(prediction, built.name)

    return policy


def observed_condition(env: gymnasium.Env[Any, Any], observation: dict[str, Any]) -> Condition:
    """The condition an observation of ``env`` holds, as a model is given it.

    A one-hot kind's value is its vector's hot choice among the task's; a sentence and a
    picture are the observation's own.
    """
    pick_env = _pick_env(env)
    given = observation["condition"]
    kind = tuple(ConditionKind)[int(given["kind"])]
    if kind is ConditionKind.NONE:
        return NO_CONDITION
    if kind is ConditionKind.TEXT:
        return Condition(kind, str(given["sentence"]))
    if kind is ConditionKind.IMAGE:
        return Condition(kind, picture=np.asarray(given["picture"], dtype=np.uint8))
    choices = tuple(condition_choices(pick_env.task, YUMI_SCENE))
    return Condition(kind, choices[int(np.argmax(given["vector"]))], choices)


def _pick_env(env: gymnasium.Env[Any, Any]) -> PickEnv:
    """``env``'s :class:`PickEnv`, under any wrappers."""
    if not isinstance(env.unwrapped, PickEnv):
        raise InvalidInputError("env", type(env.unwrapped).__name__, "gva/Pick-v0 (a PickEnv, "
                                "wrapped or not)")
    return env.unwrapped
