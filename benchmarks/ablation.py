"""The ``kqv`` ablation at today's recipe (issue 35): each departure from the paper removed alone.

    python benchmarks/ablation.py --workers 2                  # every row, resumed where it stopped
    python benchmarks/ablation.py --rows recipe,minus-starts --tasks single --seeds 2
    python benchmarks/ablation.py --from runs/ablation         # read finished folders, run nothing

A row is a model config file ``benchmarks/ablation/<row>.toml`` for ``kqv`` (every file there,
``paper-plus-*`` rows added later included), plus ``recipe``: no file, today's ``kqv``. Each
runs (or resumes) ``gva reproduce sim --scene yumi --models kqv --sizes 20 --seeds N --seed S
--tasks T [--workers W] --out OUT/<row> [--model-config kqv=FILE]``, recipe first; a row's
folder is given the datasets other rows' folders already hold (hard links: the demonstrations
depend on the task and seed alone, and each file is checked against what the run asks).

The record (``--json``) and the printed table give, per row and task, over the training seeds:
the mean position error on the untrained test scenes with its sample std and the worst seed;
the grasp judge's predicted picked share pooled over the seeds' targets and at the worst seed;
the median training seconds per cell; and the difference of mean errors against ``recipe``
(row minus recipe: positive, the removed departure helps), flagged *beyond the seed spread*
when |mean of the paired per-seed differences| > 2 x their standard error (sample std of the
differences / sqrt(seeds)), over the seeds both rows finished (at least two); a
``paper-plus-*`` row also against ``paper``. A task a row has not finished, or whose folder
holds another row's settings, is shown as such, with no number.
A row whose settings are the recipe's on a task (:data:`ONLY_TASKS`) is not trained there. A
row that changes only how a trained network is read (every setting in
:data:`~perception.models.kqv_config.INFERENCE_FIELDS`, e.g. ``minus-focus``) is not trained at
all: the recipe's checkpoints are scored again under its settings on the recipe's test scenes
(``OUT/<row>/rescored.json``, each cell tied to the recipe cell it came from), and its
training time is the recipe's.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import statistics
import sys
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from results_file import add_out_option, write_record

from experiments.cli import main as gva
from harness.run_files import dataset_path
from perception.learning.dataset_file import load_dataset
from perception.learning.evaluate import evaluate
from perception.model_config_file import read_model_config
from perception.models.kqv import KqvModel
from perception.models.kqv_config import INFERENCE_FIELDS
from perception.registry import load_model
from sim.tasks.scene_sampling import SeedStream

ROWS_DIR = Path(__file__).resolve().parent / "ablation"
RECIPE = "recipe"
PAPER = "paper"
TASKS = ("single", "multiple", "selected-type", "selected-position")
SIZE = 20
TEST_SCENES = 100
RESCORED = "rescored.json"
ONLY_TASKS: Mapping[str, tuple[str, ...]] = {
    # query_mode "paper" and "auto" differ on an object-type condition only.
    "minus-query": ("selected-type",),
    # the recipe trains no type head where the condition names the type.
    "minus-type-head": ("single", "multiple", "selected-position"),
}
"""Rows trained on some tasks only: on the others their model is the recipe's."""


@dataclass(frozen=True)
class SeedStats:
    """A quantity over training seeds: mean, sample std (None for one seed), the worst seed."""

    mean: float
    std: float | None
    worst_seed: int
    worst: float


@dataclass(frozen=True)
class Difference:
    """A row's mean error minus the recipe's [cm], over the seeds both finished, paired."""

    difference_cm: float
    standard_error_cm: float  # sample std of the per-seed differences / sqrt(seeds)
    seeds: int
    beyond_seed_spread: bool  # |difference_cm| > 2 x standard_error_cm


def seed_stats(values: Mapping[int, float], worst_is_high: bool = True) -> SeedStats:
    """Mean, std and worst seed of per-seed ``values`` (the highest, else the lowest, is worst)."""
    worst_seed = (max if worst_is_high else min)(sorted(values), key=lambda s: values[s])
    data = list(values.values())
    return SeedStats(statistics.fmean(data), statistics.stdev(data) if len(data) > 1 else None,
                     worst_seed, values[worst_seed])


def paired_difference(row: Mapping[int, float], recipe: Mapping[int, float]) -> Difference | None:
    """The row's error against the recipe's, seed by seed; None: fewer than two common seeds."""
    seeds = sorted(set(row) & set(recipe))
    if len(seeds) < 2:
        return None
    differences = [row[s] - recipe[s] for s in seeds]
    mean = statistics.fmean(differences)
    error = statistics.stdev(differences) / math.sqrt(len(seeds))
    return Difference(mean, error, len(seeds), abs(mean) > 2 * error)


