"""Argparse types of the ``gva`` options: each rejects bad text with a message that says why."""

from __future__ import annotations

import argparse
import shlex
from collections.abc import Callable

from sim.jobs import Executor, ExecutorKind


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
    """An argparse type: comma-separated names (checked against the allowed ones later)."""
    return tuple(name.strip() for name in text.split(",") if name.strip())


def integers(text: str) -> tuple[int, ...]:
    """An argparse type: comma-separated integers."""
    try:
        return tuple(int(value) for value in names(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not comma-separated integers") from None


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
    """The :class:`~sim.jobs.Executor` the options ask for (it refuses an address without Ray)."""
    return Executor(ExecutorKind(args.executor), args.ray_address)
