"""Whether any threshold on the grasp judge's predicted success reaches issue 47's bar.

    python studies/check_judge_operating_points.py runs/t3-s10 runs/t3-s0 \
        [--out benchmarks/results/judge_operating_points.json]

The judge calls a pick a miss when its predicted success rate is below 0.5. A lower or higher
threshold trades flagged misses against false alarms; this lists, per run folder of Table III
trials, both at each threshold, so the bar (>= 80 % of misses flagged, no more false alarms
than misses) can be read against every operating point, not only the one in use.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from results_file import add_out_option, write_record

from harness.judging import judged_picks, trial_folders
from sim.trials.records import TrialOutcome, read_trial_records

THRESHOLDS = (0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.93, 0.95, 0.97, 0.99)


def operating_points(run: Path) -> dict[str, object]:
    """Picks, misses, and per threshold the misses flagged and the false alarms."""
    picks = [(jp.outcome is TrialOutcome.SUCCESS, jp.verdict.success_rate)
             for folder in trial_folders(run)
             for record in read_trial_records(folder / "trials.jsonl")
             for jp in judged_picks(record) if jp.verdict is not None]
    misses = sum(not held for held, _ in picks)
    points = [{"threshold": t,
               "flagged_misses": sum(not held and rate < t for held, rate in picks),
               "false_alarms": sum(held and rate < t for held, rate in picks)}
              for t in THRESHOLDS]
    return {"run": str(run), "picks": len(picks), "misses": misses, "points": points,
            "meets_bar": [p["threshold"] for p in points
                          if p["flagged_misses"] >= 0.8 * misses and p["false_alarms"] <= misses]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="gva reproduce real run folders")
    add_out_option(parser, "judge_operating_points")
    args = parser.parse_args()
    results = [operating_points(run) for run in args.runs]
    for result in results:
        print(f"{result['run']}: {result['picks']} picks, {result['misses']} misses")
        for point in result["points"]:
            print(f"  below {point['threshold']:.2f}: {point['flagged_misses']} flagged, "
                  f"{point['false_alarms']} false alarms")
        print(f"  thresholds meeting the bar: {result['meets_bar'] or 'none'}")
    write_record(args.out, {"benchmark": "judge_operating_points", "runs": results}, indent=1)


if __name__ == "__main__":
    main()
