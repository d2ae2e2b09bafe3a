"""``gva compare``: two finished runs of trials on the same trial list, compared pair by pair.

More pairs of runs (one per seed, say) pool their pairs of trials into one comparison.

Prints the pairs of outcomes, the exact McNemar test and B - A with its 95 % interval, overall
and per object type (:mod:`harness.compare` holds the statistics); ``--out`` also writes
them as JSON. Exit status 1 when B is significantly worse than A, a CI job's signal; 0
otherwise; 2 for bad input. No torch or pinocchio here.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from harness.compare import compare_pooled
from perception.files import atomic_write
from sim.errors import InvalidInputError


def add_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``gva compare``."""
    parser.add_argument("run_a", metavar="RUN_A", type=Path,
                        help="the reference run: a folder gva trials finished")
    parser.add_argument("run_b", metavar="RUN_B", type=Path,
                        help="the run compared with it, of the same task, seed and n")
    parser.add_argument("more", metavar="RUN_A RUN_B", type=Path, nargs="*",
                        help="more pairs, e.g. one per seed (gva reproduce real's "
                        "OUT/s{0..4}/trials/{kqv,fcn}/single): their trials pooled")
    parser.add_argument("--out", type=Path, metavar="FILE",
                        help="also write the comparison to FILE as JSON")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Compares the runs, prints (and writes) the comparison; 1 when B is significantly worse."""
    if args.out is not None and args.out.is_dir():
        raise InvalidInputError("--out", str(args.out), "a file to write, not a folder")
    if len(args.more) % 2:
        raise InvalidInputError("runs", f"{len(args.more) + 2} folders",
                                "pairs: RUN_A RUN_B [RUN_A RUN_B ...]")
    folders = [args.run_a, args.run_b, *args.more]
    pairs = list(zip(folders[::2], folders[1::2], strict=True))
    comparison = compare_pooled(pairs)
    shown = ((args.run_a, comparison.model_a), (args.run_b, comparison.model_b))
    labels = (f"{folder} (model {model})" + (f" and {len(pairs) - 1} more" if args.more else "")
              for folder, model in shown)
    for line in comparison.lines(*labels):
        print(line)
    if args.out is not None:
        data = {"run_a": str(args.run_a), "run_b": str(args.run_b),
                "runs": [[str(a), str(b)] for a, b in pairs]} | comparison.to_dict() | {
            "exit_status": comparison.exit_status}
        text = json.dumps(data, indent=2, sort_keys=True) + "\n"
        args.out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(args.out, lambda temporary: temporary.write_text(text))
        print(f"comparison: {args.out}")
    return comparison.exit_status
