"""``gva trials``: pick trials at untrained positions, appended to a run folder.

Defaults are :class:`~harness.inputs.trial_settings.TrialSettings`'. No torch here: ``gva
trials --model oracle`` never loads it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from experiments.commands.arguments import (
    Once,
    add_executor_options,
    add_sensor_option,
    executor,
    integer,
    resume_command,
    sensor_kind,
)
from experiments.commands.pick_options import ROBOT, add_loop_options, loop_settings
from harness.inputs.trial_settings import TrialSettings, held_out_check
from harness.run_loop import TRIAL_WORKERS, RunStopped, run_trials
from harness.trial_summary import TrialSummary
from sim.tasks.variants import builtin_variants
from sim.trials.planner_setup import ObstacleSource


def add_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``gva trials``."""
    parser.add_argument("--model", default="oracle",
                        help="oracle (default), a checkpoint folder, package.module:Class, or "
                        "a name an installed package registers in gva.models")
    parser.add_argument("--model-class", metavar="MODULE:CLASS",
                        help="the class that loads a checkpoint of an unregistered model")
    parser.add_argument("--task", default="single",
                        help="built-in task name or task TOML path (default: %(default)s)")
    parser.add_argument("--n", type=integer(1), default=TrialSettings.n,
                        help="number of trials (%(default)s)")
    parser.add_argument("--seed", type=integer(0), default=TrialSettings.seed,
                        help="seed of the test scenes (%(default)s)")
    parser.add_argument("--out", type=Path, required=True, help="run folder")
    parser.add_argument("--workers", type=integer(1), default=TRIAL_WORKERS,
                        help="trials side by side in this many processes (%(default)s); the "
                        "records are the same however many")
    parser.add_argument("--obstacles", choices=[source.value for source in ObstacleSource],
                        default=TrialSettings.obstacles.value,
                        help="what picks are planned around: the head camera's depth image "
                        "(default), or the simulator's true shapes, to debug the planner only")
    parser.add_argument("--variant", metavar="NAME|FILE", action=Once,
                        help="the task under a variant of its looks: one of "
                        f"{', '.join(builtin_variants())}, or a variant .toml file "
                        "(docs/tasks.md)")
    parser.add_argument("--phrases", type=Path, metavar="FILE",
                        help="a text task's test sentences from FILE: lines of "
                        "phrase<TAB>target, target an object type or a side")
    add_sensor_option(parser, otherwise="a checkpoint's own (the sensor its datasets were "
                      "rendered by), else ")
    parser.add_argument("--allow-sensor-change", action="store_true",
                        help="run a checkpoint under --sensor or the task file's sensor even "
                        "when its datasets were rendered by another (refused by default, "
                        "naming both)")
    add_loop_options(parser)
    ROBOT.add_to(parser, TrialSettings.robot)
    add_executor_options(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Runs (or resumes) the trials and prints their summary; the exit status."""
    settings = TrialSettings(model=args.model, task=args.task, n=args.n, seed=args.seed,
                             model_class=args.model_class,
                             obstacles=ObstacleSource(args.obstacles),
                             phrases=None if args.phrases is None else str(args.phrases),
                             allow_sensor_change=args.allow_sensor_change,
                             loop=loop_settings(args), robot=args.robot,
                             variant=args.variant, sensor=sensor_kind(args))
    check = held_out_check(settings)
    if check is not None and not check.passed:
        print(f"WARNING: checkpoint {args.model} failed its training's held-out check "
              f"({check.reason}): these trials measure a model known to be poor",
              file=sys.stderr)
    try:
        summary = run_trials(settings, args.out, progress=not args.no_progress,
                             workers=args.workers, executor=executor(args))
    except RunStopped as stopped:  # Ctrl-C, or the model's SystemExit: what finished, kept
        print_summary(stopped.summary, args.out)
        print(f"gva trials: stopped: {stopped}; resume with: {resume_command(args)}",
              file=sys.stderr)
        return 130 if isinstance(stopped.cause, KeyboardInterrupt) else 1
    print_summary(summary, args.out)
    return 0


def print_summary(summary: TrialSummary, out: Path) -> None:
    """Prints what a run of trials gave: successes, outcomes, picks by object, where it is."""
    print(summary.headline())
    for outcome, count in summary.outcomes.items():
        if count:
            print(f"  {outcome:<18} {count}")
    picked = ", ".join(f"{name} {c['picked']}/{c['attempted']}"
                       for name, c in summary.per_object.items())
    print(f"picks by object: {picked}")
    if summary.judge is not None:
        print(f"grasp judge (error in the grasp frame vs each object's tolerance): "
              f"{summary.judge.line()}")
    print(f"median wall time per trial: {summary.median_wall_time_s:.2f} s")
    print(f"trials: {out / 'trials.jsonl'}   summary: {out / 'summary.json'}")
