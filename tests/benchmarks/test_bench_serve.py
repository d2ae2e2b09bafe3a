"""benchmarks/bench_serve.py times a served model against in-process and counts its bytes."""

from __future__ import annotations

import json
from pathlib import Path

from benchmark_scripts import load_benchmark

PLUGINS = Path(__file__).resolve().parents[2] / "examples" / "plugins"


def test_a_served_plugin_is_timed_against_in_process(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(PLUGINS))
    monkeypatch.setenv("PYTHONPATH", str(PLUGINS))  # the server's process finds it too
    bench = load_benchmark("bench_serve")
    out = tmp_path / "serve.json"
    assert bench.main(["--model", "colour_detector:ColourDetector", "--n", "4", "--frames",
                       "2", "--warmup", "1", "--out", str(out)]) == 0
    record = json.loads(out.read_text())
    assert record["identical_predictions"] == "4/4"
    assert record["remote"]["median_ms"] > 0.0 and "median_ms" in record["overhead"]
    sizes = record["bytes_per_pick"]
    assert sizes["request_payload"] > 128 * 128 * 3  # the RGB alone
    assert sizes["sent_on_wire"] == sizes["request_payload"] + 14  # 64-bit length, masked
    assert record["machine"]["load_average_1_5_15min_before"]
