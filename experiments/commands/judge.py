"""``gva judge RUN``: a run's picks replayed through the grasp judge, set beside the physics.

Any run folder of ``gva trials`` or ``gva reproduce real``, also one made before the judge
existed. Prints per trial set (task, seed, model) the real and the predicted count, then over
all picks the misses, the misses the judge flagged, the ones it did not and its false alarms,
per object type; the judge scored as a probability (AUC, Brier score and skill, expected misses
against observed, a reliability table: :mod:`harness.calibration`); and each unflagged miss
and false alarm with its errors in the grasp frame. ``--json`` also gives each pick's
probability.
No torch, no physics: seconds for a Table III run.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from harness.judging import RunJudgement, describe_error, judge_run
from perception.files import atomic_write
from perception.judge.grasp_tolerance import ToleranceMap, default_tolerance_map
from sim.errors import InvalidInputError


def add_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``gva judge``."""
    parser.add_argument("folder", type=Path, metavar="RUN",
                        help="a run folder of gva trials or gva reproduce real")
    parser.add_argument("--json", type=Path, metavar="FILE",
                        help="also write the whole judgement (every set, every miss) as JSON")
    parser.add_argument("--map", type=Path, metavar="FILE",
                        help="the tolerance map to judge by (default: the one gva ships, "
                        "made by benchmarks/bench_grasp_tolerance.py)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Judges the run, prints the report, writes the JSON; the exit status (0)."""
    if args.json is not None and args.json.is_dir():  # before the judging, as gva compare does
        raise InvalidInputError("--json", str(args.json), "a file to write, not a folder")
    tolerance = default_tolerance_map() if args.map is None else ToleranceMap.load(args.map)
    judgement = judge_run(args.folder, tolerance)
    if args.json is not None:  # before the report: a reader that stops early (| head) loses none
        text = json.dumps(judgement.to_json(), indent=1) + "\n"
        args.json.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(args.json, lambda path: path.write_text(text))
    print_report(judgement)
    if args.json is not None:
        print(f"wrote {args.json}")
    return 0


def print_report(judgement: RunJudgement) -> None:
    """The judgement as a reader scans it: sets, totals, then the picks it got wrong."""
    print(f"{'trial set':<44} {'task':<22} {'seed':>4} {'real':>6} {'judge':>6}")
    for s in judgement.sets:
        print(f"{s.folder:<44} {s.task:<22} {s.seed:>4} {s.successes:>3}/{s.n:<2} "
              f"{s.predicted_successes:>3}/{s.n:<2}")
    print(f"all: {judgement.picks.line()}")
    for object_type, counts in judgement.per_object.items():
        print(f"  {object_type:<13} {counts.line()}")
    calibration = judgement.calibration
    if calibration is not None:
        scaling = judgement.probability_scaling
        print("probabilities: the map's chance " + (
            "as it is (the map carries no calibration)" if scaling is None else
            f"through its calibration (slope {scaling['slope']:.3f}, offset "
            f"{scaling['offset']:+.3f}), fitted on "
            f"{scaling['fitted_on'].get('runs', 'runs it does not name')}"))
        print(f"as a probability: {calibration.line()}")
        print("  reliability: " + "; ".join(
            f"p {b.low:.1f}-{b.high:.1f}: {b.picks} picks, held {100 * b.observed_rate:.0f} %"
            for b in calibration.reliability if b.observed_rate is not None))
    unflagged = [row for row in judgement.misses
                 if row.get("judge", {}).get("predicted_success", False)]
    for title, rows in (("misses the judge did not flag", unflagged),
                        ("false alarms", judgement.false_alarms)):
        if rows:
            print(f"{title}:")
            for row in rows:
                print(f"  {row['folder']} trial {row['trial']} pick {row['pick']} "
                      f"{row['target']}: {row['outcome']}; {describe_error(row)}")