def inference_only(settings: Mapping[str, Any]) -> bool:
    """Whether a row changes only how a trained network is read (scored, never trained)."""
    return bool(settings) and set(settings) <= INFERENCE_FIELDS


def rescore(out: Path, row: str, file: Path, tasks: Sequence[str], seeds: Sequence[int]) -> int:
    """Scores the recipe's finished cells under an inference-only row; returns cells scored.

    Writes ``out/row/rescored.json`` as ``reproduce sim`` writes ``table2.json`` (the fields
    :func:`row_summary` reads), each cell with the identity of the recipe cell it came from: a
    cell is scored again only when that cell changed. Recipe cells not finished are left out.
    """
    settings = read_model_config(file, "kqv")
    recipe = out / RECIPE
    if not (recipe / "table2.json").exists():
        print(f"[{row}] scores the recipe's checkpoints: run the recipe row first", flush=True)
        return 0
    run = json.loads((recipe / "table2.json").read_text())["settings"]
    target = out / row / RESCORED
    kept = {(c["task"], c["seed"]): c for c in (json.loads(target.read_text())["cells"]
                                                if target.exists() else [])}
    cells, scored = [], 0
    for path in sorted((recipe / "cells").glob(f"kqv-*-{SIZE}-s*.json")):
        source = json.loads(path.read_text())
        if path.name.endswith("-error.json") or source["task"] not in tasks or source[
                "seed"] not in seeds:
            continue
        old = kept.get((source["task"], source["seed"]))
        if old is not None and old["scored_from"] == source["identity"] and old[
                "settings"] == settings:
            cells.append(old)
            continue
        model = load_model(recipe / source["checkpoint"])
        assert isinstance(model, KqvModel), path  # the recipe row trains kqv
        test = load_dataset(dataset_path(recipe, source["task"], SeedStream.TEST,
                                         run["test_scenes"], run["test_seed"]))
        result = evaluate(model.read_with(**settings), test)
        cells.append({k: source[k] for k in ("model", "task", "size", "seed", "train_s")} | {
            "error_cm": result.mean_position_error_cm,
            "judged": None if result.judged is None else result.judged.to_json(),
            "settings": settings, "scored_from": source["identity"]})
        scored += 1
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(json.dumps({"cells": cells, "failed": [], "settings": {
        "scene": run["scene"], "test_scenes": run["test_scenes"], "scored_from": str(recipe),
        "model_configs": {"kqv": {"path": str(file), "settings": settings}}}}, indent=1) + "\n")
    return scored


def row_files(folder: Path = ROWS_DIR) -> dict[str, Path]:
    """Every row file of ``folder``: its stem -> its path, in name order."""
    return {path.stem: path for path in sorted(folder.glob("*.toml"))}


def task_summary(cells: Sequence[Mapping[str, Any]], seeds: Sequence[int]) -> dict[str, Any]:
    """One row's task from its ``table2.json`` cells: errors, judged picks and times per seed."""
    errors = {c["seed"]: c["error_cm"] for c in cells if c["seed"] in seeds}
    missing = [s for s in seeds if s not in errors]
    summary: dict[str, Any] = {"status": "unfinished" if missing else "finished",
                               "seeds_missing": missing,
                               "error_cm": {str(s): errors[s] for s in sorted(errors)}}
    if missing:
        return summary
    used = [c for c in cells if c["seed"] in seeds]
    summary["error"] = asdict(seed_stats(errors))
    summary["median_train_s"] = statistics.median(c["train_s"] for c in used)
    judged = {c["seed"]: c["judged"]["all"] for c in used if c.get("judged")}
    if len(judged) == len(seeds):  # position labels and cells made before the judge have none
        picked = sum(j["predicted_success_rate"] * j["targets"] for j in judged.values())
        rates = {s: j["predicted_success_rate"] for s, j in judged.items()}
        summary["picked"] = {"pooled": picked / sum(j["targets"] for j in judged.values()),
                             **asdict(seed_stats(rates, worst_is_high=False))}
    return summary


