"""benchmarks/bench_ik.py measures our IK against PyBullet's on every arm of either robot."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(("robot", "arms"), [("yumi", {"r", "l"}), ("panda", {"panda"})])
def test_each_arm_is_measured_against_the_bar(tmp_path, robot, arms):
    spec = importlib.util.spec_from_file_location("bench_ik", ROOT / "benchmarks" / "bench_ik.py")
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    out = tmp_path / "ik.json"
    assert bench.main(["--n", "20", "--robot", robot, "--out", str(out)]) == 0
    record = json.loads(out.read_text())
    assert record["robot"] == robot and set(record["results"]) == arms
    for by_solver in record["results"].values():
        assert set(by_solver) == {"ours", "pybullet"}
        assert by_solver["ours"]["success_rate"] >= 0.95  # 20 poses: the bar's 99.5 % is 1000's
