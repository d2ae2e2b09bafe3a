"""Whether a fix keeps ``kqv`` off the look-alike block, judged offline in minutes (issue 49).

    python studies/check_distractor_offline.py --candidate clutter --seed 0 --seeds 2 \
        [--tasks single,multiple] [--sensor d435] [--demos 20] [--steps N] \
        [--clutter-per-scene 0,2] [--checkpoints runs/t3-s10 ...] [--test-scenes 30] \
        [--out runs/distractor-offline] [--json benchmarks/results/distractor_offline.json]

Per model, task and seed: the grasps the grasp judge predicts would be picked (as ``gva
evaluate`` judges them) on test scenes *with the block* and on *clean* ones, the mean position
error, and the grasps nearer the block than the target. A candidate records its own
demonstrations and trains as ``gva reproduce real`` trains a unit, in ``OUT/<candidate>/s<S>/``
(a rerun resumes; a folder of other settings is refused): ``clutter``, with
``--clutter-per-scene`` of ``CLUTTER_TYPES`` a scene; ``balanced``, the object types taken in
turn (``objects.balance_types``: 20 demonstrations of ``single`` at seed 10 hold 2 sponges).
``--checkpoints RUN`` scores ``RUN/s<S>/checkpoints/kqv/<T>/`` on the run's own
``tasks/<T>-distractor.toml`` and ``<T>.toml`` (missing in older runs: the built-in variant under
``run.json``'s sensor, as the output notes). Test scenes (TEST stream, seeds ``--seed`` ..
``--seed + --seeds - 1``) are cached in ``OUT/test-scenes/<sensor>/s<S>/``. They
are oracle demonstrations: a scene the oracle fails is replaced by a later one (``redrawn``).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shlex
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from functools import partial
from pathlib import Path
from typing import NamedTuple

from distractor_scores import SET_NAMES, Score, score_set, table

from experiments import tables
from experiments.commands.arguments import integer, integers, names
from experiments.table3 import jobs
from experiments.table3 import settings as table3
from harness import run_files, run_report
from harness.inputs.collector import CollectSettings, collect
from harness.inputs.trial_settings import task_identity
from harness.run_folder import differences, json_form
from perception.learning.learnable import LearnableModel
from perception.learning.train import TrainConfig
from perception.models.kqv import KqvModel
from perception.objects.catalog import CLUTTER_TYPES
from perception.registry import load_model
from robots.yumi import YUMI
from sim.errors import RunFolderError, SimError
from sim.tasks.scene_sampling import SeedStream
from sim.tasks.task_in_scene import target_count
from sim.tasks.task_spec import TaskSpec
from sim.tasks.task_toml import load_task, task_to_toml
from sim.world.sensor import SensorConfig, SensorKind, sensor_from_table, sensor_kind

MODEL = "kqv"
TEST_SETS = dict(zip(SET_NAMES, ("block", table3.PLAIN), strict=True))


@dataclass(frozen=True)
class TestTask:
    """A test set's task: its definition, the file to collect from, the cached dataset."""

    spec: TaskSpec
    task_path: Path
    dataset: Path


@dataclass(frozen=True)
class Entry:
    """A checkpoint to score, with its seed's two test tasks."""

    source: str
    task: str
    seed: int
    checkpoint: Path
    block: TestTask
    clean: TestTask


class Step(NamedTuple):
    """Work to do before scoring: its name, its estimated seconds, the work."""

    name: str
    cost_s: float
    run: Callable[[], object]


def clutter_task(task: str, sensor: SensorKind, per_scene: tuple[int, int]) -> TaskSpec:
    """The task under ``sensor`` with ``per_scene`` clutter objects a scene, never targets."""
    base = table3.variant_task(task, table3.PLAIN, sensor)
    return replace(base, distractors=CLUTTER_TYPES, distractors_per_scene=per_scene,
                   description=f"{base.description} Plus {per_scene[0]}-{per_scene[1]} of "
                   f"{', '.join(CLUTTER_TYPES)} (clutter, never a target).")


def balanced_task(task: str, sensor: SensorKind, _: tuple[int, int]) -> TaskSpec:
    """The task under ``sensor`` with its training scenes' types taken in turn."""
    base = table3.variant_task(task, table3.PLAIN, sensor)
    return replace(base, balance_types=True, description=f"{base.description} Types taken in "
                   "turn in the training scenes.")


