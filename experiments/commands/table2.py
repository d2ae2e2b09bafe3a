"""``gva reproduce sim``: the paper's Table II in the simulator, its options and summary.

Defaults are :class:`~experiments.table2.settings.ReproduceSimSettings`'.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from experiments.commands.arguments import (
    add_executor_options,
    add_model_config_option,
    add_sensor_option,
    executor,
    integer,
    integers,
    model_config_files,
    names,
    sensor_kind,
)
from experiments.table2.run import run_reproduce_sim
from experiments.table2.settings import SCENES, ReproduceSimSettings
from experiments.tables import BEYOND_TASKS


def add_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``gva reproduce sim``."""
    defaults = ReproduceSimSettings  # its fields' defaults, as class attributes
    parser.add_argument("--out", type=Path, required=True, help="run folder")
    parser.add_argument("--seeds", type=integer(1), default=defaults.seeds,
                        help="training seeds (%(default)s)")
    parser.add_argument("--seed", type=integer(0), default=defaults.seed,
                        help="first training seed, also the test scenes' seed (%(default)s)")
    parser.add_argument("--workers", type=integer(1), default=defaults.workers,
                        help="processes at once (default: the cores this process may use)")
    parser.add_argument("--models", type=names, default=defaults.models,
                        help=f"comma-separated (default all: {','.join(defaults.models)})")
    add_model_config_option(parser)
    parser.add_argument("--tasks", type=names, default=defaults.tasks,
                        help=f"comma-separated (default the paper's: {','.join(defaults.tasks)}; "
                        f"beyond it: {','.join(BEYOND_TASKS)})")
    parser.add_argument("--sizes", type=integers, default=defaults.sizes,
                        help="training set sizes, comma-separated (default all: "
                        f"{','.join(str(s) for s in defaults.sizes)})")
    parser.add_argument("--steps", type=integer(1), default=defaults.steps,
                        help="optimiser steps per training phase (%(default)s)")
    parser.add_argument("--test-scenes", type=integer(1), default=defaults.test_scenes,
                        help="test scenes per task (%(default)s, as in the paper; fewer for a "
                        "quick check)")
    parser.add_argument("--scene", choices=SCENES, default=defaults.scene,
                        help="paper-sim (Table II) or yumi (the robot's demonstrations, "
                        "offline) (%(default)s)")
    add_sensor_option(parser)
    add_executor_options(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Runs (or resumes) the table and prints its summary; 1 when some cell failed."""
    settings = ReproduceSimSettings(models=args.models, tasks=args.tasks, sizes=args.sizes,
                                    seeds=args.seeds, seed=args.seed, steps=args.steps,
                                    test_scenes=args.test_scenes, workers=args.workers,
                                    executor=executor(args), scene=args.scene,
                                    sensor=sensor_kind(args),
                                    model_configs=model_config_files(args))
    report = run_reproduce_sim(settings, args.out, progress=not args.no_progress)
    for line in report.summary_lines(
            "cell(s) computed", lambda r: f"{r['model']}-{r['task']}-{r['size']}-s{r['seed']}"):
        print(line)
    print("wrote " + ", ".join(str(path) for path in report.outputs))
    return 1 if report.failed else 0
