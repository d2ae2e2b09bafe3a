"""``gva/Pick-v0``: Gymnasium's checks, and a grasp gets in the env what it gets in a trial."""

from __future__ import annotations

import functools
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AsyncVectorEnv, AutoresetMode

from robots import get_robot
from robots.yumi import YUMI
from sim.envs.episodes import oracle_policy, run_episode
from sim.errors import InvalidInputError
from sim.tasks.task_toml import builtin_tasks, load_task
from sim.trials.trial_runner import TrialRunner
from sim.trials.trial_scenes import trial_scene

ENV_ID = "sim.envs:gva/Pick-v0"  # the module prefix: no import of ours needed first


def make(**kwargs):
    return gymnasium.make(ENV_ID, **kwargs)


def trial_outcomes(task: str, n: int) -> dict[int, tuple[str, str]]:
    """What ``gva trials --model oracle --seed 0`` records for test scenes 0..n-1."""
    spec = load_task(task)
    with TrialRunner(spec, robot=YUMI) as runner:
        records = [runner.run(trial_scene(spec, 0, i), i, 0, "oracle") for i in range(n)]
    return {r.index: (r.outcome.value, r.reason) for r in records}


def env_outcomes(task: str, n: int) -> dict[int, tuple[str, str]]:
    """The same scenes as episodes of one env driven by the oracle's grasps."""
    env, outcomes = make(task=task), {}
    for index in range(n):
        episode = run_episode(env, oracle_policy(env), 0, index)
        assert episode.reward == episode.picks.count("success")  # 1 for each target picked
        assert (episode.reward == episode.targets) == (episode.outcome == "success")
        outcomes[index] = (episode.outcome, episode.reason)
    env.close()
    return outcomes


SCENES = 4
"""Test scenes of ``single`` both ways (two an env in the vector env); all 30 of two tasks:
benchmarks/check_gym_env.py."""


@pytest.fixture(scope="module")
def single_trials() -> dict[int, tuple[str, str]]:
    return trial_outcomes("single", SCENES)


@pytest.mark.slow
@pytest.mark.parametrize("task", builtin_tasks())
def test_gymnasiums_env_checker_passes(task: str) -> None:
    env = make(task=task, render_mode="rgb_array")
    with warnings.catch_warnings():  # depth is inf where a ray meets nothing: an honest bound
        warnings.filterwarnings("ignore", message=".*maximum value is infinity.*")
        check_env(env.unwrapped)
    env.close()


@pytest.mark.slow
def test_the_oracles_grasps_in_the_env_get_the_trials_outcomes(single_trials) -> None:
    assert env_outcomes("single", SCENES) == single_trials
    for task, n in (("selected-type", 2), ("multiple", 1)):  # one-hot; three picks a trial
        assert env_outcomes(task, n) == trial_outcomes(task, n), task


@pytest.mark.slow
def test_a_vector_env_of_two_gets_the_outcomes_of_one(single_trials) -> None:
    envs = AsyncVectorEnv([functools.partial(make, task="single", first_index=k, index_step=2)
                           for k in range(2)], autoreset_mode=AutoresetMode.SAME_STEP)
    envs.reset(seed=[0, 0])
    outcomes: dict[int, tuple[str, str]] = {}
    while not set(range(SCENES)) <= set(outcomes):  # each env steps its own indices
        _, _, terminated, _, info = envs.step(
            {key: np.stack([a[key] for a in envs.call("oracle_action")])
             for key in ("position_m", "rotation_6d", "object_type", "opening_m")})
        final = info["final_info"]
        for k in np.flatnonzero(terminated):
            outcomes[int(final["index"][k])] = (str(final["trial_outcome"][k]),
                                                str(final["trial_reason"][k]))
    envs.close()
    assert {i: outcomes[i] for i in range(SCENES)} == single_trials


def test_a_scene_is_the_same_whatever_ran_before() -> None:
    env = make(task="selected-type")
    first, _ = env.reset(seed=3, options={"index": 5})
    env.step(env.unwrapped.oracle_action())
    env.reset(seed=0)
    again, info = env.reset(seed=3, options={"index": 5})
    assert info["index"] == 5
    np.testing.assert_array_equal(first["rgb"], again["rgb"])
    np.testing.assert_array_equal(first["condition"]["vector"], again["condition"]["vector"])
    _, info = env.reset()  # no options: the next index
    assert (info["seed"], info["index"]) == (3, 6)
    env.close()


def test_bad_input_names_the_field() -> None:
    env = make(task="single")
    with pytest.raises(gymnasium.error.ResetNeeded):
        env.unwrapped.step({"position_m": np.zeros(3), "rotation_6d": np.eye(3)[:, :2].T.ravel()})
    env.reset(seed=0)
    good = env.unwrapped.oracle_action()
    with pytest.raises(InvalidInputError, match=r"action\['rotation_6d'\].*non-parallel"):
        env.step(good | {"rotation_6d": np.array([1.0, 0, 0, 2.0, 0, 0])})
    with pytest.raises(InvalidInputError, match=r"action = \['position_m'\]"):
        env.step({"position_m": good["position_m"]})
    with pytest.raises(InvalidInputError, match=r"options = \['idx'\]"):
        env.reset(options={"idx": 1})
    with pytest.raises(InvalidInputError, match="first_index = -1"):
        make(task="single", first_index=-1)
    env.close()