CANDIDATES: dict[str, Callable[[str, SensorKind, tuple[int, int]], TaskSpec]] = {
    "clutter": clutter_task, "balanced": balanced_task}
"""Each candidate's task for a built-in task name, a sensor and ``--clutter-per-scene``."""


def test_task(out: Path, spec: TaskSpec, task: str, variant: str, seed: int,
              n: int, given: Path | None) -> TestTask:
    """Where ``spec``'s test set is cached: by sensor, plus a hash unless the built-in variant.

    ``given``: the task file to collect from (a run's); None: one written into the cache.
    """
    key, identity = spec.sensor.kind.value, json_form(task_identity(spec))
    if identity != json_form(task_identity(table3.variant_task(task, variant, spec.sensor.kind))):
        key += "-" + hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()[:8]
    folder = out / "test-scenes" / key / f"s{seed}"
    path, text = given or folder / "tasks" / f"{spec.name}.toml", task_to_toml(spec)
    if given is None and (not path.exists() or path.read_text(encoding="utf-8") != text):
        run_files.write_text(path, text)
    return TestTask(spec, path, run_files.dataset_path(folder, spec.name, SeedStream.TEST, n, seed))


def candidate_entry(args: argparse.Namespace, candidate: str, task: str, seed: int,
                    steps: list[Step]) -> Entry:
    """``candidate``'s checkpoint of ``task`` and ``seed``; its missing work to ``steps``."""
    folder, sensor = table3.seed_folder(args.out / candidate, seed), sensor_kind(args.sensor)
    settings = table3.ReproduceRealSettings(
        models=(MODEL,), tasks=(task,), demos=args.demos, steps=args.steps, seed=seed,
        sensor=sensor, train_threads=args.train_threads)
    spec = CANDIDATES[candidate](task, sensor, args.clutter_per_scene)
    unit = table3.Unit(MODEL, task)
    path, asked = table3.task_file(folder, task), json_form(task_identity(spec))
    if path.exists() and (found := json_form(task_identity(load_task(path)))) != asked:
        raise RunFolderError(f"{path} holds the task of other settings ({differences(found, asked)}"
                             f", stored vs asked); remove {folder} or use another --out")
    run_files.write_text(path, f"# {task}, candidate {candidate}, written by "
                      f"{Path(__file__).name}\n" + task_to_toml(spec))
    identity = json_form(settings.train_identity(unit) | {"task": asked, "candidate": candidate})
    trained = table3.trained_file(folder, unit)
    if trained.exists():  # reused, unless trained with other settings
        run_files.refuse_other_settings(
            [(str(trained), run_files.read_json(trained)["identity"], identity)], "checkpoint(s)")
    else:
        demos = table3.dataset_file(folder, task, settings)
        if not run_files.dataset_present(demos, table3.SCENE, str(path), args.demos, seed,
                                         SeedStream.TRAIN, robot=settings.description()):
            job = jobs.CollectJob(f"collect-{task}-s{seed}", task, settings, folder)
            steps.append(Step(job.name, jobs.COLLECT_S_PER_PICK * args.demos
                              * target_count(spec), partial(finish, job)))
        train = jobs.TrainJob(f"train-{unit.name}-s{seed}", unit, settings, identity, folder)
        steps.append(Step(train.name, jobs.TRAIN_S_PER_STEP * args.steps, partial(finish, train)))
    block, clean = (test_task(args.out, table3.variant_task(task, v, sensor), task, v, seed,
                              args.test_scenes, None) for v in TEST_SETS.values())
    return Entry(candidate, task, seed, table3.checkpoint_folder(folder, unit), block, clean)


def finish(job: jobs.Job) -> None:
    """Runs a job of ``gva reproduce real``; its failure stops the check, naming its record."""
    if (failure := jobs.run_job(job).failure) is not None:
        raise SimError(f"{job.name} failed: {failure} (see {jobs.error_file(job.out, job.name)})")


