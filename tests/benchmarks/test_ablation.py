"""benchmarks/ablation.py: its row files, its statistics and ``--from`` on hand-made run folders."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from benchmark_scripts import load_benchmark
from user_models import CAMERA, synthetic_dataset

from harness.run_files import dataset_path
from perception.interface import LabelKind
from perception.learning.dataset_file import save_dataset
from perception.learning.evaluate import evaluate
from perception.learning.train import TrainConfig
from perception.model_config_file import read_model_config
from perception.models.kqv_config import PAPER, KqvConfig
from perception.registry import new_model
from sim.tasks.scene_sampling import SeedStream

ROOT = Path(__file__).resolve().parents[2]


ablation = load_benchmark("ablation")
ROWS = ablation.row_files()


# row files


def test_the_rows_of_the_issue_are_there() -> None:
    assert {"minus-cosine", "minus-starts", "minus-point-loss", "minus-ray-readout",
            "minus-64-heatmap", "minus-focus", "minus-per-image", "minus-mirror",
            "minus-type-head", "minus-axis-line", "paper"} <= set(ROWS)
    assert set(ablation.ONLY_TASKS) <= set(ROWS)
    assert all(set(tasks) <= set(ablation.TASKS) for tasks in ablation.ONLY_TASKS.values())


@pytest.mark.parametrize("row", sorted(ROWS))
def test_each_row_file_reads_and_changes_kqv(row: str) -> None:
    path = ROWS[row]
    settings = read_model_config(path, "kqv")
    default = KqvConfig()
    assert any(getattr(default, key) != value for key, value in settings.items()), row
    assert path.read_text().startswith("# ")
    assert "docs/decisions/kqv.md" in path.read_text()


def test_the_paper_row_is_the_paper_preset() -> None:
    settings = read_model_config(ROWS["paper"], "kqv")
    assert settings == {key: value for key, value in PAPER.items() if value is not None}


# statistics


def test_seed_stats_mean_std_and_worst_seed() -> None:
    stats = ablation.seed_stats({0: 1.0, 1: 3.0, 2: 2.0})
    assert (stats.mean, stats.std, stats.worst_seed, stats.worst) == (2.0, 1.0, 1, 3.0)
    lowest = ablation.seed_stats({0: 0.9, 1: 0.7, 2: 0.8}, worst_is_high=False)
    assert (lowest.worst_seed, lowest.worst) == (1, 0.7)
    assert ablation.seed_stats({4: 1.5}).std is None


def test_paired_difference_flags_beyond_two_standard_errors() -> None:
    steady = ablation.paired_difference({0: 1.5, 1: 2.5, 2: 3.5}, {0: 1.0, 1: 2.0, 2: 3.0})
    assert steady.difference_cm == pytest.approx(0.5)
    assert steady.standard_error_cm == pytest.approx(0.0)
    assert steady.beyond_seed_spread and steady.seeds == 3
    # differences -1 and +2: mean 0.5, std 2.12, standard error 1.5
    noisy = ablation.paired_difference({0: 1.0, 1: 3.0}, {0: 2.0, 1: 1.0})
    assert noisy.difference_cm == pytest.approx(0.5)
    assert noisy.standard_error_cm == pytest.approx(1.5)
    assert not noisy.beyond_seed_spread
    assert ablation.paired_difference({0: 1.0, 1: 2.0}, {1: 2.0, 2: 3.0}) is None


# run folders


def _cell(task: str, seed: int, error_cm: float, train_s: float,
          picked: tuple[float, int] | None) -> dict[str, Any]:
    """A cell of ``table2.json`` as experiments/table2/report.py writes it."""
    judged = None if picked is None else {
        "all": {"targets": picked[1], "predicted_success_rate": picked[0]}, "per_object": {}}
    return {"model": "kqv", "task": task, "size": 20, "seed": seed, "error_cm": error_cm,
            "per_condition_error_cm": None, "per_target_error_cm": [error_cm],
            "per_stage_error_cm": [error_cm], "judged": judged, "train_s": train_s}


def _write(folder: Path, cells: list[dict[str, Any]],
           settings: dict[str, Any] | None = None) -> None:
    configs = {} if settings is None else {"kqv": {"path": "x.toml", "settings": settings}}
    folder.mkdir(parents=True)
    (folder / "table2.json").write_text(json.dumps({
        "cells": cells, "failed": [], "settings": {"scene": "yumi", "test_scenes": 100,
                                                   "model_configs": configs}}))


@pytest.fixture
def runs(tmp_path: Path) -> Path:
    """recipe and minus-starts finished on single (seeds 0-2), minus-mirror at one seed."""
    _write(tmp_path / "recipe", [
        _cell("single", 0, 1.0, 100.0, (1.0, 100)), _cell("single", 1, 2.0, 120.0, (0.5, 100)),
        _cell("single", 2, 3.0, 140.0, (0.9, 50))])
    _write(tmp_path / "minus-starts", [
        _cell("single", 0, 1.5, 60.0, None), _cell("single", 1, 2.5, 50.0, None),
        _cell("single", 2, 3.5, 70.0, None)], {"starts": 1})
    _write(tmp_path / "minus-mirror", [_cell("single", 0, 1.0, 1.0, None)], {"mirror": False})
    _write(tmp_path / "minus-cosine", [_cell("single", s, 1.0, 1.0, None) for s in range(3)],
           {"similarity": "cosine"})  # a file changed since the run
    return tmp_path


def test_summary_of_finished_unfinished_and_stale_rows(runs: Path) -> None:
    rows = {"recipe": None, **{r: ROWS[r] for r in ("minus-starts", "minus-mirror",
                                                    "minus-cosine", "minus-per-image")}}
    summary = ablation.summarise(runs, rows, ["single"], [0, 1, 2])["rows"]
    recipe = summary["recipe"]["tasks"]["single"]
    assert recipe["status"] == "finished"
    assert recipe["error"] == {"mean": 2.0, "std": 1.0, "worst_seed": 2, "worst": 3.0}
    assert recipe["median_train_s"] == 120.0
    assert recipe["picked"]["pooled"] == pytest.approx((100 + 50 + 45) / 250)
    assert (recipe["picked"]["worst_seed"], recipe["picked"]["worst"]) == (1, 0.5)
    starts = summary["minus-starts"]["tasks"]["single"]
    assert starts["error"]["mean"] == pytest.approx(2.5)
    assert "picked" not in starts  # no cell was judged
    assert starts["vs_recipe"]["beyond_seed_spread"]
    assert starts["vs_recipe"]["difference_cm"] == pytest.approx(0.5)
    mirror = summary["minus-mirror"]["tasks"]["single"]
    assert (mirror["status"], mirror["seeds_missing"]) == ("unfinished", [1, 2])
    assert "error" not in mirror and "vs_recipe" not in mirror
    assert summary["minus-cosine"]["tasks"]["single"]["status"] == "other settings"
    assert summary["minus-per-image"]["tasks"]["single"]["status"] == "not run"


def test_from_reports_a_missing_row_unfinished(runs: Path, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "ablation.json"
    status = ablation.main(["--from", str(runs), "--json", str(record), "--rows",
                            "recipe,minus-point-loss,minus-query", "--tasks", "single",
                            "--seeds", "3"])
    assert status == 0
    printed = capsys.readouterr().out
    assert "| minus-point-loss | single | not run (0/3 seeds) |" in printed
    assert "| minus-query | single | recipe's model |" in printed
    assert "| recipe | single | 2.00 ± 1.00 | 3.00 (s2) | 78 % | 50 % (s1) | 120 |" in printed
    rows = json.loads(record.read_text())["rows"]
    assert rows["minus-point-loss"]["tasks"]["single"]["status"] == "not run"
    assert not (runs / "minus-point-loss").exists()  # --from runs nothing


def test_command_and_shared_datasets(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    args = ablation.parse_args(["--tasks", "single,selected-type", "--seeds", "2",
                                "--workers", "2"])
    argv = ablation.command("minus-query", ROWS["minus-query"], tmp_path, args)
    assert argv[:2] == ["reproduce", "sim"]
    assert argv[argv.index("--tasks") + 1] == "selected-type"
    assert argv[argv.index("--out") + 1] == str(tmp_path / "minus-query")
    assert argv[-4:] == ["--workers", "2", "--model-config",
                         "kqv=benchmarks/ablation/minus-query.toml"]
    assert "--model-config" not in ablation.command("recipe", None, tmp_path, args)
    (tmp_path / "recipe" / "datasets").mkdir(parents=True)
    (tmp_path / "recipe" / "datasets" / "single-train-20-s0.gva").write_bytes(b"demos")
    assert ablation.share_datasets(tmp_path, "minus-starts") == 1
    assert (tmp_path / "minus-starts" / "datasets" / "single-train-20-s0.gva").read_bytes() == (
        b"demos")
    assert ablation.share_datasets(tmp_path, "minus-starts") == 0


def test_rows_are_every_file_of_the_folder(tmp_path: Path) -> None:
    (tmp_path / "paper-plus-ray-readout.toml").write_text('readout = "ray"\n')
    assert list(ablation.row_files(tmp_path)) == ["paper-plus-ray-readout"]
    assert ablation.parse_args([]).rows == ["recipe", *ROWS]


# rows scored from the recipe's checkpoints


def test_only_rows_that_change_how_a_network_is_read_are_scored_untrained() -> None:
    assert ablation.inference_only(read_model_config(ROWS["minus-focus"], "kqv"))
    assert not any(ablation.inference_only(read_model_config(ROWS[r], "kqv"))
                   for r in ROWS if r != "minus-focus")
    assert not ablation.inference_only({})


def test_minus_focus_scores_the_recipe_checkpoints_again(tmp_path: Path) -> None:
    recipe = tmp_path / "recipe"
    train = synthetic_dataset(8, kind=LabelKind.GRASP_POSE, camera=CAMERA, seed=1)
    test = synthetic_dataset(6, kind=LabelKind.GRASP_POSE, camera=CAMERA, seed=2)
    save_dataset(test, dataset_path(recipe, "single", SeedStream.TEST, 100, 0))
    model = new_model("kqv", train, seed=0, starts=1, warmup_steps=0)
    model.fit(train, TrainConfig(steps=2, seed=0), progress=False)
    model.save(recipe / "checkpoints" / "s0")
    (recipe / "table2.json").write_text(json.dumps({"cells": [], "settings": {
        "scene": "yumi", "test_scenes": 100, "test_seed": 0}}))
    (recipe / "cells").mkdir()
    cell = recipe / "cells" / "kqv-single-20-s0.json"
    cell.write_text(json.dumps({"model": "kqv", "task": "single", "size": 20, "seed": 0,
                                "train_s": 90.0, "checkpoint": "checkpoints/s0",
                                "identity": {"steps": 1300}}))
    (recipe / "cells" / "kqv-single-20-s1-error.json").write_text("{}")  # a failed cell
    assert ablation.rescore(tmp_path, "minus-focus", ROWS["minus-focus"], ["single"], [0, 1]) == 1
    record = json.loads((tmp_path / "minus-focus" / "rescored.json").read_text())
    [scored] = record["cells"]
    whole = evaluate(model.read_with(focus_window_px=0), test)
    assert scored["error_cm"] == pytest.approx(whole.mean_position_error_cm)
    assert (scored["train_s"], scored["scored_from"]) == (90.0, {"steps": 1300})
    assert record["settings"]["model_configs"]["kqv"]["settings"] == {"focus_window_px": 0}
    assert ablation.rescore(tmp_path, "minus-focus", ROWS["minus-focus"], ["single"], [0]) == 0
    cell.write_text(cell.read_text().replace("1300", "1000"))  # the recipe cell was redone
    assert ablation.rescore(tmp_path, "minus-focus", ROWS["minus-focus"], ["single"], [0]) == 1
    summary = ablation.summarise(tmp_path, {"minus-focus": ROWS["minus-focus"]}, ["single"], [0])
    assert summary["rows"]["minus-focus"]["tasks"]["single"]["status"] == "finished"
    assert summary["rows"]["minus-focus"]["tasks"]["single"]["median_train_s"] == 90.0


def test_a_paper_plus_row_is_compared_with_the_paper_too(runs: Path) -> None:
    _write(runs / "paper", [_cell("single", s, 4.0 + s, 80.0, None) for s in range(3)],
           read_model_config(ROWS["paper"], "kqv"))
    _write(runs / "paper-plus-point-loss", [_cell("single", s, 2.0 + s, 85.0, None)
                                            for s in range(3)],
           read_model_config(ROWS["paper-plus-point-loss"], "kqv"))
    rows = {"recipe": None, "paper-plus-point-loss": ROWS["paper-plus-point-loss"]}
    summary = ablation.summarise(runs, rows, ["single"], [0, 1, 2])
    entry = summary["rows"]["paper-plus-point-loss"]["tasks"]["single"]
    assert entry["vs_paper"]["difference_cm"] == pytest.approx(-2.0)
    assert entry["vs_recipe"]["difference_cm"] == pytest.approx(1.0)
    assert "vs_paper" not in summary["rows"]["recipe"]["tasks"]["single"]
    lines = ablation.markdown(summary)
    assert any("+1.00 ± 0.00 * -2.00 ± 0.00 * (vs paper)" in line for line in lines)