def test_a_refused_reset_leaves_the_env_usable() -> None:
    # issue 63: after a refused first reset, a good reset then every step raised
    # "TypeError: cannot unpack non-iterable NoneType" (the checker gymnasium.make added)
    env = make(task="single")
    with pytest.raises(InvalidInputError, match=r"options\['index'\] = -1 is not allowed"):
        env.reset(options={"index": -1})
    env.reset(seed=3, options={"index": 5})
    _, _, terminated, _, info = env.step(env.unwrapped.oracle_action())
    assert terminated and (info["seed"], info["index"]) == (3, 5)
    with pytest.raises(InvalidInputError, match=r"options\['index'\] = -2 is not allowed"):
        env.reset(seed=7, options={"index": -2})  # refused: changes nothing
    with pytest.raises(InvalidInputError, match=r"seed = -1 is not allowed"):
        env.reset(seed=-1)
    _, info = env.reset()
    assert (info["seed"], info["index"]) == (3, 6)
    _, _, _, _, info = env.step(env.unwrapped.oracle_action())
    assert info["outcome"]
    env.close()


def test_an_action_of_no_numbers_or_overflowing_ones_is_refused_naming_the_field() -> None:
    # issue 63: [1e300, 0, 0, 0, 1e300, 0] overflowed to a zero matrix, blamed on the oracle;
    # a string position raised numpy's "could not convert string to float"
    env = make(task="single")
    env.reset(seed=0)
    good = env.unwrapped.oracle_action()
    for change, field, allowed in [
            ({"rotation_6d": np.array([1e300, 0, 0, 0, 1e300, 0])}, "rotation_6d",
             "6 finite numbers within +-1e+100"),
            ({"rotation_6d": np.array([1e90, 0, 0, 1e90, 1e70, 0])}, "rotation_6d",
             "two non-parallel 3-vectors"),
            ({"rotation_6d": np.array([np.inf, 0, 0, 0, 1, 0])}, "rotation_6d",
             "6 finite numbers"),
            ({"position_m": "abc"}, "position_m", "3 finite numbers"),
            ({"position_m": np.array([np.nan, 0, 0])}, "position_m", "3 finite numbers"),
            ({"object_type": "mug"}, "object_type", "an integer, 0 (not stated) to 3"),
            ({"opening_m": "wide"}, "opening_m", "0 (not stated) or a gap")]:
        with pytest.raises(InvalidInputError) as refused:
            env.step(good | change)
        value = change[field]
        shown = value.tolist() if isinstance(value, np.ndarray) else value
        assert str(refused.value).startswith(
            f"action['{field}'] = {shown!r} is not allowed: {allowed}"), str(refused.value)
    _, _, terminated, _, _ = env.step(good)  # the refused actions changed nothing
    assert terminated
    env.close()


def test_a_grasp_far_off_is_a_recorded_failure_not_a_crash() -> None:
    env = make(task="single")
    env.reset(seed=0, options={"index": 0})
    action = env.unwrapped.oracle_action() | {"position_m": np.array([0.9, 0.9, 0.5])}
    _, reward, terminated, _, info = env.step(action)
    assert (reward, terminated) == (0.0, True)
    assert info["outcome"] != "success" and info["reason"] and info["trial_outcome"]
    assert info["judge"]["predicted_success"] is False
    env.close()


def test_the_panda_env_gets_the_panda_trials_outcomes() -> None:
    """``robot="panda"``: its camera, its joints, its spaced scenes; a grasp gets there what
    it gets in ``gva trials --robot panda``."""
    env = make(task="single", robot="panda")
    panda = get_robot("panda")
    assert env.unwrapped.joint_names == tuple(TrialRunner(load_task("single"), robot=panda)
                                              .world.robot.joint_names)
    assert env.unwrapped.task.min_spacing_m == panda.neighbour_spacing_m
    assert env.action_space["opening_m"].high[0] == 0.08  # the Panda's hand opens 80 mm
    spec = env.unwrapped.task
    with TrialRunner(spec, robot=panda) as runner:
        trials = {i: runner.run(trial_scene(spec, 0, i), i, 0, "oracle") for i in range(2)}
    for index, record in trials.items():
        episode = run_episode(env, oracle_policy(env), 0, index)
        assert (episode.outcome, episode.reason) == (record.outcome.value, record.reason)
    with pytest.raises(InvalidInputError, match=r"robot = 'ur5' is not allowed: one of yumi, "
                                                r"panda"):
        make(task="single", robot="ur5")
    env.close()


def test_the_env_sees_through_the_d435_unless_its_sensor_says_otherwise() -> None:
    """Issue 64: ``sensor=`` means what ``gva trials --sensor`` does; the default is the D435."""
    from sim.world.sensor import SensorConfig, SensorKind

    for kwargs, sensor in (({}, SensorConfig(SensorKind.D435)), ({"sensor": "ideal"},
                                                                 SensorConfig())):
        env = make(task="single", **kwargs)
        assert env.unwrapped.task.camera == sensor
        assert env.unwrapped._runner.mounted_camera.sensor == sensor
        env.close()
    with pytest.raises(InvalidInputError, match="sensor = 'kinect' is not allowed"):
        make(task="single", sensor="kinect")
