"""benchmarks/results_file.py: records written as the scripts wrote them by hand; NaN refused."""

from __future__ import annotations

import argparse
import json
import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import pytest
from benchmark_scripts import load_benchmark

results_file = load_benchmark("results_file")


@dataclass
class _Row:
    name: str
    ms: float


RECORD = {"machine": {"cpus": 2, "load": [1.5, 0.25]}, "rows": [asdict(_Row("ik", 0.57))],
          "note": "2 °C, \"quoted\"", "empty": {}, "none": None, "flag": True, "n": 10**20}


@pytest.mark.parametrize("indent", [1, 2])
def test_the_bytes_are_the_old_hand_written_form(tmp_path, indent, capsys):
    path = tmp_path / "deep" / "folder" / "record.json"
    results_file.write_record(path, RECORD, indent=indent)
    assert path.read_bytes() == (json.dumps(RECORD, indent=indent) + "\n").encode()
    assert capsys.readouterr().out == f"wrote {path}\n"


def test_default_converts_as_json_dumps_does(tmp_path):
    record = {"names": {"b", "a"}, "path": Path("x/y")}
    results_file.write_record(tmp_path / "list.json", {"names": frozenset("a")}, default=list)
    results_file.write_record(tmp_path / "str.json", record, default=str, announce=False)
    assert (tmp_path / "list.json").read_text() == '{\n  "names": [\n    "a"\n  ]\n}\n'
    assert (tmp_path / "str.json").read_text() == json.dumps(record, indent=2, default=str) + "\n"


def test_a_record_replaces_the_old_one_and_leaves_nothing_beside_it(tmp_path, capsys):
    path = tmp_path / "record.json"
    path.write_text("old\n")
    results_file.write_record(path, [1, 2], announce=False)
    assert path.read_text() == "[\n  1,\n  2\n]\n"
    assert os.listdir(tmp_path) == ["record.json"]
    assert capsys.readouterr().out == ""


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_nan_and_infinity_are_refused_by_where_they_sit(tmp_path, bad):
    path = tmp_path / "record.json"
    path.write_text("old\n")
    with pytest.raises(ValueError, match=r"\['rows'\]\[1\]\['ms'\] \((nan|inf|-inf)\)"):
        results_file.write_record(path, {"rows": [{"ms": 1.0}, {"ms": bad}]})
    assert path.read_text() == "old\n"  # the earlier record stands
    assert os.listdir(tmp_path) == ["record.json"]


def test_the_out_option_defaults_to_the_results_folder():
    parser = argparse.ArgumentParser()
    results_file.add_out_option(parser, "trials")
    results_file.add_out_option(parser, "ablation", flag="--json")
    args = parser.parse_args([])
    assert args.out == Path("benchmarks/results/trials.json")
    assert args.json == Path("benchmarks/results/ablation.json")
    assert parser.parse_args(["--out", "a/b.json"]).out == Path("a/b.json")
    assert results_file.record_path("ik-panda") == Path("benchmarks/results/ik-panda.json")
