"""The ``gva`` command line.

    gva trials --model oracle --task single --n 30 --seed 0 --out runs/oracle-single

Bad input exits with status 2 and one line naming the value and what is allowed; a run that
stops half-way is resumed by running the same command again.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

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
    trials.add_argument("--model", default="oracle", help="perception model (default: oracle)")
    trials.add_argument("--task", default="single", help="task name (default: single)")
    trials.add_argument("--n", type=_integer(1), default=30, help="number of trials (30)")
    trials.add_argument("--seed", type=_integer(0), default=0, help="seed of the test scenes (0)")
    trials.add_argument("--out", type=Path, required=True, help="run folder")
    trials.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser


def _run_trials(args: argparse.Namespace) -> int:
    from sim.trials import TrialSettings, run_trials

    settings = TrialSettings(model=args.model, task=args.task, n=args.n, seed=args.seed)
    summary = run_trials(settings, args.out, progress=not args.no_progress)
    print(summary.headline())
    for outcome, count in summary.outcomes.items():
        if count:
            print(f"  {outcome:<18} {count}")
    print(f"median wall time per trial: {summary.median_wall_time_s:.2f} s")
    print(f"trials: {args.out / 'trials.jsonl'}   summary: {args.out / 'summary.json'}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``gva`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        if args.command == "trials":
            return _run_trials(args)
    except (SimError, ControlError, PerceptionError, ValueError) as error:
        print(f"gva {args.command}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"gva {args.command}: interrupted; run the same command again to resume",
              file=sys.stderr)
        return 130
    raise AssertionError(f"unhandled command {args.command}")  # argparse rejects others


if __name__ == "__main__":
    sys.exit(main())
