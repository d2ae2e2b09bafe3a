"""``gva reproduce real``: the paper's Table III on the simulated YuMi, its options and summary.

Defaults are :class:`~experiments.table3.settings.ReproduceRealSettings`' (and the held-out
check's, :class:`~perception.learning.validation.CheckConfig`'s).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from experiments.commands.arguments import (
    add_executor_options,
    add_model_config_option,
    executor,
    integer,
    model_config_files,
    names,
)
from experiments.commands.trials import add_loop_options, add_robot_option, loop_settings
from experiments.table3.run import run_reproduce_real
from experiments.table3.settings import ReproduceRealSettings
from experiments.tables import BEYOND_TASKS
from perception.learning.validation import CheckConfig
from sim.tasks.variants import builtin_variants
from sim.world.sensor import SensorKind


def add_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``gva reproduce real``."""
    defaults = ReproduceRealSettings  # its fields' defaults, as class attributes
    parser.add_argument("--out", type=Path, required=True, help="run folder")
    parser.add_argument("--seeds", type=integer(1), default=defaults.seeds,
                        help="runs of the whole experiment, seeds S0 .. S0 + SEEDS - 1 "
                        "(%(default)s)")
    parser.add_argument("--seed", type=integer(0), default=defaults.seed,
                        help="S0: seeds the demonstrations, the weights and the test scenes "
                        "(%(default)s)")
    parser.add_argument("--workers", type=integer(1), default=defaults.workers,
                        help="processes at once (default: the cores this process may use)")
    parser.add_argument("--train-threads", type=integer(1), default=defaults.train_threads,
                        help="torch threads per training job (%(default)s: jobs train side by "
                        "side; a one-task run trains faster on all cores; results depend on it)")
    parser.add_argument("--tasks", type=names, default=defaults.tasks,
                        help=f"comma-separated (default the paper's: {','.join(defaults.tasks)}; "
                        f"beyond it: {','.join(BEYOND_TASKS)})")
    parser.add_argument("--models", type=names, default=defaults.models,
                        help="comma-separated names gva train takes, e.g. kqv,keypoint-16,fcn, "
                        "or plug-ins package.module:Class, tried untrained on the same scenes "
                        f"(docs/plugins.md; default {','.join(defaults.models)})")
    add_model_config_option(parser)
    parser.add_argument("--n", type=integer(1), default=defaults.n,
                        help="trials per model and task (%(default)s)")
    parser.add_argument("--demos", type=integer(1), default=defaults.demos,
                        help="demonstrations per task (%(default)s)")
    parser.add_argument("--steps", type=integer(1), default=defaults.steps,
                        help="optimiser steps of training (%(default)s)")
    parser.add_argument("--holdout", type=float, default=CheckConfig.holdout,
                        help="fraction of each task's demonstrations held out to check its "
                        "trained model (%(default)s; 0: train on all, check nothing)")
    parser.add_argument("--gif-trials", type=integer(0), default=defaults.gif_trials,
                        help="first trials of each model and task recorded again as a GIF "
                        "(%(default)s; 0: none, each is a pick run twice)")
    parser.add_argument("--use-failed-checkpoints", action="store_true",
                        help="run the trials of a checkpoint that failed its held-out check at "
                        "every start anyway, with a warning (for studies); default: its cells "
                        "are recorded failed with the check's reason and exit status 1")
    parser.add_argument("--variants", type=variant_names, default=defaults.variants,
                        help="comma-separated variants every model is also tried under, each "
                        f"paired with its clean trials: {', '.join(builtin_variants())}, or "
                        f"variant .toml files; none for none (default {','.join(defaults.variants)}"
                        ": the paper's robustness rows)")
    parser.add_argument("--no-robustness", dest="variants", action="store_const", const=(),
                        help="no variants: the same as --variants none")
    parser.add_argument("--balance-types", action=argparse.BooleanOptionalAction,
                        default=defaults.balance_types,
                        help="demonstrations take the object types in turn where a scene draws "
                        "one type, as a person recording them would; off: at random "
                        f"({'on' if defaults.balance_types else 'off'})")
    parser.add_argument("--sensor", choices=[k.value for k in SensorKind],
                        default=defaults.sensor.value,
                        help="what the head camera renders through, for demonstrations and "
                        "trials: d435 (lens distortion, depth noise and holes, hand-eye error; "
                        "docs/decisions/d435-sensor.md) or ideal, an exact pinhole "
                        "(%(default)s)")
    parser.add_argument("--world", metavar="VARIANT",
                        help="the world the whole run lives in, demonstrations and trials: a "
                        f"variant of every task's looks ({', '.join(builtin_variants())}, or "
                        "a variant .toml file); varied-held-out demonstrates on half the "
                        "palette and textures and tries on the other half (default: "
                        "today's world)")
    add_loop_options(parser)
    add_robot_option(parser)
    add_executor_options(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(run=run)


def variant_names(text: str) -> tuple[str, ...]:
    """``--variants``: comma-separated names or files; ``none`` for none.

    An empty name, or nothing at all, is refused as :func:`names` refuses it: say ``none``.
    """
    return () if text.strip() == "none" else names(text)


def run(args: argparse.Namespace) -> int:
    """Runs (or resumes) the table and prints its summary; 1 when some job failed."""
    settings = ReproduceRealSettings(models=args.models, tasks=args.tasks, n=args.n,
                                     demos=args.demos, steps=args.steps, seed=args.seed,
                                     seeds=args.seeds, check=CheckConfig(holdout=args.holdout),
                                     variants=args.variants,
                                     balance_types=args.balance_types,
                                     sensor=SensorKind(args.sensor), workers=args.workers,
                                     loop=loop_settings(args), robot=args.robot,
                                     executor=executor(args), train_threads=args.train_threads,
                                     model_configs=model_config_files(args),
                                     world=args.world,
                                     gif_trials=args.gif_trials,
                                     use_failed_checkpoints=args.use_failed_checkpoints)
    report = run_reproduce_real(settings, args.out, progress=not args.no_progress)
    for line in report.summary_lines("job(s) run", lambda record: record["job"]):
        print(line)
    print(report.table)
    print(f"files: {args.out}/ (table3.md, table3.json; per seed s<seed>/: gifs/, trials/, "
          "checkpoints/)")
    return 1 if report.failed else 0
