"""``--executor ray`` gives what the local pool gives: the same cells, counts and records.

Each run here joins the session's local Ray of 2 CPUs (``local_ray``), as a cluster run would
join its cluster; the local pool runs the same settings beside it.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from experiments.table2.run import run_reproduce_sim
from experiments.table2.settings import ReproduceSimSettings
from experiments.table3.jobs import CollectJob, TrainJob, job_resources
from experiments.table3.run import run_reproduce_real
from experiments.table3.settings import ReproduceRealSettings, Unit
from harness.inputs.trial_settings import TrialSettings
from harness.jobs import Executor, ExecutorKind, JobResources
from harness.run_loop import run_trials

pytestmark = pytest.mark.ray  # make test runs these alone, after the rest
RAY = Executor(ExecutorKind.RAY)


def _records(folder: Path) -> list[dict]:
    """A run's trial records by index, less wall times (the machine's) and the model's path."""
    records = [json.loads(line) for line in (folder / "trials.jsonl").read_text().splitlines()]
    return [{key: value for key, value in record.items() if "wall" not in key and key != "model"}
            for record in sorted(records, key=lambda record: record["index"])]


def test_a_small_table2_on_ray_has_the_cells_of_the_local_pool(local_ray, tmp_path):
    settings = ReproduceSimSettings(models=("kqv", "fcn"), tasks=("single",), sizes=(4,),
                                    seeds=1, steps=3, test_scenes=5, workers=2)  # a cell a worker
    local = run_reproduce_sim(settings, tmp_path / "local", progress=False)
    on_ray = run_reproduce_sim(dataclasses.replace(settings, executor=RAY), tmp_path / "ray",
                               progress=False)
    assert len(on_ray.computed) == len(local.computed) == 2 and not on_ray.failed
    cells = [json.loads((tmp_path / run / "table2.json").read_text())["cells"]
             for run in ("local", "ray")]
    for cell in (*cells[0], *cells[1]):
        cell.pop("train_s")  # the machine's
    assert cells[0] == cells[1]
    again = run_reproduce_sim(dataclasses.replace(settings, executor=RAY), tmp_path / "ray",
                              progress=False)
    assert not again.computed and len(again.skipped) == 2  # resumed: nothing twice


def test_a_one_task_table3_on_ray_has_the_counts_and_records_of_the_local_pool(
        local_ray, tmp_path):
    settings = ReproduceRealSettings(tasks=("single",), demos=2, n=2, steps=3, workers=2,
                                     variants=(), gif_trials=0)
    run_reproduce_real(settings, tmp_path / "local", progress=False)
    run_reproduce_real(dataclasses.replace(settings, executor=RAY), tmp_path / "ray",
                       progress=False)
    tables = [json.loads((tmp_path / run / "table3.json").read_text())["tasks"]
              for run in ("local", "ray")]
    for table in tables:
        table["single"].pop("median_wall_time_s")  # the machine's
    assert tables[0] == tables[1]
    trials = "s0/trials/kqv/single"
    assert _records(tmp_path / "local" / trials) == _records(tmp_path / "ray" / trials)


def test_trials_on_ray_write_the_records_of_one_process(local_ray, tmp_path):
    settings = TrialSettings(model="oracle", task="selected-type", n=2, seed=4)
    straight = run_trials(settings, tmp_path / "straight", progress=False)
    on_ray = run_trials(settings, tmp_path / "ray", progress=False, workers=2, executor=RAY)
    assert on_ray.n == straight.n == 2  # one a worker
    assert _records(tmp_path / "straight") == _records(tmp_path / "ray")


def test_each_job_declares_what_it_holds():
    settings = ReproduceRealSettings(tasks=("single",), train_threads=2)
    train = TrainJob("train-kqv-single-s0", Unit("kqv", "single"), settings, {}, Path("out"))
    collect = CollectJob("collect-single-s0", "single", settings, Path("out"))
    assert job_resources(train) == JobResources(cpus=2.0)
    assert job_resources(collect) == JobResources(cpus=1.0)
