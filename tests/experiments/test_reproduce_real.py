"""``gva reproduce real``: a real tiny run, resuming, refusals, the tables, the GIF."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import pytest
from gva_cli import gva

from experiments.table3.layout import task_file, trained_file
from experiments.table3.run import run_reproduce_real
from experiments.table3.settings import ReproduceRealSettings, TrialSet, Unit
from perception.learning.dataset_file import read_metadata
from perception.registry import load_model
from robots.yumi import YUMI
from sim.errors import InvalidInputError, RunFolderError
from sim.tasks.task_toml import load_task
from sim.trials.model_fit import check_model_fits_task
from sim.world.sensor import SensorConfig, SensorKind

TINY = ["--tasks", "single", "--demos", "2", "--n", "2", "--steps", "3", "--workers", "1",
        "--no-progress"]
TINY_SETTINGS = ReproduceRealSettings(tasks=("single",), demos=2, n=2, steps=3, workers=1)
UNIT = Unit("kqv", "single")


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("reproduce-real") / "run"
    status, stdout, stderr = gva("reproduce", "real", "--out", out, *TINY)
    assert status == 0, stderr
    # collect, train, the trials plain, dark and with a distractor, the GIF
    assert "6 job(s) run (0 failed), 0 finished earlier" in stdout
    assert "| Paper (real YuMi, 20 demonstrations) | 27/30 |" in stdout
    assert "| Ours (kqv, q=min) | " in stdout
    assert f"files: {out}/" in stdout
    return out


def test_a_tiny_run_writes_the_table_and_the_gif(tiny_run):
    table = json.loads((tiny_run / "table3.json").read_text())
    single = table["tasks"]["single"]
    assert single["n"] == 2 and 0 <= single["successes"] <= 2
    assert set(single) >= {"successes", "n", "wilson95", "outcomes"}
    assert sum(single["outcomes"].values()) == 2 and single["outcomes"]["error"] == 0
    assert table["models"]["kqv"]["single"] == single
    for variant in ("dark", "block"):
        entry = table["variants"]["models"]["kqv"][variant]["single"]
        assert entry["n"] == 2 and [e["seed"] for e in entry["against_clean"]] == [0]
        assert entry["against_clean"][0]["n"] == 2
    assert table["paper"]["single"] == {"successes": 27, "n": 30}
    assert table["seeds"] == [0] and single["per_seed"] == [
        {"seed": 0, "successes": single["successes"], "n": 2, "unfinished": False}]
    assert single["mean"] == single["successes"] and single["std"] == 0.0
    assert table["settings"]["train"]["steps"] == 3 and table["wall_time_s"] > 0
    markdown = (tiny_run / "table3.md").read_text()
    assert "| Paper (real YuMi, 20 demonstrations) | 27/30 | 28/30 | 26/30 | 27/30 |" in markdown
    assert "| Ours (kqv, q=min), darker light (brightness 0.5) |" in markdown
    assert "| Ours (kqv, q=min), + block distractor |" in markdown
    assert "## Each variant against the clean world, paired on the same trials" in markdown
    assert "## Failure reasons" in markdown and "--steps 3" in markdown
    gif = tiny_run / "s0" / "gifs" / "kqv-single.gif"
    assert gif.read_bytes()[:6] == b"GIF89a"
    from PIL import Image

    with Image.open(gif) as image:
        assert image.n_frames > 1 and image.size == (256, 142)
    shown = json.loads(gif.with_suffix(".json").read_text())["trials"]
    assert [t["index"] for t in shown] == [0, 1]  # n = 2 trials, so 2 of the 3


def test_the_gif_replays_the_logged_trials(tiny_run):
    logged = [json.loads(line) for line in
              (tiny_run / "s0" / "trials" / "kqv" / "single" / "trials.jsonl").read_text()
              .splitlines()]
    shown = json.loads((tiny_run / "s0" / "gifs" / "kqv-single.json").read_text())["trials"]
    assert [(t["outcome"], t["reason"]) for t in shown] == [
        (r["outcome"], r["reason"]) for r in sorted(logged, key=lambda r: r["index"])]


def test_the_variants_are_task_files_the_checkpoint_is_accepted_for(tiny_run):
    seed0 = tiny_run / "s0"
    dark = load_task(task_file(seed0, TrialSet(UNIT, "dark").task_name))
    distractor = load_task(task_file(seed0, TrialSet(UNIT, "block").task_name))
    assert (dark.name, dark.brightness, dark.distractors) == ("single+dark", 0.5, ())
    assert (distractor.name, distractor.distractors) == ("single+block", ("block",))
    model = load_model(seed0 / "checkpoints" / "kqv" / "single")
    for task in (dark, distractor):
        check_model_fits_task(model, task, "kqv", robot=YUMI)  # trained on `single`: accepted
    def scenes(name):
        log = seed0 / "trials" / "kqv" / name / "trials.jsonl"
        return {r["index"]: r["objects"] for r in map(json.loads, log.read_text().splitlines())}

    plain = scenes("single")
    assert scenes("single-dark") == plain
    for index, objects in scenes("single-block").items():  # the same scene, plus a block
        assert objects[:1] == plain[index]
        assert (objects[1]["type"], objects[1]["distractor"]) == ("block", True)


def test_the_run_sees_through_the_d435_by_default_and_records_it(tiny_run):
    seed0 = tiny_run / "s0"
    for name in ("single", "single-dark", "single-block"):
        assert load_task(task_file(seed0, name)).camera == SensorConfig(SensorKind.D435)
    dataset = next((seed0 / "datasets").glob("*.gva"))
    assert read_metadata(dataset).camera["sensor"]["sensor"] == "d435"
    assert load_model(seed0 / "checkpoints" / "kqv" / "single").spec.sensor["sensor"] == "d435"
    table = json.loads((tiny_run / "table3.json").read_text())
    assert table["settings"]["sensor"]["sensor"] == "d435"
    assert "seen through the d435 sensor" in (tiny_run / "table3.md").read_text()


def test_plain_trials_of_its_checkpoint_repeat_its_records_and_collect_its_sensor(tiny_run,
                                                                                  tmp_path):
    """Issue 64: ``gva trials --model CKPT --task T`` sees through the checkpoint's sensor (the
    D435 here) with no --sensor, so it repeats the run's trials; ``gva collect`` at the same
    seed renders through the sensor the run's demonstrations were."""
    seed0 = tiny_run / "s0"
    out = tmp_path / "mine"
    status, _, stderr = gva("trials", "--model", seed0 / "checkpoints" / "kqv" / "single",
                            "--task", "single", "--seed", "0", "--n", "2", "--out", out,
                            "--no-progress")
    assert status == 0, stderr

    def records(folder):
        lines = (folder / "trials.jsonl").read_text().splitlines()
        return sorted(({k: v for k, v in json.loads(line).items() if k != "wall_time_s"}
                       for line in lines), key=lambda r: r["index"])

    ours, theirs = records(out), records(seed0 / "trials" / "kqv" / "single")
    assert [r["index"] for r in ours] == [0, 1]
    for mine, run in zip(ours, theirs, strict=True):  # field by field, to name any that differ
        assert {k: mine.get(k) for k in mine | run} == {k: run.get(k) for k in mine | run}
    assert json.loads((out / "run.json").read_text())["task"]["camera"]["sensor"] == "d435"
    status, _, stderr = gva("collect", "--scene", "yumi", "--task", "single", "--size", "1",
                            "--seed", "0", "--out", tmp_path / "d.gva", "--no-progress")
    assert status == 0, stderr
    demos = next((seed0 / "datasets").glob("*.gva"))
    collected = read_metadata(tmp_path / "d.gva").camera["sensor"]
    assert collected == read_metadata(demos).camera["sensor"] == SensorConfig(
        SensorKind.D435).to_json()


