"""The options of the commands that pick, ``gva trials`` and ``gva reproduce real``.

Not in :mod:`experiments.commands.arguments`: the loop's settings load pinocchio, which a
command that picks nothing (``gva judge``, ``gva compare``) must not.
"""

from __future__ import annotations

import argparse

from experiments.commands.options import Option
from robots import ROBOT_NAMES
from sim.errors import InvalidInputError
from sim.trials.closed_loop.loop_settings import Loop, LoopSettings

ROBOT = Option("--robot", choices=ROBOT_NAMES,
               help="the robot that picks, seen through its workcell's camera (default "
               "{default}; docs/decisions/robots.md)")
"""``--robot``: which robot picks (its own camera, arm and hand); ``gva trials``' and
``gva reproduce real``'s."""


def add_loop_options(parser: argparse.ArgumentParser) -> None:
    """``--loop`` and ``--replan-hz``: whether picks look again while the arm approaches.

    Two options, one field (:class:`~sim.trials.closed_loop.loop_settings.LoopSettings`),
    checked together by :func:`loop_settings`: not :class:`~experiments.commands.options.Option`
    rows.
    """
    parser.add_argument("--loop", choices=[loop.value for loop in Loop],
                        default=LoopSettings.loop.value,
                        help="open (default): one image, one plan; closed: re-predict during "
                        "the approach and re-target the arm when the grasp moved")
    parser.add_argument("--replan-hz", type=float, default=LoopSettings.replan_hz,
                        help="re-predictions per second of a closed loop (%(default)s)")


def loop_settings(args: argparse.Namespace) -> LoopSettings:
    """The loop the options ask for; a rate given to an open loop is refused."""
    if args.loop == Loop.OPEN.value and args.replan_hz != LoopSettings.replan_hz:
        raise InvalidInputError("--replan-hz", args.replan_hz, "only with --loop closed")
    return LoopSettings(Loop(args.loop), args.replan_hz)


def loop_options(loop: LoopSettings) -> list[str]:
    """The command line's words for ``loop``: a closed loop names its rate, even the default's."""
    if loop.loop is not Loop.CLOSED:
        return []
    return [f"--loop closed --replan-hz {loop.replan_hz:g}"]