def run_entry(args: argparse.Namespace, run: Path, task: str, seed: int, notes: list[str]
              ) -> Entry:
    """A run folder's checkpoint of ``task`` and ``seed``, on the scenes of its task files."""
    folder = table3.seed_folder(run, seed)
    checkpoint = table3.checkpoint_folder(folder, table3.Unit(MODEL, task))
    if not (checkpoint / "config.json").exists():
        have = sorted(p.parts[-5] for p in run.glob(f"s*/checkpoints/{MODEL}/{task}/config.json"))
        raise SystemExit(f"--checkpoints {run}: no {MODEL} checkpoint of task {task!r} for seed "
                         f"{seed} ({checkpoint}); seed folders with one: "
                         f"{', '.join(have) or 'none'} (choose them with --seed and --seeds)")
    meta = next((p for p in (folder / "run.json", run / "run.json") if p.exists()), None)
    stored = {} if meta is None else run_files.read_json(meta)
    sensor = (sensor_from_table(stored["sensor"], f"{meta}: sensor") if "sensor" in stored
              else SensorConfig())
    tests = []
    for variant in TEST_SETS.values():
        spec = replace(table3.variant_task(task, variant, sensor.kind), camera=sensor)
        given: Path | None = table3.task_file(folder, spec.name)
        if given is not None and given.exists():
            spec = load_task(given)
        else:
            given = None
            notes.append(f"{run} s{seed}: no tasks/{spec.name}.toml; used the built-in {task} "
                         f"as variant_task(..., {variant!r}) with the run's sensor "
                         f"{sensor.describe()} (from {meta})")
        tests.append(test_task(args.out, spec, task, variant, seed, args.test_scenes, given))
    return Entry(str(run), task, seed, checkpoint, tests[0], tests[1])


def collect_step(test: TestTask, seed: int, n: int) -> Step | None:
    """The collection of a test set, unless the cache holds it (another one there is refused)."""
    if run_files.dataset_present(test.dataset, table3.SCENE, str(test.task_path), n, seed,
                                 SeedStream.TEST, robot=YUMI):
        return None
    settings = CollectSettings(table3.SCENE, str(test.task_path), n, seed, SeedStream.TEST)
    return Step(f"collect test {test.spec.name} s{seed}",
                jobs.COLLECT_S_PER_PICK * n * target_count(test.spec),
                partial(collect, settings, test.dataset, progress=False))


def score(entry: Entry, model: LearnableModel, focus_px: int | None) -> Score:
    """``entry``'s checkpoint, loaded as ``model``, scored on its block and clean test sets.

    ``focus_px``: the heatmap focus to read with (``KqvConfig.focus_window_px``; 0: the whole
    heatmap); None: the checkpoint's own. The source is named with it.
    """
    source = entry.source
    if focus_px is not None and isinstance(model, KqvModel):
        model, source = model.read_with(focus_window_px=focus_px), f"{source} (focus {focus_px} px)"
    return Score(source, entry.task, entry.seed, str(entry.checkpoint),
                 score_set(model, "block", entry.block.dataset),
                 score_set(model, "clean", entry.clean.dataset))


def per_scene(text: str) -> tuple[int, int]:
    """An argparse type: ``LO,HI`` clutter objects a scene, 0 <= LO <= HI <= the types."""
    values, most = integers(text), len(CLUTTER_TYPES)
    if len(values) != 2 or not 0 <= values[0] <= values[1] <= most:
        raise argparse.ArgumentTypeError(f"{text!r} is not allowed: LO,HI with 0 <= LO <= HI <= "
                                         f"{most} (the clutter types: {', '.join(CLUTTER_TYPES)})")
    return values[0], values[1]


def focus_list(text: str) -> tuple[int | None, ...]:
    """An argparse type: comma-separated focus windows [px], each >= 0."""
    values = integers(text)
    if not values or min(values) < 0:
        raise argparse.ArgumentTypeError(f"{text!r} is not allowed: comma-separated integers "
                                         ">= 0 (0: the whole heatmap)")
    return values