def test_demonstrations_take_the_types_in_turn_unless_asked_and_trials_see_the_same_scenes():
    single, multiple = (TINY_SETTINGS.run_task(TrialSet(Unit("kqv", t))) for t in
                        ("single", "multiple"))
    assert single.balance_types and not multiple.balance_types  # one drawn type a scene only
    random = replace(TINY_SETTINGS, balance_types=False)
    assert not random.run_task(TrialSet(UNIT)).balance_types
    assert random.command(Path("out")).endswith("--no-balance-types")
    status, stdout, _ = gva("reproduce", "real", "--help")
    assert status == 0 and "--no-balance-types" in stdout
    balanced = TINY_SETTINGS.run_task(TrialSet(UNIT, "block"))
    assert balanced.balance_types and replace(balanced, balance_types=False) == \
        random.run_task(TrialSet(UNIT, "block"))


def test_a_folder_run_through_one_sensor_refuses_the_other(tiny_run):
    ideal = replace(TINY_SETTINGS, sensor=SensorKind.IDEAL)
    assert ideal.command(tiny_run).endswith("--sensor ideal")
    with pytest.raises(RunFolderError, match="sensor"):
        run_reproduce_real(ideal, tiny_run, progress=False)


def test_an_unknown_sensor_is_refused_by_name():
    status, _, stderr = gva("reproduce", "real", "--out", "unused", "--sensor", "kinect")
    assert status == 2 and "--sensor" in stderr and "'d435'" in stderr
    with pytest.raises(InvalidInputError, match="sensor"):
        ReproduceRealSettings(sensor="d435")


