"""``gva reproduce real``: the paper's Table III on the simulated YuMi, its options and summary.

Its options are declared once, in :data:`experiments.table3.options.REAL`; their defaults are
:class:`~experiments.table3.settings.ReproduceRealSettings`' (and the held-out check's,
:class:`~perception.learning.validation.CheckConfig`'s).
"""

from __future__ import annotations

import argparse

from experiments.commands.arguments import add_reproduce_options
from experiments.table3.options import REAL
from experiments.table3.run import run_reproduce_real
from experiments.table3.settings import ReproduceRealSettings


def add_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``gva reproduce real``."""
    add_reproduce_options(parser, REAL, ReproduceRealSettings, run, "no progress bar")


def run(args: argparse.Namespace) -> int:
    """Runs (or resumes) the table and prints its summary; 1 when some job failed."""
    settings = ReproduceRealSettings(**REAL.keywords(args, ReproduceRealSettings))
    report = run_reproduce_real(settings, args.out, progress=not args.no_progress)
    for line in report.summary_lines("job(s) run", lambda record: record["job"]):
        print(line)
    print(report.table)
    print(f"files: {args.out}/ (table3.md, table3.json; per seed s<seed>/: gifs/, trials/, "
          "checkpoints/)")
    return 1 if report.failed else 0
