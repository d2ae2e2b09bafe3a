"""Fits the grasp judge's probability calibration on real runs and writes it into its map.

    python benchmarks/fit_judge_calibration.py RUN [RUN ...]
        [--map perception/judge/grasp_tolerance.json] [--dry-run]

The tolerance map (``bench_grasp_tolerance.py``) is measured on oracle picks moved one error at
a time and some at once; read as a probability on a trained model's picks, it expected 43
misses where 30 happened (issue 63). This script judges every pick of the given run folders
with the map's own chance (any calibration it carries set aside), fits a Platt scaling of that
chance to what the physics did (:class:`perception.judge.grasp_tolerance.PlattScaling`: the chance's
order kept, so no verdict changes), prints the fit set's scores before and after, and writes
the scaling into the map's ``calibration`` with the runs it was fitted on. Judge it on runs it
was not fitted on (``gva judge``). Picks with no grasp keep probability 0 and are not fitted.
"""

from __future__ import annotations

import argparse
import datetime
import json
import subprocess
from pathlib import Path

import numpy as np

from harness.calibration import Calibration
from harness.judging import judge_run
from perception.files import atomic_write
from perception.judge.grasp_tolerance import PlattScaling, ToleranceMap

DEFAULT_MAP = Path(__file__).resolve().parents[1] / "perception" / "judge" / "grasp_tolerance.json"


def main() -> None:
    """Fits, reports, writes (unless ``--dry-run``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run folders to fit on")
    parser.add_argument("--map", type=Path, default=DEFAULT_MAP, help="tolerance map to update")
    parser.add_argument("--dry-run", action="store_true", help="fit and report, write nothing")
    args = parser.parse_args()
    data = json.loads(args.map.read_text())
    data.pop("calibration", None)
    raw_map = ToleranceMap.from_json(data)
    picks = [(p["probability"], p["held"]) for run in args.runs
             for p in judge_run(run, raw_map).probabilities]
    rates = np.array([rate for rate, _ in picks if rate > 0.0])
    held = np.array([was for rate, was in picks if rate > 0.0])
    commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                            check=False).stdout.strip()
    scaling = PlattScaling.fit(rates, held, {
        "runs": ", ".join(str(run) for run in args.runs), "picks": len(rates),
        "misses": int((~held.astype(bool)).sum()),
        "command": "python benchmarks/fit_judge_calibration.py " +
                   " ".join(str(run) for run in args.runs),
        "commit": commit, "date": datetime.date.today().isoformat()})
    before = Calibration.of(picks)
    after = Calibration.of([(scaling(rate), was) for rate, was in picks])
    print(f"{len(picks)} picks ({len(rates)} with a grasp) of {len(args.runs)} run(s)")
    print(f"the map's chance:       {before.line()}")
    print(f"slope {scaling.slope:.3f}, offset {scaling.offset:+.3f}: {after.line()}")
    if args.dry_run:
        return
    data["calibration"] = scaling.to_json()
    text = json.dumps(data, indent=1) + "\n"
    atomic_write(args.map, lambda path: path.write_text(text))
    print(f"wrote the calibration into {args.map}")


if __name__ == "__main__":
    main()