def test_a_rerun_skips_everything(tiny_run):
    seed0 = tiny_run / "s0"
    watched = [*(seed0 / "trials").glob("*/*/trials.jsonl"), seed0 / "gifs" /
               "kqv-single.gif", trained_file(seed0, UNIT),
               seed0 / "checkpoints" / "kqv" / "single" / "weights.safetensors",
               *(seed0 / "datasets").glob("*.gva")]
    before = {path: path.stat().st_mtime_ns for path in watched}
    report = run_reproduce_real(TINY_SETTINGS, tiny_run, progress=False)
    assert report.computed == () and len(report.skipped) == 6
    assert {path: path.stat().st_mtime_ns for path in watched} == before
    history = (tiny_run / "history.jsonl").read_text().splitlines()
    assert json.loads(history[-1])["computed"] == []


def test_the_history_places_each_job_after_what_it_needs(tiny_run):
    """The job graph: a training starts after its collection, trials after their training."""
    first = json.loads((tiny_run / "history.jsonl").read_text().splitlines()[0])
    jobs = {job["name"]: job for job in first["jobs"]}
    assert set(jobs) == set(first["computed"])

    def end(name: str) -> float:
        return jobs[name]["started_at"] + jobs[name]["seconds"]

    assert jobs["train-kqv-single-s0"]["started_at"] >= end("collect-single-s0") - 0.05
    for name in jobs:
        if name.startswith(("trials-", "gif-")):
            assert jobs[name]["started_at"] >= end("train-kqv-single-s0") - 0.05, name
    assert all(job["cpu_s"] >= 0 and job["worker"] > 0 and job["cpus"] >= 1
               for job in jobs.values())
    trained = json.loads(trained_file(tiny_run / "s0", UNIT).read_text())
    assert trained["phases"][0]["name"] == "targets"  # two demonstrations: nothing held out
    assert trained["attempts"] == 0 and len(trained["attempt_times"]) == 1


def test_a_run_with_other_steps_is_refused(tiny_run):
    other = ["4" if before == "--steps" else value for before, value in
             zip(["", *TINY], TINY, strict=False)]
    status, _, stderr = gva("reproduce", "real", "--out", tiny_run, *other)
    assert status == 2
    assert "holds a different run ({'train.steps': (3, 4)}, stored vs asked)" in stderr
    assert stderr.startswith("gva reproduce real: error:")


def test_training_threads_are_part_of_the_run_and_of_its_command(tiny_run):
    status, _, stderr = gva("reproduce", "real", "--out", tiny_run, *TINY, "--train-threads", "2")
    assert status == 2
    assert "holds a different run ({'train.threads': (1, 2)}, stored vs asked)" in stderr
    two = ReproduceRealSettings(tasks=("single",), train_threads=2)
    assert two.train_config()["threads"] == 2
    assert two.command(Path("runs/demo")).endswith("--tasks single --train-threads 2")
    status, _, stderr = gva("reproduce", "real", "--out", tiny_run, "--train-threads", "0")
    assert status == 2 and "--train-threads" in stderr