def row_summary(folder: Path, file: Path | None, tasks: Sequence[str],
                seeds: Sequence[int]) -> dict[str, Any]:
    """A row's record read from ``folder/table2.json``; unfinished tasks say so."""
    settings = {} if file is None else read_model_config(file, "kqv")
    record: dict[str, Any] = {"file": None if file is None else str(file),
                              "settings": json.loads(json.dumps(settings)), "tasks": {}}
    path = folder / (RESCORED if inference_only(settings) else "table2.json")
    table = json.loads(path.read_text()) if path.exists() else None
    made_with = None if table is None else (table["settings"].get("model_configs") or {}).get(
        "kqv", {}).get("settings", {})
    for task in tasks:
        if task not in ONLY_TASKS.get(folder.name, tasks):
            record["tasks"][task] = {"status": "recipe's model"}
        elif table is None:
            record["tasks"][task] = {"status": "not run", "seeds_missing": list(seeds)}
        elif made_with != record["settings"] or (table["settings"]["scene"], table[
                "settings"]["test_scenes"]) != ("yumi", TEST_SCENES):
            record["tasks"][task] = {"status": "other settings"}  # rerun into another --out
        else:
            cells = [c for c in table["cells"] if c["model"] == "kqv" and c["task"] == task
                     and c["size"] == SIZE]
            record["tasks"][task] = task_summary(cells, seeds)
    times = [t["median_train_s"] for t in record["tasks"].values() if "median_train_s" in t]
    record["median_train_s"] = statistics.median(times) if times else None
    return record


def summarise(out: Path, rows: Mapping[str, Path | None], tasks: Sequence[str],
              seeds: Sequence[int]) -> dict[str, Any]:
    """Every row's record, each finished task compared with ``out/recipe``'s.

    A ``paper-plus-*`` row (the paper's model with one departure restored) is also compared
    with ``out/paper``'s, where that row is finished: what the one departure buys the paper.
    """
    recipe = row_summary(out / RECIPE, None, tasks, seeds)
    records = {name: recipe if name == RECIPE else row_summary(out / name, file, tasks, seeds)
               for name, file in rows.items()}
    paper_file = row_files().get(PAPER)
    paper = None if paper_file is None else records.get(PAPER) or row_summary(
        out / PAPER, paper_file, tasks, seeds)
    for name, record in records.items():
        bases = [("vs_recipe", recipe)] + ([("vs_paper", paper)] if paper is not None
                                           and name.startswith(f"{PAPER}-plus-") else [])
        for task, entry in record["tasks"].items():
            for key, base_record in bases:
                base = base_record["tasks"][task]
                if name != RECIPE and entry["status"] == base["status"] == "finished":
                    difference = paired_difference(
                        {int(s): e for s, e in entry["error_cm"].items()},
                        {int(s): e for s, e in base["error_cm"].items()})
                    entry[key] = None if difference is None else asdict(difference)
    return {"benchmark": "ablation", "out": str(out), "scene": "yumi", "size": SIZE,
            "tasks": list(tasks), "seeds": list(seeds), "rows": records, "machine": machine()}


def markdown(summary: Mapping[str, Any]) -> list[str]:
    """The summary as one markdown table, a line per row and task."""
    lines = ["| row | task | error cm, mean ± std | worst seed cm | picked pooled | "
             "picked worst seed | train s (median) | vs recipe cm |", "|---" * 8 + "|"]
    for name, record in summary["rows"].items():
        for task, entry in record["tasks"].items():
            if entry["status"] != "finished":
                missing = entry.get("seeds_missing", [])
                note = entry["status"] + (f" ({len(summary['seeds']) - len(missing)}/"
                                          f"{len(summary['seeds'])} seeds)" if missing else "")
                lines.append(f"| {name} | {task} | {note} |" + " |" * 5)
                continue
            error = entry["error"]
            std = "" if error["std"] is None else f" ± {error['std']:.2f}"
            picked = entry.get("picked")
            pooled = "—" if picked is None else f"{100 * picked['pooled']:.0f} %"
            worst = "—" if picked is None else (f"{100 * picked['worst']:.0f} % "
                                                f"(s{picked['worst_seed']})")
            shown = " ".join(
                f"{versus['difference_cm']:+.2f} ± {versus['standard_error_cm']:.2f}"
                + (" *" if versus["beyond_seed_spread"] else "") + label
                for key, label in (("vs_recipe", ""), ("vs_paper", " (vs paper)"))
                if (versus := entry.get(key)) is not None) or "—"
            lines.append(f"| {name} | {task} | {error['mean']:.2f}{std} | {error['worst']:.2f} "
                         f"(s{error['worst_seed']}) | {pooled} | {worst} | "
                         f"{entry['median_train_s']:.0f} | {shown} |")
    lines += ["", "vs recipe: row minus recipe, ± the paired standard error over seeds; "
              "*: beyond the seed spread (more than 2 standard errors)."]
    return lines