def parse(argv: Sequence[str]) -> argparse.Namespace:
    """The options, checked: a bad one exits naming the option, its value and what is allowed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    add = parser.add_argument
    add("--candidate", action="append", choices=list(CANDIDATES), default=[],
        help="a fix to train and score (repeatable): clutter in the demonstrations, or their "
        "object types balanced")
    add("--checkpoints", action="append", type=Path, default=[], metavar="RUN_FOLDER",
        help="a gva reproduce real run folder to score (repeatable)")
    add("--tasks", type=names, default=("single",),
        help=f"comma-separated, from {','.join(tables.TASKS)} (single)")
    add("--seed", type=integer(0), default=0, help="the first seed (0)")
    add("--seeds", type=integer(1), default=1, help="how many seeds (1)")
    add("--sensor", choices=[k.value for k in SensorKind], default=SensorKind.D435.value,
        help="the candidate's camera (d435); a run keeps its own")
    add("--demos", type=integer(1), default=20, help="the candidate's demonstrations (20)")
    add("--steps", type=integer(1), default=TrainConfig.steps, help="its steps (%(default)s)")
    add("--train-threads", type=integer(1), default=table3.ReproduceRealSettings.train_threads,
        help="torch threads of a training, as gva reproduce real's (%(default)s)")
    add("--clutter-per-scene", type=per_scene, default=(0, 2), metavar="LO,HI",
        help="clutter objects a demonstration presents (0,2)")
    add("--focus-px", type=focus_list, default=(None,), metavar="PX[,PX...]",
        help="score each checkpoint reading its heatmaps through these focus windows "
        "(KqvConfig.focus_window_px; 0: the whole heatmap); default: each checkpoint's own")
    add("--test-scenes", type=integer(1), default=30, help="test scenes of each set (30)")
    add("--out", type=Path, default=Path("runs/distractor-offline"), help="the work folder")
    add("--json", type=Path, default=Path("benchmarks/results/distractor_offline.json"))
    add("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    unknown = [t for t in args.tasks if t not in tables.TASKS]
    if unknown or not args.tasks or len(set(args.tasks)) != len(args.tasks):
        parser.error(f"argument --tasks: {','.join(unknown or args.tasks)!r} is not allowed: "
                     f"distinct comma-separated names from {', '.join(tables.TASKS)}")
    if not args.candidate and not args.checkpoints:
        parser.error(f"nothing to score: give --candidate ({'|'.join(CANDIDATES)}) and/or "
                     "--checkpoints RUN_FOLDER")
    for run in args.checkpoints:
        if not (run / "run.json").is_file():
            parser.error(f"argument --checkpoints: {str(run)!r} is not allowed: a gva reproduce "
                         "real run folder (it has no run.json)")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Prepares every checkpoint and test set, scores them, prints the table, writes the JSON."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parse(argv)
    started, load = time.perf_counter(), os.getloadavg()
    seeds = range(args.seed, args.seed + args.seeds)
    steps: list[Step] = []
    notes: list[str] = []
    entries = [entry for seed in seeds for task in args.tasks for entry in (
        *(candidate_entry(args, c, task, seed, steps) for c in dict.fromkeys(args.candidate)),
        *(run_entry(args, run, task, seed, notes) for run in args.checkpoints))]
    tests = {t.dataset: (t, e.seed) for e in entries for t in (e.block, e.clean)}
    steps += [step for test, seed in tests.values()
              if (step := collect_step(test, seed, args.test_scenes)) is not None]
    print("".join(f"note: {note}\n" for note in notes) + f"{len(steps)} job(s) to run "
          f"({', '.join(s.name for s in steps) or 'none'}), {len(entries)} checkpoint(s) to score")
    with run_report.cost_bar(sum(s.cost_s for s in steps), "distractor offline",
                         not args.no_progress) as bar:
        for step in steps:
            bar.set_postfix_str(step.name)
            step.run()
            bar.update(step.cost_s)
    models = [load_model(entry.checkpoint) for entry in entries]  # once, for every focus
    scores = [score(entry, model, focus) for focus in args.focus_px
              for entry, model in zip(entries, models, strict=True)]
    lines, totals = table(scores, list(seeds))
    print("cell: picks the grasp judge predicts succeed / picks, mean position error; "
          "N>blk: predicted grasps nearer the block than the target")
    print("\n".join(lines))
    for dataset, redrawn in {s.dataset: s.redrawn for x in scores for s in (x.block, x.clean)
                             if s.redrawn}.items():
        print(f"note: {dataset}: {redrawn} test scene(s) the oracle failed were replaced by "
              "later ones of the stream (not the trials' scenes)")
    run_files.write_json(args.json, json_form({
        "benchmark": "distractor_offline",
        "command": shlex.join(["python", "studies/check_distractor_offline.py", *argv]),
        "settings": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()}
        | {"checkpoints": [str(r) for r in args.checkpoints], "clutter_types": CLUTTER_TYPES},
        "notes": notes, "scores": [asdict(s) for s in scores],
        "pooled": [asdict(t) for t in totals], "wall_time_s": time.perf_counter() - started,
        "load_average_1_5_15min_at_start": load}))
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
