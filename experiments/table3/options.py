"""The options of ``gva reproduce real``, declared once (:mod:`experiments.commands.options`).

Its parser, the :class:`~experiments.table3.settings.ReproduceRealSettings` the parsed options
give, and the command line those settings stand for (``settings.command(out)``) all come from
:data:`REAL`; each default is the settings field's.
"""

from __future__ import annotations

from experiments.commands.arguments import (
    add_executor_options,
    add_model_config_option,
    executor,
    integer,
    model_config_files,
    names,
    variant_names,
)
from experiments.commands.options import CommandLine, Option, Special, same_members
from experiments.commands.pick_options import ROBOT, add_loop_options, loop_options, loop_settings
from experiments.tables import BEYOND_TASKS, model_config_options
from sim.tasks.variants import builtin_variants
from sim.world.sensor import SensorKind

REAL = CommandLine("gva reproduce real", (
    Option("--seeds", parse=integer(1),
           help="runs of the whole experiment, seeds S0 .. S0 + SEEDS - 1 ({default})"),
    Option("--seed", parse=integer(0), shown="always",
           help="S0: seeds the demonstrations, the weights and the test scenes ({default})"),
    Option("--workers", parse=integer(1), shown="never",
           help="processes at once (default: the cores this process may use)"),
    Option("--train-threads", parse=integer(1),
           help="torch threads per training job ({default}: jobs train side by side; a one-task "
           "run trains faster on all cores; results depend on it)"),
    Option("--tasks", parse=names, same=same_members,
           help="comma-separated (default the paper's: {default}; beyond it: "
           f"{','.join(BEYOND_TASKS)})"),
    Option("--models", parse=names,
           help="comma-separated names gva train takes, e.g. kqv,keypoint-16,fcn, or plug-ins "
           "package.module:Class, tried untrained on the same scenes (docs/plugins.md; default "
           "{default})"),
    # repeated MODEL=FILE, each checked against --models and read: its own shape
    Special("--model-config", "model_configs", add_model_config_option, model_config_files,
            model_config_options),
    Option("--n", parse=integer(1), shown="always",
           help="trials per model and task ({default})"),
    Option("--demos", parse=integer(1), shown="always",
           help="demonstrations per task ({default})"),
    Option("--steps", parse=integer(1), shown="always",
           help="optimiser steps of training ({default})"),
    Option("--holdout", parse=float, field="check.holdout",
           help="fraction of each task's demonstrations held out to check its trained model "
           "({default}; 0: train on all, check nothing)"),
    Option("--gif-trials", parse=integer(0),
           help="first trials of each model and task recorded again as a GIF ({default}; 0: "
           "none, each is a pick run twice)"),
    Option("--use-failed-checkpoints",
           help="run the trials of a checkpoint that failed its held-out check at every start "
           "anyway, with a warning (for studies); default: its cells are recorded failed with "
           "the check's reason and exit status 1"),
    Option("--variants", parse=variant_names, none_flag="--no-robustness",
           none_help="no variants: the same as --variants none",
           help="comma-separated variants every model is also tried under, each paired with its "
           f"clean trials: {', '.join(builtin_variants())}, or variant .toml files; none for "
           "none (default {default}: the paper's robustness rows)"),
    Option("--balance-types",
           help="demonstrations take the object types in turn where a scene draws one type, as "
           "a person recording them would; off: at random ({default})"),
    Option("--sensor", choices=SensorKind,
           help="what the head camera renders through, for demonstrations and trials: d435 "
           "(lens distortion, depth noise and holes, hand-eye error; "
           "docs/decisions/d435-sensor.md) or ideal, an exact pinhole ({default})"),
    Option("--world", metavar="VARIANT",
           help="the world the whole run lives in, demonstrations and trials: a variant of every "
           f"task's looks ({', '.join(builtin_variants())}, or a variant .toml file); "
           "varied-held-out demonstrates on half the palette and textures and tries on the "
           "other half (default: today's world)"),
    Option("--randomised-scenes", parse=integer(0), metavar="N",
           help="besides each task's demonstrations, N scenes in randomised looks labelled by "
           "the catalog (what gva collect --labels catalog --looks randomised makes, at the "
           "seed + 100 on the training stream), each "
           "trained model trained on both, as gva train --data DEMOS --data RANDOMISED; the "
           "held-out check holds out demonstrations only; plug-ins and served models are not "
           "trained and take none ({default}: none)"),
    # --loop and --replan-hz, one field checked together; a closed loop always names its rate
    Special("--loop", "loop", add_loop_options, loop_settings, loop_options),
    ROBOT,
    # --executor and --ray-address, one field; where jobs run changes no result: never written
    Special("--executor", "executor", add_executor_options, executor),
), order=("--seed", "--n", "--demos", "--steps", "--seeds", "--tasks", "--models", "--variants",
          "--balance-types", "--sensor", "--loop", "--robot", "--world", "--randomised-scenes",
          "--train-threads", "--holdout", "--gif-trials", "--use-failed-checkpoints",
          "--model-config"))
"""``gva reproduce real``'s options; ``--out`` and ``--no-progress`` are the command module's."""