def command(row: str, file: Path | None, out: Path, args: argparse.Namespace) -> list[str]:
    """The ``gva`` arguments that run (or resume) ``row`` into ``out/row``."""
    tasks = [t for t in args.tasks if t in ONLY_TASKS.get(row, args.tasks)]
    argv = ["reproduce", "sim", "--scene", "yumi", "--models", "kqv", "--sizes", str(SIZE),
            "--seeds", str(args.seeds), "--seed", str(args.seed), "--tasks", ",".join(tasks),
            "--out", str(out / row)]
    if args.workers is not None:
        argv += ["--workers", str(args.workers)]
    if file is not None:
        shown = file.relative_to(Path.cwd()) if file.is_relative_to(Path.cwd()) else file
        argv += ["--model-config", f"kqv={shown}"]
    return argv


def share_datasets(out: Path, row: str) -> int:
    """Links into ``out/row/datasets`` the files other rows' folders hold; returns how many."""
    target = out / row / "datasets"
    linked = 0
    for source in sorted(out.glob("*/datasets/*.gva")):
        destination = target / source.name
        if source.parent == target or destination.exists():
            continue
        target.mkdir(parents=True, exist_ok=True)
        try:
            os.link(source, destination)
        except OSError:  # another file system, or links not allowed: a copy does too
            shutil.copy2(source, destination)
        linked += 1
    return linked


def machine() -> dict[str, Any]:
    """The machine the record was written on: CPUs, load average, Python (as the benchmarks')."""
    return {"cpus": os.cpu_count(), "cpus_usable": len(os.sched_getaffinity(0)),
            "load_average_1_5_15min": [round(v, 2) for v in os.getloadavg()],
            "python": platform.python_version(), "platform": platform.platform()}


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """The options; ``--rows`` and ``--tasks`` checked and split."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    parser.add_argument("--rows", help=f"comma-separated (default: {RECIPE} and every file of "
                        f"{ROWS_DIR})")
    parser.add_argument("--tasks", default=",".join(TASKS), help="comma-separated (%(default)s)")
    parser.add_argument("--seeds", type=int, default=5, help="training seeds (%(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="first training seed (%(default)s)")
    parser.add_argument("--workers", type=int, help="processes at once (gva's default)")
    parser.add_argument("--out", type=Path, default=Path("runs/ablation"),
                        help="a folder per row inside (%(default)s)")
    parser.add_argument("--from", dest="source", type=Path,
                        help="a finished --out: read its row folders, run nothing")
    add_out_option(parser, "ablation", flag="--json")
    args = parser.parse_args(argv)
    files = row_files()
    known = [RECIPE, *files]
    args.rows = known if args.rows is None else args.rows.split(",")
    unknown = [r for r in args.rows if r not in known]
    if unknown:
        parser.error(f"unknown row(s) {', '.join(unknown)}; known: {', '.join(known)}")
    args.files = {r: files.get(r) for r in args.rows}
    args.tasks = args.tasks.split(",")
    if args.seeds < 1 or args.seed < 0:
        parser.error(f"--seeds {args.seeds} --seed {args.seed}: want seeds >= 1, seed >= 0")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the rows asked (or reads ``--from``), writes the record and prints the table."""
    args = parse_args(argv)
    out = args.source or args.out
    seeds = list(range(args.seed, args.seed + args.seeds))
    status = 0
    if args.source is None:
        ordered = sorted(args.files.items(), key=lambda item: item[0] != RECIPE)
        for row, file in ordered:
            if file is not None and inference_only(read_model_config(file, "kqv")):
                scored = rescore(out, row, file, args.tasks, seeds)
                print(f"[{row}] {scored} recipe checkpoint(s) scored under {file.name}",
                      flush=True)
                continue
            linked = share_datasets(out, row)
            argv_row = command(row, file, out, args)
            print(f"[{row}] gva {' '.join(argv_row)}" + (f" ({linked} dataset(s) linked)"
                                                         if linked else ""), flush=True)
            row_status = gva(argv_row)
            if row_status == 130:  # Ctrl-C: stop the sweep, the rows keep what they finished
                return row_status
            status = max(status, row_status)
    summary = summarise(out, args.files, args.tasks, seeds)
    write_record(args.json, summary, announce=False)
    print("\n".join(markdown(summary)))
    print(f"wrote {args.json}")
    return status


if __name__ == "__main__":
    sys.exit(main())
