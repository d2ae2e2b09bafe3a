"""benchmarks/bench_ik.py measures our IK against PyBullet's on every arm of either robot."""

from __future__ import annotations

import json

import pytest
from benchmark_scripts import load_benchmark


@pytest.mark.parametrize(("robot", "arms"), [("yumi", {"r", "l"}), ("panda", {"panda"})])
def test_each_arm_is_measured_against_the_bar(tmp_path, robot, arms):
    bench = load_benchmark("bench_ik")
    out = tmp_path / "ik.json"
    assert bench.main(["--n", "20", "--robot", robot, "--out", str(out)]) == 0
    record = json.loads(out.read_text())
    assert record["robot"] == robot and set(record["results"]) == arms
    for by_solver in record["results"].values():
        assert set(by_solver) == {"ours", "pybullet"}
        assert by_solver["ours"]["success_rate"] >= 0.95  # 20 poses: the bar's 99.5 % is 1000's
