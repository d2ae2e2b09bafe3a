"""Argparse types of the ``gva`` options, and the options several commands share.

Each type rejects bad text with a message that says why. The options of a command that fills a
settings dataclass are declared once, as :class:`~experiments.commands.options.Option` rows
(:mod:`experiments.commands.options`); those several commands share are here and, for the
commands that pick, in :mod:`experiments.commands.pick_options`.
"""

from __future__ import annotations

import argparse
import shlex
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from experiments.commands.options import CommandLine, Option
from harness.jobs import Executor, ExecutorKind
from sim.tasks.task_sensor import as_sensor_kind
from sim.world.sensor import DEFAULT_SENSOR, SensorKind

if TYPE_CHECKING:  # imported where used: a command's --help must not load torch
    from perception.model_config_file import ModelConfigFile


def integer(minimum: int) -> Callable[[str], int]:
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


def names(text: str) -> tuple[str, ...]:
    """An argparse type: comma-separated names (checked against the allowed ones later).

    An empty name (``a,,b``, a trailing comma, nothing at all) is refused: it is a typo, and
    dropping it silently runs less than was asked.
    """
    parts = tuple(name.strip() for name in text.split(","))
    if not all(parts):
        raise argparse.ArgumentTypeError(f"{text!r} is not allowed: comma-separated names, "
                                         "none empty")
    return parts


class Once(argparse.Action):
    """An argparse action: the option may be given once; a second value is refused by name.

    Argparse's own keeps the last of several (``--variant dark --variant block`` ran ``block``
    alone, without a word).
    """

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: object, option_string: str | None = None) -> None:
        """Keeps the value; the option's second appearance stops the command (exit 2)."""
        if getattr(namespace, self.dest, None) is not None:
            parser.error(f"{option_string} is given twice ({getattr(namespace, self.dest)!r}, "
                         f"{values!r}): give it once")
        setattr(namespace, self.dest, values)


def variant_names(text: str) -> tuple[str, ...]:
    """An argparse type, ``--variants``: comma-separated names or files; ``none`` for none.

    An empty name, or nothing at all, is refused as :func:`names` refuses it: say ``none``.
    """
    return () if text.strip() == "none" else names(text)


def integers(text: str) -> tuple[int, ...]:
    """An argparse type: comma-separated integers."""
    try:
        return tuple(int(value) for value in names(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not comma-separated integers") from None


def model_config_pair(text: str) -> tuple[str, str]:
    """An argparse type: ``MODEL=FILE.toml``, a ``--model-config`` of a run of several models."""
    model, equals, path = text.partition("=")
    if not equals or not model.strip() or not path.strip():
        raise argparse.ArgumentTypeError(f"{text!r} is not MODEL=FILE.toml")
    return model.strip(), path.strip()


def add_model_config_option(parser: argparse.ArgumentParser) -> None:
    """``--model-config MODEL=FILE.toml``, repeatable: a model's settings from a file."""
    parser.add_argument("--model-config", type=model_config_pair, action="append", default=[],
                        metavar="MODEL=FILE.toml",
                        help="settings of MODEL (one of --models) from a TOML file, a top-level "
                        "key per field of its config (docs/perception.md); repeatable, one "
                        "per model; part of each checkpoint's identity")


def model_config_files(args: argparse.Namespace) -> tuple[ModelConfigFile, ...]:
    """The ``--model-config`` files, each checked against ``--models`` and then read."""
    from experiments.tables import check_model_configs
    from perception.model_config_file import ModelConfigFile

    check_model_configs(args.model_config, args.models)
    return tuple(ModelConfigFile.read(path, model) for model, path in args.model_config)


def sensor_option(otherwise: str = "") -> Option:
    """``--sensor``: what the yumi scene is rendered through, as ``gva reproduce real --sensor``.

    It replaces the task file's ``[camera] sensor``; without it, the file's, else ``otherwise``
    (e.g. a checkpoint's own sensor), else the D435 (:mod:`sim.tasks.task_sensor`).
    """
    return Option("--sensor", choices=SensorKind,
                  help="yumi scene: what the head camera renders through, replacing the task "
                  "file's [camera] sensor: d435 (lens distortion, depth noise and holes, "
                  "hand-eye error; docs/decisions/d435-sensor.md) or ideal, an exact pinhole "
                  f"(default: the task file's, else {otherwise}{DEFAULT_SENSOR.value})")


def add_sensor_option(parser: argparse.ArgumentParser, otherwise: str = "") -> None:
    """:func:`sensor_option` for a command whose settings have no sensor field: none by default."""
    sensor_option(otherwise).add_to(parser, None)


def sensor_kind(args: argparse.Namespace) -> SensorKind | None:
    """The ``--sensor`` asked for; None where none was."""
    return as_sensor_kind(args.sensor)


def add_reproduce_options(parser: argparse.ArgumentParser, table: CommandLine,
                          settings: type[Any], run: Callable[[argparse.Namespace], int],
                          progress_help: str) -> None:
    """A ``gva reproduce`` command's options: ``--out``, ``table``'s, ``--no-progress``.

    Both reproduce commands resume a run folder (``--out``) and draw progress bars; the rest
    of their options is their ``table``'s, each default the field's of ``settings``. The
    command runs ``run``.
    """
    parser.add_argument("--out", type=Path, required=True, help="run folder")
    table.add_to(parser, settings)
    parser.add_argument("--no-progress", action="store_true", help=progress_help)
    parser.set_defaults(run=run)


def resume_command(args: argparse.Namespace) -> str:
    """The command line that was run, quoted for a shell: running it again resumes the run."""
    return shlex.join(["gva", *args.argv])


def add_executor_options(parser: argparse.ArgumentParser) -> None:
    """``--executor`` and ``--ray-address``: where a run's jobs go (docs/cluster.md)."""
    parser.add_argument("--executor", choices=[kind.value for kind in ExecutorKind],
                        default=Executor.kind.value,
                        help="local: this machine's process pool (default); ray: Ray tasks, on "
                        "a local Ray started for the run or the cluster of --ray-address "
                        "(pip install -e '.[ray]')")
    parser.add_argument("--ray-address", metavar="ADDRESS",
                        help="the Ray cluster to join, e.g. ray://head:10001 (default: "
                        "$RAY_ADDRESS, else a local Ray); every node must see --out")


def executor(args: argparse.Namespace) -> Executor:
    """The :class:`~harness.jobs.Executor` the options ask for (refuses an address without Ray)."""
    return Executor(ExecutorKind(args.executor), args.ray_address)

