"""benchmarks/bench_serve_clients.py: gva serve under concurrent clients answers every one."""

from __future__ import annotations

import json
import os
from pathlib import Path

from benchmark_scripts import load_benchmark

PLUGINS = Path(__file__).resolve().parents[2] / "examples" / "plugins"
FAILING = '''
from colour_detector import ColourDetector


class Failing(ColourDetector):
    def predict_frame(self, frame, condition):
        raise RuntimeError("no prediction today")
'''


def test_concurrent_clients_are_all_answered(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(PLUGINS))
    monkeypatch.setenv("PYTHONPATH", str(PLUGINS))  # the server's process finds it too
    bench = load_benchmark("bench_serve_clients")
    out = tmp_path / "clients.json"
    assert bench.main(["--model", "colour_detector:ColourDetector", "--clients", "3",
                       "--requests", "2", "--frames", "2", "--out", str(out)]) == 0
    record = json.loads(out.read_text())
    assert (record["clients"], record["requests_per_client"]) == (3, 2)
    assert (record["answered"], record["failed"], record["failures"]) == (6, 0, [])
    latency = record["latency"]
    assert 0.0 < latency["median_s"] <= latency["p95_s"] <= latency["max_s"] <= record["wall_s"]
    assert record["idle_client"] and record["silent_socket"]
    assert record["idle_client_open_at_end"]
    assert record["machine"]["load_average_before"]


def test_an_unanswered_request_fails_the_benchmark_with_its_reason(tmp_path, monkeypatch):
    (tmp_path / "failing.py").write_text(FAILING)
    for folder in (PLUGINS, tmp_path):
        monkeypatch.syspath_prepend(str(folder))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(PLUGINS), str(tmp_path)]))
    bench = load_benchmark("bench_serve_clients")
    out = tmp_path / "clients.json"
    assert bench.main(["--model", "failing:Failing", "--clients", "2", "--requests", "1",
                       "--frames", "1", "--out", str(out)]) == 1
    record = json.loads(out.read_text())
    assert (record["answered"], record["failed"], record["latency"]) == (0, 2, None)
    [failure] = record["failures"]
    assert failure["count"] == 2 and "ServerSaidError" in failure["reason"]
    assert "no prediction today" in failure["reason"]
