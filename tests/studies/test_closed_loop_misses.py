"""studies/closed_loop_misses.py sorts a moved-target pick's miss by what its looks did."""

from __future__ import annotations

import pytest
from benchmark_scripts import load_study


def record(outcome: str, *looks: tuple[float, str, float]) -> dict:
    """A trial moved at 1.0 s whose looks are (time [s], reaction, grasp error [m])."""
    return {"outcome": outcome, "picks": [{
        "disturbance": {"time_s": 1.0},
        "repredictions": [{"time_s": t, "reaction": r, "position_error_m": e}
                          for t, r, e in looks]}]}


@pytest.mark.parametrize(("trial", "expected"), [
    (record("missed", (0.9, "held", 0.001), (1.1, "retargeted", 0.01)), "followed, off"),
    (record("missed", (1.1, "hidden", 0.06), (1.2, "hidden", 0.011)),
     "not followed: seen, unheeded"),
    (record("missed", (0.9, "held", 0.001), (1.1, "hidden", 0.05)), "not followed: never seen"),
    (record("missed", (0.9, "retargeted", 0.001)), "not followed: never seen"),  # before it
    (record("plan_collision"), "other"),
])
def test_a_miss_is_classed_by_the_looks_after_the_move(trial, expected):
    assert load_study("closed_loop_misses").miss_class(trial) == expected
