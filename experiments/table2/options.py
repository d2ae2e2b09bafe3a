"""The options of ``gva reproduce sim``, declared once as :data:`SIM`.

As ``gva reproduce real``'s (:mod:`experiments.table3.options`): the parser, the settings and
``settings.command(out)`` derive from it (:mod:`experiments.commands.options`).
"""

from __future__ import annotations

from experiments.commands.arguments import (
    add_executor_options,
    add_model_config_option,
    executor,
    integer,
    integers,
    model_config_files,
    names,
    sensor_option,
)
from experiments.commands.options import CommandLine, Option, Special, same_members
from experiments.tables import BEYOND_TASKS, model_config_options

SCENES = ("paper-sim", "yumi")
"""The scenes a sweep can run on (yumi: demonstrations, offline); here, not in the settings'
module, so that it can import :data:`SIM` for its command line."""

SIM = CommandLine("gva reproduce sim", (
    Option("--seeds", parse=integer(1), shown="always", help="training seeds ({default})"),
    Option("--seed", parse=integer(0), shown="always",
           help="first training seed, also the test scenes' seed ({default})"),
    Option("--workers", parse=integer(1), shown="never",
           help="processes at once (default: the cores this process may use)"),
    Option("--models", parse=names, same=same_members,
           help="comma-separated (default all: {default})"),
    # repeated MODEL=FILE, each checked against --models and read: its own shape
    Special("--model-config", "model_configs", add_model_config_option, model_config_files,
            model_config_options),
    Option("--tasks", parse=names, same=same_members,
           help="comma-separated (default the paper's: {default}; beyond it: "
           f"{','.join(BEYOND_TASKS)})"),
    Option("--sizes", parse=integers, same=same_members,
           help="training set sizes, comma-separated (default all: {default})"),
    Option("--steps", parse=integer(1), shown="always",
           help="optimiser steps per training phase ({default})"),
    Option("--test-scenes", parse=integer(1),
           help="test scenes per task ({default}, as in the paper; fewer for a quick check)"),
    Option("--scene", choices=SCENES,
           help="paper-sim (Table II) or yumi (the robot's demonstrations, offline) ({default})"),
    sensor_option(),
    # --executor and --ray-address, one field; where jobs run changes no result: never written
    Special("--executor", "executor", add_executor_options, executor),
), order=("--seeds", "--seed", "--steps", "--models", "--tasks", "--sizes", "--test-scenes",
          "--scene", "--sensor", "--model-config"))
"""``gva reproduce sim``'s options; ``--out`` and ``--no-progress`` are the command module's."""
