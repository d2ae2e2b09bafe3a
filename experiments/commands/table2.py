"""``gva reproduce sim``: the paper's Table II in the simulator, its options and summary.

Its options are declared once, in :data:`experiments.table2.options.SIM`; their defaults are
:class:`~experiments.table2.settings.ReproduceSimSettings`'.
"""

from __future__ import annotations

import argparse

from experiments.commands.arguments import add_reproduce_options
from experiments.table2.options import SIM
from experiments.table2.run import run_reproduce_sim
from experiments.table2.settings import ReproduceSimSettings


def add_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``gva reproduce sim``."""
    add_reproduce_options(parser, SIM, ReproduceSimSettings, run, "no progress bars")


def run(args: argparse.Namespace) -> int:
    """Runs (or resumes) the table and prints its summary; 1 when some cell failed."""
    settings = ReproduceSimSettings(**SIM.keywords(args, ReproduceSimSettings))
    report = run_reproduce_sim(settings, args.out, progress=not args.no_progress)
    for line in report.summary_lines(
            "cell(s) computed", lambda r: f"{r['model']}-{r['task']}-{r['size']}-s{r['seed']}"):
        print(line)
    print("wrote " + ", ".join(str(path) for path in report.outputs))
    return 1 if report.failed else 0
