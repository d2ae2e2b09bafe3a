"""Every command the README shows, for every registered model, every built-in task, each scene.

The chain a user runs (``gva collect`` -> ``gva train`` -> ``gva evaluate`` -> ``gva show
attention`` -> ``gva trials --n 1``) on tiny datasets and a few steps, in both scenes (``yumi``:
the robot's demonstrations and pick trials; ``paper-sim``: Table II's images, offline only),
and ``gva reproduce sim`` / ``gva reproduce real`` with every model at tiny sizes. A command a
model cannot serve (attention pictures of a model without attention, pick trials of a
position model) must be refused in one line before it writes anything, never crash half-way.

A model joins by being registered (:data:`perception.registry.MODELS` or a preset), a task by
shipping in ``sim/tasks/task_files/``. One class per task, so ``make test``'s workers (a class
each, ``--dist loadscope``) share the load and each collects its datasets once.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest
from gva_cli import gva

from experiments import tables
from perception.learning.dataset_file import load_dataset
from perception.registry import MODELS, PRESETS, load_model, model_class
from sim.tasks.scene_specs import SCENE_NAMES
from sim.tasks.task_toml import builtin_tasks
from sim.trials.records import TrialOutcome

pytestmark = pytest.mark.slow


def registered_models() -> tuple[str, ...]:
    """Every model by the name ``gva train`` takes: each preset, and each registered model
    no preset stands for (``keypoint`` is ``keypoint-16``, ``dsae`` is ``dsae-16``: presets
    that set only defaults; ``kqv-mlp`` changes ``kqv``'s readout, so both are tried)."""
    def at_defaults(base: str, settings: Mapping[str, Any]) -> bool:
        config = model_class(base).config_class()
        return all(getattr(config, key) == value for key, value in settings.items())

    same = {base for base, settings in PRESETS.values() if at_defaults(base, settings)}
    return (*(name for name in MODELS if name not in same), *PRESETS)


MATRIX_MODELS = registered_models()
TRAIN = ["--steps", "2", "--batch-size", "2", "--threads", "1", "--holdout", "0",
         "--no-progress"]
"""Two optimiser steps: the matrix proves that every path runs, not that a model learns."""
PICKS = "yumi"
"""The scene pick trials run in; a checkpoint of the other predicts positions, not grasps."""


def one_line(text: str) -> str:
    """``text``'s only line; fails unless it is exactly one."""
    lines = text.strip().splitlines()
    assert len(lines) == 1, text
    return lines[0]


@pytest.fixture(scope="class")
def datasets(request: pytest.FixtureRequest,
             tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """``gva collect``: one training and one test scene of the class's task in each scene."""
    task = request.cls.task
    root = tmp_path_factory.mktemp(f"matrix-{task}")
    paths = {}
    for scene in SCENE_NAMES:
        for stream in ("train", "test"):
            path = root / f"{scene}-{stream}.gva"
            status, out, err = gva("collect", "--scene", scene, "--task", task, "--size", 1,
                                   "--stream", stream, "--out", path, "--no-progress")
            assert status == 0, err
            assert out.splitlines()[-1] == f"dataset: {path}"
            meta = load_dataset(path).metadata
            assert (meta.scene, meta.task) == (scene, task)
            paths[f"{scene}-{stream}"] = path
    return paths


class Chain:
    """The README's chain of commands on one task (``task``), for every model and scene."""

    task: ClassVar[str]

    @pytest.mark.parametrize("scene", SCENE_NAMES)
    @pytest.mark.parametrize("model", MATRIX_MODELS)
    def test_every_command_runs(self, model: str, scene: str, datasets: dict[str, Path],
                                tmp_path: Path) -> None:
        train, test = datasets[f"{scene}-train"], datasets[f"{scene}-test"]
        checkpoint = tmp_path / "checkpoint"
        status, out, err = gva("train", "--model", model, "--data", train, "--out", checkpoint,
                               *TRAIN)
        assert status == 0, err
        trained = load_model(checkpoint)
        assert (trained.spec.scene, trained.spec.task) == (scene, self.task)
        test_set = load_dataset(test)
        depth = None if test_set.depths_m is None else test_set.depths_m[:1]  # kqv reads it
        seen = trained.predict_batch(test_set.images[:1], test_set.conditions[:1], depth)[0]

        evaluation = tmp_path / "evaluation.json"
        status, out, err = gva("evaluate", "--model", checkpoint, "--data", test,
                               "--out", evaluation)
        assert status == 0, err
        assert out.startswith(f"{trained.name} on {scene} / {self.task} ({len(test_set)} "
                              "images): position error mean ")
        result = json.loads(evaluation.read_text())
        assert np.isfinite(result["mean_position_error_cm"])
        assert (result["median_heatmap_entropy_nats"] is None) == (seen.heatmaps is None)
        if not trained.attention_per_target:
            assert result["attention_on_named_fraction"] is None

        pictures = tmp_path / "attention"
        status, out, err = gva("show", "attention", "--model", checkpoint, "--data", test,
                               "--out", pictures, "--count", 1, "--scale", 1)
        if len(seen.attention_px):
            assert status == 0, err
            assert (pictures / "attention-000.png").read_bytes()[:4] == b"\x89PNG"
        else:  # conv-ae, fcn: nothing to draw, said in one line, nothing written
            assert status == 2
            assert "predicts no attention points" in one_line(err)
            assert not pictures.exists()

        trials = tmp_path / "trials"
        status, out, err = gva("trials", "--model", checkpoint, "--task", self.task,
                               "--n", 1, "--out", trials, "--no-progress")
        if scene == PICKS:
            assert status == 0, err
            records = (trials / "trials.jsonl").read_text().splitlines()
            assert len(records) == 1
            outcome = TrialOutcome(json.loads(records[0])["outcome"])
            assert outcome is not TrialOutcome.ERROR, records[0]
            assert_strict_json(trials)
        else:  # a position model cannot pick: refused before any trial
            assert status == 2
            assert "label_kind = 'position' is not allowed" in one_line(err)
            assert not (trials / "trials.jsonl").exists()


def assert_strict_json(folder: Path) -> None:
    """Every JSON file and JSON-lines record under ``folder`` parses strictly: no NaN, no
    Infinity, which strict readers refuse (issue 77: a server's NaN reached run.json)."""
    def refuse(constant: str) -> None:
        raise AssertionError(f"{constant} in a JSON file")

    files = [*folder.rglob("*.json"), *folder.rglob("*.jsonl")]
    assert files
    for path in files:
        text = path.read_text(encoding="utf-8")
        for line in (text.splitlines() if path.suffix == ".jsonl" else [text]):
            if line.strip():
                try:
                    json.loads(line, parse_constant=refuse)
                except AssertionError as error:
                    raise AssertionError(f"{path}: {error}") from None


# One test class per built-in task (TestSingle, TestSelectedTypeText, ...): a shipped task joins.
for _task in builtin_tasks():
    _name = "Test" + "".join(word.title() for word in _task.split("-"))
    globals()[_name] = type(_name, (Chain,), {"task": _task, "__doc__": Chain.__doc__})


def test_the_tables_take_every_shipped_task_and_name_registered_models() -> None:
    """What the reproduce tests below run is every task gva ships, with registered models."""
    assert set(tables.ALL_TASKS) == set(builtin_tasks())
    assert set(tables.PAPER_MODELS) <= set(MATRIX_MODELS)


class TestReproduceSim:
    """``gva reproduce sim`` with every registered model and preset, every task, size 4."""

    def test_reproduce_sim_computes_every_cell_of_every_model_and_task(
            self, tmp_path: Path) -> None:
        out = tmp_path / "table2"
        status, stdout, err = gva(
            "reproduce", "sim", "--out", out, "--models", ",".join(MATRIX_MODELS),
            "--tasks", ",".join(tables.ALL_TASKS), "--sizes", 4, "--seeds", 1, "--steps", 2,
            "--test-scenes", 2, "--workers", 1, "--no-progress")
        cells = len(MATRIX_MODELS) * len(tables.ALL_TASKS)
        assert status == 0, stdout + err
        assert f"{cells} cell(s) computed (0 failed)" in stdout
        table = json.loads((out / "table2.json").read_text())
        assert table["failed"] == []
        assert {(c["model"], c["task"]) for c in table["cells"]} == {
            (m, t) for m in MATRIX_MODELS for t in tables.ALL_TASKS}
        markdown = (out / "table2.md").read_text()
        for model in MATRIX_MODELS:
            assert f"| {tables.model_title(model)} |" in markdown


class ReproduceReal:
    """``gva reproduce real`` with ``models`` on ``tasks``, one pick each, and no GIFs: a GIF
    replays its trials (as long again as the picks here); ``test_reproduce_real.py`` records
    one, and every model's attention points are drawn by ``gva show attention`` above."""

    tasks: ClassVar[tuple[str, ...]]
    models: ClassVar[tuple[str, ...]]

    def test_reproduce_real_picks_with_its_models(self, tmp_path: Path) -> None:
        out = tmp_path / "table3"
        status, stdout, err = gva(
            "reproduce", "real", "--out", out, "--models", ",".join(self.models),
            "--tasks", ",".join(self.tasks), "--demos", 1, "--n", 1, "--steps", 2,
            "--no-robustness", "--gif-trials", 0, "--workers", 1, "--no-progress")
        assert status == 0, stdout + err
        assert "(0 failed)" in stdout
        table = json.loads((out / "table3.json").read_text())
        for model in self.models:
            for task in self.tasks:
                counted = table["models"][model][task]
                assert counted["n"] == 1 and counted["outcomes"]["error"] == 0, counted
        assert not (out / "s0" / "gifs").exists()  # --gif-trials 0: none made
        markdown = (out / "table3.md").read_text()
        assert "--no-robustness --gif-trials 0" in markdown  # the command, to run it again
        assert_strict_json(out)
        for model in self.models:
            assert f"| {tables.model_title(model)} |" in markdown


class TestReproduceRealPaperModels(ReproduceReal):
    """Every model of the paper on the paper's task of several targets and on one of its
    conditioned tasks: what ``reproduce real`` adds to the chain above is the training job and
    its held-out check, which reads per target (``multiple``) or per condition (the selected
    tasks); ``single`` and ``selected-position`` ask nothing of a model that these two do not,
    and every model meets them in the chain (train, trials)."""

    tasks = ("multiple", "selected-type")
    models = tables.PAPER_MODELS


class TestReproduceRealEveryTask(ReproduceReal):
    """Every other task, the paper's and beyond, with ``kqv`` and a model that predicts no
    attention: each other model meets these tasks in the chain above (train, trials), and
    ``reproduce real`` with every model above, so the pairs left out test nothing new (and cost
    a minute of ``make test``)."""

    tasks = tuple(task for task in tables.ALL_TASKS
                  if task not in TestReproduceRealPaperModels.tasks)
    models = ("kqv", "fcn")


def test_the_reproduce_real_classes_try_every_task_and_every_paper_model() -> None:
    tried = {(model, task) for cls in (TestReproduceRealPaperModels, TestReproduceRealEveryTask)
             for model in cls.models for task in cls.tasks}
    assert {task for _, task in tried} == set(tables.ALL_TASKS)
    assert {model for model, _ in tried} == set(tables.PAPER_MODELS)
