"""benchmarks/bench_closed_loop.py runs a cycle as the loop does and records every part."""

from __future__ import annotations

import json

from benchmark_scripts import load_benchmark


def test_one_cycle_is_timed_part_by_part(tmp_path):
    bench = load_benchmark("bench_closed_loop")
    out = tmp_path / "cycle.json"
    assert bench.main(["--n", "2", "--out", str(out)]) == 0
    record = json.loads(out.read_text())
    assert set(record["parts_ms"]) == set(bench.PARTS)
    assert sum(record["answers"].values()) == 2
    assert record["cycle_median_ms"] > 0.0
