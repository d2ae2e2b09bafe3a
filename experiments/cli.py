"""The ``gva`` command line.

    gva collect --scene yumi --task multiple --size 20 --seed 0 --out runs/yumi-multiple-20.gva
    gva collect --scene yumi --task multiple --size 100 --seed 1 --out runs/yumi-multiple-test.gva
    gva train --model kqv --data runs/yumi-multiple-20.gva --out runs/kqv-multiple
    gva evaluate --model runs/kqv-multiple --data runs/yumi-multiple-test.gva
    gva trials --model oracle --task single --n 30 --seed 0 --out runs/oracle-single
    gva trials --model runs/kqv-multiple --task multiple --n 30 --out runs/kqv-multiple-trials
    gva show scene --scene paper-sim --task multiple --out runs/scene.png
    gva show attention --model runs/kqv-multiple --data runs/yumi-multiple-20.gva --out runs/att
    gva reproduce sim --out runs/table2 --seeds 3 --models kqv,fcn --tasks single --sizes 4,20
    gva reproduce real --out runs/table3 --models kqv,keypoint-16,fcn

``train`` takes a registered model, a preset (``keypoint-16``) or ``package.module:Class``;
``evaluate``, ``show attention`` and ``trials`` take a checkpoint folder, with
``--model-class package.module:Class`` for a model that is not registered. ``trials`` also
takes ``oracle`` or ``package.module:Class`` of a model that needs no weights.

``reproduce sim`` runs the paper's Table II in the simulator (see
:mod:`experiments.table2.settings`): it collects, trains and scores every model x task x size x
seed cell in parallel processes and writes ``table2.md``/``.json``/``.png`` and ``fig5.png``;
it exits with status 1 when it finished but some cells failed (each failure is recorded).
``reproduce real`` runs the paper's Table III on the simulated YuMi (see
:mod:`experiments.table3.settings`): per task, 20 oracle demonstrations, each model trained on
them, 30 closed-loop pick trials with the model in the loop, kqv again under darker light and
with a distractor; it writes ``table3.md``/``.json`` and a GIF per model and task, and exits
with status 1 when some job failed. ``make demo`` is its short form (one task, kqv).

Bad input exits with status 2 and one line naming the value and what is allowed; a run that
stops half-way (``trials``, ``reproduce sim``, ``reproduce real``) is resumed by running the
same command again.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from control.errors import ControlError
from perception.interface import PerceptionError
from sim.errors import SimError


def _integer(minimum: int) -> Callable[[str], int]:
    """An argparse type: an integer >= ``minimum``, with a message that says so."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{value} is not allowed: an integer >= {minimum}")
        return value

    return parse


def _names(text: str) -> tuple[str, ...]:
    """An argparse type: comma-separated names (checked against the allowed ones later)."""
    return tuple(name.strip() for name in text.split(",") if name.strip())