def test_gif_trials_are_counted_in_the_identity_and_the_command_and_never_negative():
    none = replace(TINY_SETTINGS, gif_trials=0)
    assert none.shared_identity()["gif_trials"] == 0  # a folder of GIFs resumes only with them
    assert TINY_SETTINGS.shared_identity()["gif_trials"] == 3
    assert none.command(Path("out")).endswith("--gif-trials 0")
    with pytest.raises(InvalidInputError, match="gif_trials = -1 is not allowed"):
        replace(TINY_SETTINGS, gif_trials=-1)


def test_a_failing_training_is_recorded_and_the_run_goes_on(tiny_run, tmp_path, monkeypatch):
    import experiments.table3.jobs

    def broken(*_, **__):
        raise RuntimeError("out of ideas")

    copied = Path(shutil.copytree(tiny_run, tmp_path / "run"))
    trained_file(copied / "s0", UNIT).unlink()
    monkeypatch.setattr(experiments.table3.jobs, "new_model", broken)
    status, stdout, _ = gva("reproduce", "real", "--out", copied, *TINY)
    assert status == 1
    assert "1 job(s) run (1 failed)" in stdout
    assert "FAILED train-kqv-single-s0: RuntimeError: out of ideas" in stdout
    error = json.loads((copied / "s0" / "errors" / "train-kqv-single-s0.json").read_text())
    assert "Traceback" in error["traceback"]
    assert "- train-kqv-single-s0: RuntimeError: out of ideas" in (
        copied / "table3.md").read_text()


def test_a_failing_collection_leaves_out_the_trainings_that_need_it(tiny_run, tmp_path,
                                                                   monkeypatch):
    import experiments.table3.jobs

    def broken(*_, **__):
        raise RuntimeError("no demonstrations today")

    copied = Path(shutil.copytree(tiny_run, tmp_path / "run"))
    for dataset in (copied / "s0" / "datasets").glob("*.gva"):
        dataset.unlink()
    trained_file(copied / "s0", UNIT).unlink()
    monkeypatch.setattr(experiments.table3.jobs, "collect", broken)
    status, stdout, _ = gva("reproduce", "real", "--out", copied, *TINY)
    assert status == 1
    assert "1 job(s) run (1 failed)" in stdout  # the collection; no training, no trials
    assert "FAILED collect-single-s0: RuntimeError: no demonstrations today" in stdout


def test_more_seeds_add_seed_folders_and_the_table_reports_each(tiny_run, tmp_path):
    copied = Path(shutil.copytree(tiny_run, tmp_path / "run"))
    status, stdout, stderr = gva("reproduce", "real", "--out", copied, *TINY, "--seeds", "2")
    assert status == 0, stdout + stderr
    assert "6 job(s) run (0 failed), 6 finished earlier" in stdout  # seed 1's; seed 0's kept
    table = json.loads((copied / "table3.json").read_text())
    assert table["seeds"] == [0, 1]
    single = table["tasks"]["single"]
    counts = [entry["successes"] for entry in single["per_seed"]]
    assert [entry["seed"] for entry in single["per_seed"]] == [0, 1]
    assert single["n"] == 4 and single["successes"] == sum(counts)
    assert single["mean"] == pytest.approx(sum(counts) / 2)
    assert single["std"] == pytest.approx(abs(counts[0] - counts[1]) / 2 ** 0.5)
    assert f"({counts[0]}, {counts[1]})" in (copied / "table3.md").read_text()
    assert (copied / "s1" / "gifs" / "kqv-single.gif").exists()
    status, _, stderr = gva("reproduce", "real", "--out", copied, *TINY, "--seeds", "2",
                            "--n", "3")
    assert status == 2 and "'n': (2, 3)" in stderr


@pytest.mark.parametrize(("option", "value", "allowed"), [
    ("--tasks", "single,juggle", "tasks = 'juggle' is not allowed: distinct comma-separated "
     "values from single, multiple, selected-type, selected-position"),
    ("--models", "kqv,foo", "models = 'foo' is not allowed: distinct comma-separated values "
     "from kqv, keypoint, dsae, conv-ae, fcn, keypoint-16, keypoint-min, dsae-16"),
])
def test_bad_tasks_and_models_name_the_allowed_values(tmp_path, option, value, allowed):
    status, _, stderr = gva("reproduce", "real", "--out", tmp_path / "run", option, value)
    assert status == 2
    assert allowed in stderr
    assert not (tmp_path / "run").exists()


