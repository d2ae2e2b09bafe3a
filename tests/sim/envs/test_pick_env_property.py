"""Generated Gym actions and reset options thrown at gva/Pick-v0 (issue 63).

An action is turned into a grasp or refused by an ``InvalidInputError`` in one line naming
``action['field']``; a reset's seed and options are taken or refused naming them, and a
refused reset leaves the env usable. Never another exception.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from perception.interface import Target
from sim.envs.pick_env import PickEnv
from sim.errors import InvalidInputError

_ODD = st.one_of(
    st.sampled_from([None, True, "abc", math.nan, math.inf, -math.inf, 1e300, -1e300, 2**64,
                     [], [1, 2], {}, 1.5, -1, 0, 3, 4]),
    st.integers(-5, 5), st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=5),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=0, max_size=7))
_VALID = {
    "position_m": st.lists(st.floats(-0.6, 0.6), min_size=3, max_size=3).map(np.array),
    "rotation_6d": st.lists(st.floats(-1, 1), min_size=6, max_size=6).map(np.array),
    "object_type": st.integers(0, 3),
    "opening_m": st.lists(st.floats(0, 0.05), min_size=1, max_size=1).map(np.array),
}


@pytest.fixture(scope="module")
def env():
    made = PickEnv("single")
    made.reset(seed=0)
    yield made
    made.close()


@st.composite
def actions(draw: st.DrawFn) -> dict:
    action = {key: draw(values) for key, values in _VALID.items()}
    for _ in range(draw(st.integers(0, 2))):
        key = draw(st.sampled_from([*_VALID, "extra"]))
        if draw(st.booleans()):
            action.pop(key, None)
        else:
            action[key] = draw(_ODD)
    return action


@settings(max_examples=300, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(action=actions())
def test_any_action_is_a_grasp_or_refused_naming_its_field(env, action):
    try:
        target = env._target(action)
    except InvalidInputError as error:
        message = str(error)
        assert "\n" not in message and "action" in error.field, message
        event(f"refused: {error.field}")
        return
    assert isinstance(target, Target) and np.isfinite(target.position_m).all()
    event("a grasp")


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.one_of(st.none(), st.integers(-3, 5), _ODD),
       options=st.one_of(st.none(), st.dictionaries(st.sampled_from(["index", "seed", "x"]),
                                                    _ODD, max_size=2)))
def test_any_reset_is_taken_or_refused_and_the_env_goes_on(env, seed, options):
    try:
        env.reset(seed=seed, options=options)
        event("reset")
    except InvalidInputError as error:
        assert "\n" not in str(error)
        event(f"refused: {error.field}")
    observation, _ = env.reset(seed=0, options={"index": 0})  # usable after either
    assert env.observation_space.contains(observation)
