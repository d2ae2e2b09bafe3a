"""benchmarks/bench_closed_loop.py runs a cycle as the loop does and records every part."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_one_cycle_is_timed_part_by_part(tmp_path):
    sys.path.insert(0, str(ROOT / "benchmarks"))
    spec = importlib.util.spec_from_file_location("bench_closed_loop",
                                                  ROOT / "benchmarks" / "bench_closed_loop.py")
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    out = tmp_path / "cycle.json"
    assert bench.main(["--n", "2", "--out", str(out)]) == 0
    record = json.loads(out.read_text())
    assert set(record["parts_ms"]) == set(bench.PARTS)
    assert sum(record["answers"].values()) == 2
    assert record["cycle_median_ms"] > 0.0
