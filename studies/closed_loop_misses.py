"""Why a closed loop's moved-target picks missed, read from their trial records.

Each failed trial of a moved task falls in one class (issue 66, docs/decisions/closed-loop.md):
``not followed`` (no re-prediction after the move was heeded: the pick went where the target
was), split by whether some look after the move named the new place within 2 cm (``seen,
unheeded``: the view rule held it back) or none did (``never seen``); ``followed, off`` (a
re-target was heeded and the grasp still closed off it); ``other`` (plans, collisions).

    python studies/closed_loop_misses.py runs/cl66b/s0/trials/kqv/selected-type-moved ...
"""

from __future__ import annotations

import argparse
import collections
import json
from pathlib import Path

SEEN_M = 0.02
"""A look after the move "saw" the new place when its grasp was this near the truth [m]."""


def miss_class(record: dict) -> str:
    """The class of one failed trial's record (see the module docstring)."""
    if record["outcome"] != "missed" or not record.get("picks"):
        return "other"
    pick = record["picks"][0]
    moved_at = (pick.get("disturbance") or {}).get("time_s")
    looks = [look for look in pick.get("repredictions") or []
             if moved_at is not None and look["time_s"] >= moved_at]
    if any(look["reaction"] == "retargeted" for look in looks):
        return "followed, off"
    if any(look["position_error_m"] <= SEEN_M for look in looks):
        return "not followed: seen, unheeded"
    return "not followed: never seen"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", type=Path, nargs="+", help="trial folders (trials.jsonl)")
    args = parser.parse_args()
    total: collections.Counter[str] = collections.Counter()
    for folder in args.folders:
        records = [json.loads(line) for line in (folder / "trials.jsonl").read_text().splitlines()]
        counts = collections.Counter(miss_class(r) for r in records if r["outcome"] != "success")
        total.update(counts)
        picked = sum(r["outcome"] == "success" for r in records)
        print(f"{folder}: {picked}/{len(records)} picked; misses: {dict(sorted(counts.items()))}")
    print(f"all: {dict(sorted(total.items()))}")


if __name__ == "__main__":
    main()