def _integers(text: str) -> tuple[int, ...]:
    """An argparse type: comma-separated integers."""
    try:
        return tuple(int(value) for value in _names(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not comma-separated integers") from None


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every ``gva`` sub-command."""
    parser = argparse.ArgumentParser(
        prog="gva", description="Guided visual attention: YuMi pick trials in PyBullet."
    )
    commands = parser.add_subparsers(dest="command", required=True)
    trials = commands.add_parser(
        "trials",
        help="closed-loop pick trials at untrained positions",
        description="Runs pick trials: reset a scene from the seed, predict, plan, execute, "
        "judge by physics. Appends each trial to OUT/trials.jsonl; re-running resumes.",
    )
    trials.add_argument("--model", default="oracle",
                        help="oracle (default), a checkpoint folder, or package.module:Class")
    trials.add_argument("--model-class", metavar="MODULE:CLASS",
                        help="the class that loads a checkpoint of an unregistered model")
    trials.add_argument("--task", default="single",
                        help="built-in task name or task TOML path (default: single)")
    trials.add_argument("--n", type=_integer(1), default=30, help="number of trials (30)")
    trials.add_argument("--seed", type=_integer(0), default=0, help="seed of the test scenes (0)")
    trials.add_argument("--out", type=Path, required=True, help="run folder")
    trials.add_argument("--obstacles", choices=("depth", "truth"), default="depth",
                        help="what picks are planned around: the head camera's depth image "
                        "(default), or the simulator's true shapes, to debug the planner only")
    trials.add_argument("--no-progress", action="store_true", help="no progress bar")

    collect = commands.add_parser(
        "collect",
        help="collect a training dataset (yumi: oracle demonstrations kept when they succeed)",
        description="Collects SIZE scenes of a task into one dataset file: training scenes, "
        "or untrained test scenes with --stream test.",
    )
    collect.add_argument("--scene", required=True, help="paper-sim or yumi")
    collect.add_argument("--task", required=True, help="built-in task name or task TOML path")
    collect.add_argument("--size", type=_integer(1), required=True, help="number of scenes")
    collect.add_argument("--seed", type=_integer(0), default=0, help="seed of the scenes (0)")
    collect.add_argument("--stream", choices=("train", "test"), default="train",
                         help="seed stream: train, or test for untrained scenes (train)")
    collect.add_argument("--every-condition", action=argparse.BooleanOptionalAction,
                         default=None,
                         help="a sample per condition value of each scene, each labelled with "
                         "the object that value names (default: for the train stream)")
    collect.add_argument("--out", type=Path, required=True, help="dataset file to write")
    collect.add_argument("--no-progress", action="store_true", help="no progress bar")

    train = commands.add_parser(
        "train", help="train a perception model on a dataset and save its checkpoint",
        description="Trains a fresh model on a dataset and writes its checkpoint folder.",
    )
    train.add_argument("--model", required=True,
                       help="registered model, preset (keypoint-16) or package.module:Class")
    train.add_argument("--data", type=Path, required=True, help="training dataset file")
    train.add_argument("--out", type=Path, required=True, help="checkpoint folder to write")
    train.add_argument("--seed", type=_integer(0), default=0,
                       help="seeds the weights and the batches (0)")
    train.add_argument("--steps", type=_integer(1),
                       help="optimiser steps (default: TrainConfig's)")
    train.add_argument("--batch-size", type=_integer(1),
                       help="samples per step (default: TrainConfig's)")
    train.add_argument("--points", type=_integer(1),
                       help="attention points of models that have the setting (keypoint)")
    train.add_argument("--threads", type=_integer(1),
                       help="torch CPU threads (default: the cores it may use)")
    train.add_argument("--holdout", type=float,
                       help="fraction of the training scenes held out to check the trained "
                       "model (default: CheckConfig's; 0: no check)")
    train.add_argument("--check-limit-cm", type=float,
                       help="largest held-out mean error, of the whole, each condition and each "
                       "head [cm] (default: CheckConfig's)")
    train.add_argument("--attempts", type=_integer(1),
                       help="trainings tried from other starts before the checkpoint is marked "
                       "failed (default: CheckConfig's)")
    train.add_argument("--overwrite", action="store_true",
                       help="replace a checkpoint already in --out")
    train.add_argument("--no-progress", action="store_true", help="no progress bar")

    evaluate = commands.add_parser(
        "evaluate", help="a checkpoint's errors on a dataset, as the paper reports them",
        description="Mean position error in cm (angle errors too for grasp labels) of a "
        "checkpoint on a dataset; writes them as JSON.",
    )
    evaluate.add_argument("--model", type=Path, required=True, help="checkpoint folder")
    evaluate.add_argument("--data", type=Path, required=True, help="dataset file (test scenes)")
    evaluate.add_argument("--out", type=Path,
                          help="JSON file to write (MODEL/evaluation-<dataset name>.json)")
    evaluate.add_argument("--model-class", metavar="MODULE:CLASS",
                          help="the class that loads a checkpoint of an unregistered model")

    show = commands.add_parser("show", help="pictures of what the models see")
    shown = show.add_subparsers(dest="what", required=True)
    scene = shown.add_parser(
        "scene", help="a scene as its camera sees it, as a PNG",
        description="Renders scene INDEX of a task's training or test stream.",
    )
    scene.add_argument("--scene", required=True, help="paper-sim or yumi")
    scene.add_argument("--task", default="multiple", help="task name or TOML path (multiple)")
    scene.add_argument("--seed", type=_integer(0), default=0, help="seed (0)")
    scene.add_argument("--index", type=_integer(0), default=0, help="scene index (0)")
    scene.add_argument("--stream", choices=("train", "test"), default="test",
                       help="seed stream (test)")
    scene.add_argument("--scale", type=_integer(1), default=1,
                       help="enlarge the PNG this many times (1: the model's size)")
    scene.add_argument("--out", type=Path, required=True, help="PNG file to write")
    attention = shown.add_parser(
        "attention", help="a checkpoint's attention points and heatmaps, as PNGs (Fig. 5)",
        description="For each of the first COUNT samples of a dataset: the image with the "
        "attention points, and each head's heatmap; a conditioned model gets one row per "
        "condition choice.",
    )
    attention.add_argument("--model", type=Path, required=True, help="checkpoint folder")
    attention.add_argument("--data", type=Path, required=True, help="dataset file")
    attention.add_argument("--out", type=Path, required=True, help="folder for the PNGs")
    attention.add_argument("--count", type=_integer(1), default=8, help="samples drawn (8)")
    attention.add_argument("--scale", type=_integer(1), default=3,
                           help="enlarge the image this many times (3)")
    attention.add_argument("--model-class", metavar="MODULE:CLASS",
                           help="the class that loads a checkpoint of an unregistered model")
    _add_reproduce(commands)
    return parser


def _add_reproduce(commands: Any) -> None:
    """``gva reproduce sim`` and ``gva reproduce real``."""
    from experiments.table2.settings import SCENE, SCENES, SIZES
    from experiments.tables import MODELS, TASKS

    reproduce = commands.add_parser("reproduce", help="the paper's experiments, end to end")
    experiments = reproduce.add_subparsers(dest="experiment", required=True)
    sim = experiments.add_parser(
        "sim", help="Table II: position error of every model in the simulator",
        description="Collects paper-sim datasets, trains every model x task x size x seed "
        "cell in parallel processes, scores each on the task's 100 test scenes, and writes "
        "OUT/table2.md, table2.json, table2.png and fig5.png. Re-running skips finished cells.",
    )
    sim.add_argument("--out", type=Path, required=True, help="run folder")
    sim.add_argument("--seeds", type=_integer(1), default=3, help="training seeds (3)")
    sim.add_argument("--seed", type=_integer(0), default=0,
                     help="first training seed, also the test scenes' seed (0)")
    sim.add_argument("--workers", type=_integer(1),
                     help="processes at once (default: the cores this process may use)")
    sim.add_argument("--models", type=_names, default=MODELS,
                     help=f"comma-separated (default all: {','.join(MODELS)})")
    sim.add_argument("--tasks", type=_names, default=TASKS,
                     help=f"comma-separated (default all: {','.join(TASKS)})")
    sim.add_argument("--sizes", type=_integers, default=SIZES,
                     help=f"training set sizes, comma-separated (default all: "
                     f"{','.join(str(s) for s in SIZES)})")
    sim.add_argument("--steps", type=_integer(1), default=1000,
                     help="optimiser steps per training phase (1000)")
    sim.add_argument("--test-scenes", type=_integer(1), default=100,
                     help="test scenes per task (100, as in the paper; fewer for a quick check)")
    sim.add_argument("--scene", choices=SCENES, default=SCENE,
                     help="paper-sim (Table II) or yumi (the robot's demonstrations, offline) "
                     f"({SCENE})")
    sim.add_argument("--no-progress", action="store_true", help="no progress bars")
    _add_reproduce_real(experiments, TASKS)


def _add_reproduce_real(experiments: Any, tasks: Sequence[str]) -> None:
    """``gva reproduce real``: Table III, pick trials with trained models in the loop."""
    real = experiments.add_parser(
        "real", help="Table III: YuMi pick trials out of 30 with trained models in the loop",
        description="Per task on the yumi scene: collects oracle-verified demonstrations, "
        "trains each model on them, runs closed-loop pick trials at untrained positions with "
        "the trained model in the loop (kqv also under darker light and with a distractor), "
        "each seed in OUT/s<seed>/, and writes OUT/table3.md and table3.json over the seeds "
        "and OUT/s<seed>/gifs/<model>-<task>.gif. Re-running skips what is finished.",
    )
    real.add_argument("--out", type=Path, required=True, help="run folder")
    real.add_argument("--seeds", type=_integer(1), default=1,
                      help="runs of the whole experiment, seeds S0 .. S0 + SEEDS - 1 (1)")
    real.add_argument("--seed", type=_integer(0), default=0,
                      help="S0: seeds the demonstrations, the weights and the test scenes (0)")
    real.add_argument("--workers", type=_integer(1),
                      help="processes at once (default: the cores this process may use)")
    real.add_argument("--train-threads", type=_integer(1), default=1,
                      help="torch threads per training job (1: jobs train side by side; a "
                      "one-task run trains faster on all cores; results depend on it)")
    real.add_argument("--tasks", type=_names, default=tuple(tasks),
                      help=f"comma-separated (default all: {','.join(tasks)})")
    real.add_argument("--models", type=_names, default=("kqv",),
                      help="comma-separated names gva train takes, e.g. kqv,keypoint-16,fcn "
                      "(default kqv)")
    real.add_argument("--n", type=_integer(1), default=30, help="trials per model and task (30)")
    real.add_argument("--demos", type=_integer(1), default=20,
                      help="demonstrations per task (20)")
    real.add_argument("--steps", type=_integer(1), default=1000,
                      help="optimiser steps of training (1000)")
    real.add_argument("--holdout", type=float,
                      help="fraction of each task's demonstrations held out to check its "
                      "trained model (default: CheckConfig's; 0: train on all, check nothing)")
    real.add_argument("--robustness", action=argparse.BooleanOptionalAction, default=True,
                      help="also run kqv under darker light and with a distractor (on)")
    real.add_argument("--no-progress", action="store_true", help="no progress bar")


def _run_trials(args: argparse.Namespace) -> int:
    from sim.planning import ObstacleSource
    from sim.trials import TrialSettings, held_out_check, run_trials

    settings = TrialSettings(model=args.model, task=args.task, n=args.n, seed=args.seed,
                             model_class=args.model_class,
                             obstacles=ObstacleSource(args.obstacles))
    check = held_out_check(settings)
    if check is not None and not check.passed:
        print(f"WARNING: checkpoint {args.model} failed its training's held-out check "
              f"({check.reason}): these trials measure a model known to be poor",
              file=sys.stderr)
    summary = run_trials(settings, args.out, progress=not args.no_progress)
    print(summary.headline())
    for outcome, count in summary.outcomes.items():
        if count:
            print(f"  {outcome:<18} {count}")
    picked = ", ".join(f"{name} {c['picked']}/{c['attempted']}"
                       for name, c in summary.per_object.items())
    print(f"picks by object: {picked}")
    print(f"median wall time per trial: {summary.median_wall_time_s:.2f} s")
    print(f"trials: {args.out / 'trials.jsonl'}   summary: {args.out / 'summary.json'}")
    return 0


def _run_collect(args: argparse.Namespace) -> int:
    from sim.collect import CollectSettings, collect
    from sim.scene import SeedStream

    stream = SeedStream.TRAIN if args.stream == "train" else SeedStream.TEST
    settings = CollectSettings(scene=args.scene, task=args.task, size=args.size, seed=args.seed,
                               stream=stream, every_condition=args.every_condition)
    dataset = collect(settings, args.out, progress=not args.no_progress)
    meta = dataset.metadata
    redrawn = meta.extra.get("demonstrations_redrawn")
    scenes = meta.extra.get("scenes", meta.size)
    why = ("one per condition value" if meta.extra.get("every_condition") and meta.targets == 1
           else "one before each pick")
    images = f" ({meta.size} samples: {why})" if scenes != meta.size else ""
    print(f"{scenes} scenes{images} of {meta.scene} / {meta.task} (seed {meta.seed}, "
          f"{meta.extra.get('stream', args.stream)} stream), "
          f"{meta.targets} target(s) each, {meta.label_kind.value} labels"
          + (f"; {redrawn} failed demonstrations redrawn" if redrawn is not None else ""))
    print(f"dataset: {args.out}")
    return 0


def _run_show(args: argparse.Namespace) -> int:
    if args.what == "attention":
        from experiments.model_commands import run_show_attention

        return run_show_attention(args)
    from sim.scene import SeedStream, sample_scene
    from sim.scenes import get_scene_spec
    from sim.show import render_scene, write_scene_png
    from sim.tasks import load_task

    task = load_task(args.task)
    stream = SeedStream.TRAIN if args.stream == "train" else SeedStream.TEST
    scene = sample_scene(task, get_scene_spec(args.scene), args.seed, stream, args.index)
    image = render_scene(scene, task.brightness)
    path = write_scene_png(image, args.out, args.scale)
    targets = ", ".join(scene.objects[i].object_type for i in scene.targets)
    condition = f"; condition {scene.condition.value}" if scene.condition.value else ""
    print(f"{args.scene} / {task.name}, {args.stream} scene {args.index}: targets {targets}"
          f"{condition}; {image.shape[1]}x{image.shape[0]} px image")
    print(f"wrote {path}")
    return 0


def _print_run(report: Any, done: str, name: Callable[[dict[str, Any]], str]) -> None:
    """The summary lines of a ``reproduce`` run: counts, wall time, failures, notes."""
    failed_now = sum(outcome.failure is not None for outcome in report.computed)
    print(f"{len(report.computed)} {done} ({failed_now} failed), {len(report.skipped)} "
          f"finished earlier and skipped; wall time {report.wall_time_s:.0f} s")
    for record in report.failed:
        print(f"  FAILED {name(record)}: {record['error']}")
    for note in report.notes:
        print(f"  note: {note}")


def _run_reproduce_real(args: argparse.Namespace) -> int:
    from experiments.table3.run import run_reproduce_real
    from experiments.table3.settings import ReproduceRealSettings

    settings = ReproduceRealSettings(models=args.models, tasks=args.tasks, n=args.n,
                                     demos=args.demos, steps=args.steps, seed=args.seed,
                                     seeds=args.seeds, check=_check_config(args),
                                     robustness=args.robustness, workers=args.workers,
                                     train_threads=args.train_threads)
    report = run_reproduce_real(settings, args.out, progress=not args.no_progress)
    _print_run(report, "job(s) run", lambda record: record["job"])
    print(report.table)
    print(f"files: {args.out}/ (table3.md, table3.json; per seed s<seed>/: gifs/, trials/, "
          "checkpoints/)")
    return 1 if report.failed else 0


def _check_config(args: argparse.Namespace) -> Any:
    """The :class:`~perception.validation.CheckConfig` of ``--holdout`` (defaults otherwise)."""
    from perception.validation import CheckConfig

    return CheckConfig() if args.holdout is None else CheckConfig(holdout=args.holdout)


def _run_reproduce(args: argparse.Namespace) -> int:
    if args.experiment == "real":
        return _run_reproduce_real(args)
    from experiments.table2.run import run_reproduce_sim
    from experiments.table2.settings import ReproduceSimSettings

    settings = ReproduceSimSettings(models=args.models, tasks=args.tasks, sizes=args.sizes,
                                    seeds=args.seeds, seed=args.seed, steps=args.steps,
                                    test_scenes=args.test_scenes, workers=args.workers,
                                    scene=args.scene)
    report = run_reproduce_sim(settings, args.out, progress=not args.no_progress)
    _print_run(report, "cell(s) computed",
               lambda r: f"{r['model']}-{r['task']}-{r['size']}-s{r['seed']}")
    print("wrote " + ", ".join(str(path) for path in report.outputs))
    return 1 if report.failed else 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``gva`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    name = f"reproduce {args.experiment}" if args.command == "reproduce" else args.command
    try:
        if args.command == "trials":
            return _run_trials(args)
        if args.command == "collect":
            return _run_collect(args)
        if args.command == "train":
            from experiments.model_commands import run_train

            return run_train(args)
        if args.command == "evaluate":
            from experiments.model_commands import run_evaluate

            return run_evaluate(args)
        if args.command == "show":
            return _run_show(args)
        if args.command == "reproduce":
            return _run_reproduce(args)
    except BrokenPipeError:  # the reader went away (``gva evaluate ... | head``): not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no flush error at exit
        return 0
    except (SimError, ControlError, PerceptionError, ValueError, OSError) as error:
        print(f"gva {name}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as interrupt:
        print(f"gva {name}: interrupted; {interrupt or 'run the same command again to resume'}",
              file=sys.stderr)
        return 130
    raise AssertionError(f"unhandled command {args.command}")  # argparse rejects others


if __name__ == "__main__":
    sys.exit(main())
