"""``model_policy``: a model ``gva trials --model`` takes drives ``gva/Pick-v0``, served too.

The colour detector (examples/plugins) is served in a thread; its grasps in the env, through
the websocket, get the outcomes its in-process trials get on the same scenes.
"""

from __future__ import annotations

from collections.abc import Iterator

import gymnasium
import pytest
from served_detector import DETECTOR, PLUGINS, serve

from perception.interface import PerceptionModel
from perception.plugins import build_plugin
from perception.remote.client import RemoteModelError
from robots.yumi import YUMI
from sim.envs.episodes import model_policy, observed_condition, run_episode
from sim.errors import InvalidInputError
from sim.tasks.task_toml import load_task
from sim.trials.trial_runner import TrialRunner
from sim.trials.trial_scenes import trial_scene

ENV_ID = "sim.envs:gva/Pick-v0"
SCENES = 2


@pytest.fixture(scope="module")
def detector() -> Iterator[PerceptionModel]:
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(PLUGINS))
        yield build_plugin(DETECTOR)


def test_a_served_models_episodes_get_its_trials_outcomes(detector):
    task = load_task("single")
    with TrialRunner(task, lambda world, camera: detector, robot=YUMI) as runner:
        trials = [runner.run(trial_scene(task, 0, i), i, 0, DETECTOR) for i in range(SCENES)]
    server = serve(detector)
    env = gymnasium.make(ENV_ID, task="single", sensor="ideal")  # the task's, as trials see
    try:
        policy = model_policy(env, f"ws://127.0.0.1:{server.port}")
        episodes = [run_episode(env, policy, 0, i) for i in range(SCENES)]
    finally:
        env.close()
        server.shutdown()
    assert [(e.outcome, e.reason) for e in episodes] == [
        (t.outcome.value, t.reason) for t in trials]
    assert any(e.outcome == "success" for e in episodes)  # it did pick, not only fail alike


@pytest.mark.parametrize("task", ["selected-type", "selected-position", "selected-type-image"])
def test_the_observations_condition_is_the_scenes(task):
    env = gymnasium.make(ENV_ID, task=task)
    try:
        observation, _ = env.reset(seed=0, options={"index": 1})
        assert observed_condition(env, observation) == env.unwrapped._scene.given
    finally:
        env.close()


def test_a_server_gone_raises_why_and_a_bad_model_is_refused_by_name(detector):
    server = serve(detector)
    env = gymnasium.make(ENV_ID, task="single")
    try:
        policy = model_policy(env, f"ws://127.0.0.1:{server.port}")
        server.shutdown()
        observation, _ = env.reset(seed=0)
        with pytest.raises(RemoteModelError, match="unreachable"):
            policy(observation)
        with pytest.raises(InvalidInputError, match="model = 'no-such-model'"):
            model_policy(env, "no-such-model")
    finally:
        env.close()