@pytest.mark.slow
def test_a_multiple_run_trains_on_the_image_before_each_pick_and_resumes(tmp_path):
    out = tmp_path / "run"
    args = ("reproduce", "real", "--out", out, "--tasks", "multiple", "--demos", "1", "--n",
            "1", "--steps", "2", "--workers", "1", "--no-robustness", "--no-progress")
    status, stdout, stderr = gva(*args)
    assert status == 0, stderr
    assert "4 job(s) run (0 failed)" in stdout
    trained = json.loads(trained_file(out / "s0", Unit("kqv", "multiple")).read_text())
    assert trained["samples"] == 3  # one demonstration, an image before each of its 3 picks
    status, stdout, _ = gva(*args)
    assert status == 0 and "0 job(s) run (0 failed), 4 finished earlier" in stdout


def test_a_closed_loop_run_tries_each_checkpoint_open_loop_too(tmp_path):
    """``--loop closed``: approach images in the demonstrations, every set closed-loop, and an
    ``open-loop`` set per unit on the same checkpoint and scenes (issue 36)."""
    from experiments.table3.trial_sets import split_task
    from sim.trials.closed_loop.loop_settings import Loop, LoopSettings

    closed = ReproduceRealSettings(tasks=("single-moved", "single"), variants=(),
                                   loop=LoopSettings(Loop.CLOSED, replan_hz=5.0))
    sets = closed.trial_sets()
    assert {(s.unit.task, s.variant) for s in sets} == {
        (t, v) for t in ("single-moved", "single") for v in ("plain", "open-loop")}
    loops = {s.variant: closed.trial_loop(s).loop for s in sets}
    assert loops == {"plain": Loop.CLOSED, "open-loop": Loop.OPEN}
    assert closed.approach_hz == 5.0 and closed.shared_identity()["loop"]["replan_hz"] == 5.0
    assert closed.command(tmp_path).endswith("--loop closed --replan-hz 5")
    assert split_task("single-moved-open-loop") == ("single-moved", "open-loop")
    plain = ReproduceRealSettings(variants=())
    assert plain.approach_hz is None and "loop" not in plain.shared_identity()
    assert {s.variant for s in plain.trial_sets()} == {"plain"}


@pytest.mark.slow
def test_a_panda_run_demonstrates_trains_and_picks_through_its_own_camera(tmp_path):
    """``--robot panda`` (issue 39): the run, its datasets and its table name the robot, the
    checkpoint sees through the Panda's camera, and a YuMi run refuses the folder."""
    out = tmp_path / "panda"
    status, stdout, stderr = gva("reproduce", "real", "--out", out, "--robot", "panda",
                                 "--no-robustness", *TINY)
    assert status == 0, stderr
    assert "4 job(s) run (0 failed)" in stdout
    settings = ReproduceRealSettings(tasks=("single",), demos=2, n=2, steps=3, workers=1,
                                     variants=(), robot="panda")
    assert settings.shared_identity()["robot"] == "panda"
    assert "robot" not in TINY_SETTINGS.shared_identity()  # YuMi folders resume as before
    assert settings.command(out).endswith("--robot panda")
    meta = read_metadata(next((out / "s0" / "datasets").glob("*.gva")))
    assert meta.extra["robot"] == "panda"
    assert "a simulated Franka Panda" in (out / "table3.md").read_text()
    trials = next((out / "s0" / "trials").rglob("trials.jsonl")).read_text().splitlines()
    arms = {pick.get("arm") for line in trials for pick in json.loads(line)["picks"]}
    reasons = " ".join(json.loads(line)["reason"] for line in trials)
    assert arms <= {"panda", None} and ("panda" in arms or "arm panda" in reasons)
    status, stdout, stderr = gva("reproduce", "real", "--out", out, "--robot", "panda",
                                 "--no-robustness", *TINY)  # the same run again: resumed whole
    assert status == 0 and "0 job(s) run" in stdout, stderr
    status, _, stderr = gva("reproduce", "real", "--out", out, "--no-robustness", *TINY)
    assert status != 0 and "robot" in stderr


