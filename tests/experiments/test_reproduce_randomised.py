"""``gva reproduce real --randomised-scenes N`` (issue 74): each task's demonstrations plus N
scenes in randomised looks labelled by the catalog, each unit trained on both as ``gva train
--data DEMOS --data RANDOMISED`` is; off (0), a run is today's, identity and all."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import pytest
from gva_cli import gva

from experiments.table3.layout import dataset_file, randomised_file, trained_file
from experiments.table3.run import run_reproduce_real
from experiments.table3.settings import RANDOMISED_SEED_OFFSET, ReproduceRealSettings, Unit
from perception.files import file_sha256
from perception.learning.checkpoint import read_config
from perception.learning.dataset_file import read_metadata
from sim.errors import InvalidInputError

TINY = ["--tasks", "single", "--demos", "2", "--n", "2", "--steps", "3", "--workers", "1",
        "--no-robustness", "--gif-trials", "0", "--no-progress", "--randomised-scenes", "3"]
SETTINGS = ReproduceRealSettings(tasks=("single",), demos=2, n=2, steps=3, workers=1,
                                 variants=(), gif_trials=0, randomised_scenes=3)
UNIT = Unit("kqv", "single")


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("randomised") / "run"
    status, stdout, stderr = gva("reproduce", "real", "--out", out, *TINY)
    assert status == 0, stderr
    # the demonstrations, the randomised scenes, the training, the plain trials
    assert "4 job(s) run (0 failed), 0 finished earlier" in stdout
    return out


def test_the_randomised_scenes_are_collected_at_their_own_seed_and_trained_on(run: Path) -> None:
    seed0 = run / "s0"
    path = randomised_file(seed0, "single", 3, RANDOMISED_SEED_OFFSET)
    assert path.name == "single-randomised-3-s100.gva"
    meta = read_metadata(path)
    assert (meta.task, meta.seed, meta.extra["scenes"], meta.extra["stream"]) == (
        "single+randomised", 100, 3, "train")
    assert meta.extra["labels"] == "catalog" and meta.extra["looks"]["kind"] == "randomised"
    demos = dataset_file(seed0, "single", SETTINGS)
    recorded = read_config(seed0 / "checkpoints" / "kqv" / "single")["training"]["datasets"]
    assert [(d["path"], d["sha256"], d["labels"], d["looks"]) for d in recorded] == [
        (str(demos.resolve()), file_sha256(demos), "picked", "task"),
        (str(path.resolve()), file_sha256(path), "catalog", "randomised")]
    trained = json.loads(trained_file(seed0, UNIT).read_text())
    assert trained["samples"] == 2 + 3  # two demonstrations of one pick, three scenes
    assert trained["identity"]["randomised_scenes"]["scenes"] == 3
    assert trained["identity"]["randomised_scenes"]["seed"] == 100
    assert json.loads((run / "run.json").read_text())["randomised_scenes"] == 3
    assert "--no-robustness --randomised-scenes 3 --gif-trials 0" in SETTINGS.command(run)


def test_a_rerun_skips_both_collections_and_the_training(run: Path) -> None:
    report = run_reproduce_real(SETTINGS, run, progress=False)
    assert report.computed == ()
    assert set(report.skipped) == {"collect-single-s0", "collect-randomised-single-s0",
                                   "train-kqv-single-s0", "trials-kqv-single-s0"}


def test_off_the_identities_are_todays() -> None:
    """Every folder from before the option resumes: 0 adds nothing to any identity."""
    plain = replace(SETTINGS, randomised_scenes=0)
    assert "randomised_scenes" not in plain.shared_identity()
    assert "randomised_scenes" not in plain.train_identity(UNIT)
    assert plain.shared_identity() == {k: v for k, v in SETTINGS.shared_identity().items()
                                       if k != "randomised_scenes"}
    assert plain.train_identity(UNIT) == {k: v for k, v in SETTINGS.train_identity(UNIT).items()
                                          if k != "randomised_scenes"}
    assert "--randomised-scenes" not in plain.command(Path("o"))
    status, stdout, _ = gva("reproduce", "real", "--help")  # the help names the seed's offset
    assert status == 0 and f"seed + {RANDOMISED_SEED_OFFSET} on the training" in " ".join(
        stdout.split())


def test_a_negative_count_or_one_for_plug_ins_only_is_refused(tmp_path: Path) -> None:
    status, _, stderr = gva("reproduce", "real", "--out", tmp_path / "run",
                            "--randomised-scenes", "-1")
    assert status == 2 and "--randomised-scenes" in stderr and "an integer >= 0" in stderr
    assert not (tmp_path / "run").exists()
    with pytest.raises(InvalidInputError, match="randomised_scenes = -1 is not allowed"):
        replace(SETTINGS, randomised_scenes=-1)
    with pytest.MonkeyPatch.context() as patch, pytest.raises(
            InvalidInputError, match="randomised_scenes = 3 is not allowed: 0 where no model "
            "is trained"):
        patch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "examples" / "plugins"))
        replace(SETTINGS, models=("colour_detector:ColourDetector",))


def test_a_failing_randomised_collection_leaves_out_the_training(run: Path, tmp_path: Path,
                                                                 monkeypatch) -> None:
    import experiments.table3.jobs

    def broken(*_, **__):
        raise RuntimeError("no looks today")

    copied = Path(shutil.copytree(run, tmp_path / "run"))
    randomised_file(copied / "s0", "single", 3, RANDOMISED_SEED_OFFSET).unlink()
    trained_file(copied / "s0", UNIT).unlink()
    monkeypatch.setattr(experiments.table3.jobs, "collect", broken)
    status, stdout, _ = gva("reproduce", "real", "--out", copied, *TINY)
    assert status == 1
    assert "1 job(s) run (1 failed)" in stdout  # the randomised collection; no training
    assert "FAILED collect-randomised-single-s0: RuntimeError: no looks today" in stdout
