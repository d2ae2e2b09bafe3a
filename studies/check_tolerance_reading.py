"""Which reading of the tolerance map predicts picks it has not seen? Cross-validated on physics.

    python studies/check_tolerance_reading.py [--map perception/judge/grasp_tolerance.json]
        [--folds 5] [--out benchmarks/results/tolerance_reading.json]

The joint picks of a map (every error at once, ``bench_grasp_tolerance.py --joint``) are split
into folds; each fold is predicted by the ``"product"`` reading (the grid alone, which never sees
a joint pick) and by the ``"logistic"`` reading fitted on the grid and the other folds. Per
object type and in all: the log-loss, and at the map's threshold the misses flagged and the
false alarms, the judge's own terms. No trial of any model is read: the choice of reading is
made on physics picks alone.
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import numpy as np
from results_file import add_out_option, write_record

from perception.judge.grasp_tolerance import LogisticTolerance, ToleranceMap, type_picks


def scores(rate: np.ndarray, held: np.ndarray, threshold: float) -> dict[str, Any]:
    """Log-loss and the judge's counts of predicted chances ``rate`` against picks ``held``."""
    clipped = np.clip(rate, 1e-6, 1 - 1e-6)
    misses = held == 0
    flagged = rate < threshold
    return {"picks": len(held), "misses": int(misses.sum()),
            "log_loss": round(float(-np.mean(held * np.log(clipped)
                                             + (1 - held) * np.log(1 - clipped))), 4),
            "flagged_misses": int((misses & flagged).sum()),
            "false_alarms": int((~misses & flagged).sum())}


def cross_validate(data: dict[str, Any], folds: int, seed: int = 0) -> dict[str, Any]:
    """Both readings on held-out joint picks, per type and pooled."""
    grid_only = copy.deepcopy(data)
    for entry in grid_only["types"].values():
        entry.pop("joint", None)
    product = ToleranceMap.from_json(grid_only | {"reading": "product"})
    threshold = product.threshold
    result: dict[str, Any] = {}
    pooled: dict[str, list[np.ndarray]] = {"product": [], "logistic": [], "held": []}
    for object_type, entry in data["types"].items():
        joint = entry["joint"]
        errors = np.asarray(joint["errors"], float)  # (n, 4)
        held = np.asarray(joint["picked"], float)
        fold = np.random.default_rng(seed).permutation(len(held)) % folds
        rates = {"product": np.empty(len(held)), "logistic": np.empty(len(held))}
        for k in range(folds):
            test = fold == k
            trained = copy.deepcopy(entry)
            trained["joint"] = {"errors": errors[~test].tolist(),
                                "picked": held[~test].tolist()}
            model = LogisticTolerance.fit(*type_picks(trained))
            rates["logistic"][test] = model.rate(errors[test])
            rates["product"][test] = [product.success_rate(
                object_type, c / 1000, a / 1000, z / 1000, np.radians(y))
                for c, a, z, y in errors[test]]
        result[object_type] = {name: scores(r, held, threshold) for name, r in rates.items()}
        pooled["product"].append(rates["product"])
        pooled["logistic"].append(rates["logistic"])
        pooled["held"].append(held)
    held_all = np.concatenate(pooled["held"])
    result["all"] = {name: scores(np.concatenate(pooled[name]), held_all, threshold)
                     for name in ("product", "logistic")}
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--map", type=Path, default=Path("perception/judge/grasp_tolerance.json"))
    parser.add_argument("--folds", type=int, default=5)
    add_out_option(parser, "tolerance_reading")
    args = parser.parse_args()
    data = json.loads(args.map.read_text())
    result = cross_validate(data, args.folds)
    for name, readings in result.items():
        for reading, s in readings.items():
            print(f"{name:<13} {reading:<9} log-loss {s['log_loss']:.3f}; {s['misses']} misses "
                  f"of {s['picks']}: {s['flagged_misses']} flagged, {s['false_alarms']} "
                  "false alarms")
    write_record(args.out, {"check": "tolerance_reading", "map": str(args.map),
                            "folds": args.folds, "result": result}, indent=1)


if __name__ == "__main__":
    main()
