"""What a ``gva reproduce real`` run folder holds, read back for its reports.

Each seed's GIFs, failed jobs and held-out checks, and the wall time of every run into the
folder (``history.jsonl``); the layout is :mod:`experiments.table3.settings`'s.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from experiments.table3.layout import seed_folder
from harness.run_files import read_json


def read_gifs(out: Path, seeds: Sequence[int]) -> dict[str, dict[str, Any]]:
    """The GIFs of each seed's ``gifs/`` and the trials each shows, by path in ``out``."""
    return {f"{seed_folder(out, seed).name}/gifs/{meta.stem}.gif":
            {"trials": read_json(meta)["trials"]}
            for seed in seeds for meta in sorted((seed_folder(out, seed) / "gifs").glob("*.json"))
            if meta.with_suffix(".gif").exists()}


def read_failed(out: Path, seeds: Sequence[int]) -> list[dict[str, Any]]:
    """The jobs that raised (each seed's ``errors/*.json``): job and error."""
    return [{k: read_json(p)[k] for k in ("job", "error")} for seed in seeds
            for p in sorted((seed_folder(out, seed) / "errors").glob("*.json"))]


def read_checks(out: Path, seeds: Sequence[int]) -> list[dict[str, Any]]:
    """Each finished training's held-out check (``trained.json``): seed, model, task, check."""
    found = []
    for seed in seeds:
        for trained in sorted((seed_folder(out, seed) / "checkpoints").glob("*/*/trained.json")):
            check = read_json(trained).get("check")
            if check is not None:
                found.append({"seed": seed, "model": trained.parent.parent.name,
                              "task": trained.parent.name, "passed": check["passed"],
                              "reason": check["reason"],
                              "attempts": read_json(trained).get("attempts", 1),
                              "mean_position_error_cm": check["mean_position_error_cm"],
                              "parts": check_parts(check)})
    return found


def check_parts(check: Mapping[str, Any]) -> dict[str, dict[str, float]]:
    """What a check saw of each head (or condition): error [cm], judged and expected shares.

    Where the check recorded them (older checks: the error alone). A multi-head task's parts
    are its heads; a conditioned task's, its condition values.
    """
    errors = check.get("per_target_mean_position_error_cm") or []
    if len(errors) > 1:
        names = [f"head {k}" for k in range(len(errors))]
        found = {"error_cm": dict(zip(names, errors, strict=True)),
                 "judged": check.get("per_target_judged_success_rate") or {},
                 "expected": check.get("per_target_expected_success") or {}}
    else:
        found = {"error_cm": check.get("per_condition_mean_position_error_cm") or {},
                 "judged": check.get("per_condition_judged_success_rate") or {},
                 "expected": check.get("per_condition_expected_success") or {}}
    parts = {name: {kind: float(values[name]) for kind, values in found.items()
                    if name in values} for name in found["error_cm"]}
    if parts:
        return parts
    whole = {"error_cm": check.get("mean_position_error_cm"),
             "judged": check.get("judged_success_rate"),
             "expected": check.get("expected_success")}  # one head, no condition: the whole
    return {"all": {kind: float(value) for kind, value in whole.items() if value is not None}}


def history_wall_time_s(out: Path) -> float:
    """The wall time of every run into ``out`` together [s] (``history.jsonl``)."""
    path = out / "history.jsonl"
    if not path.exists():
        return 0.0
    return sum(json.loads(line)["wall_time_s"] for line in path.read_text().splitlines()
               if line.strip())
