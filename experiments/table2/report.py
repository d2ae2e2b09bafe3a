"""The reports of ``gva reproduce sim``, rebuilt from every cell file of a run folder.

``table2.json`` (the cells, their means and spreads, the settings, the failures) and
``table2.md`` (ours laid out like the paper's Table II, then the paper's numbers,
:data:`PAPER_TABLE2_CM`, and where the two differ); the plots are :mod:`.figures`'. What each
file holds: ``docs/reproducing.md``.
"""

from __future__ import annotations

import statistics
from collections import defaultdict
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from experiments.table2.figures import draw_fig5, plot_table2
from experiments.table2.settings import (
    BOLD_BELOW_CM,
    SIZES,
    Cell,
    Key,
    ReproduceSimSettings,
)
from experiments.tables import (
    ALL_TASKS,
    NO_IMAGE,
    PAPER_MODELS,
    TASK_TITLES,
    model_order,
    model_title,
    paper_row,
)
from harness.run_files import dataset_path, read_json, write_json, write_text
from harness.run_report import duration
from perception.learning.data import Dataset
from perception.learning.dataset_file import load_dataset
from perception.learning.evaluate import label_mean_error_cm
from sim.tasks.scene_sampling import SeedStream

RATIO_FLAGGED = 2.0
"""Cells where ours and the paper's differ by more than this factor are listed for a look."""
NEAR_NO_IMAGE = 0.8
"""A mean error above this fraction of the no-image reference's counts as at its level."""
PAPER_TABLE2_CM: Mapping[str, Mapping[str, tuple[float, float, float]]] = {
    # The paper's Table II: mean error [cm] per task at 4, 20 and 100 training scenes.
    "kqv": {"single": (4.14, 2.88, 3.83), "multiple": (4.80, 3.21, 2.80),
            "selected-type": (27.16, 4.27, 4.62), "selected-position": (32.81, 4.85, 3.95)},
    "keypoint-16": {"single": (2.16, 3.69, 0.62), "multiple": (22.41, 3.85, 2.61),
                    "selected-type": (33.28, 24.61, 7.94),
                    "selected-position": (31.82, 15.75, 9.63)},
    "keypoint-min": {"single": (18.79, 18.07, 0.65), "multiple": (41.90, 48.47, 49.02),
                     "selected-type": (38.90, 23.54, 5.68),
                     "selected-position": (30.10, 20.51, 9.17)},
    "dsae-16": {"single": (15.12, 15.52, 60.05), "multiple": (22.69, 29.18, 30.26),
                "selected-type": (27.12, 39.30, 28.55),
                "selected-position": (43.97, 36.22, 28.41)},
    "conv-ae": {"single": (34.07, 30.81, 17.17), "multiple": (65.84, 44.16, 46.88),
                "selected-type": (43.84, 40.21, 39.98),
                "selected-position": (81.79, 19.88, 40.88)},
    "fcn": {"single": (14.91, 6.18, 1.60), "multiple": (33.94, 31.70, 30.52),
            "selected-type": (26.74, 27.62, 28.53), "selected-position": (34.82, 19.42, 14.82)},
}


def _order(record: Mapping[str, Any]) -> tuple[tuple[int, str], int, int, int]:
    return (model_order(record["model"]), ALL_TASKS.index(record["task"]),
            SIZES.index(record["size"]), record["seed"])


def read_cells(out: Path) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """(finished cells, failed cells without a finished file) of a run folder, in table order."""
    finished: list[dict[str, Any]] = []
    failed: list[dict[str, Any]] = []
    for path in (out / "cells").glob("*.json"):
        record = read_json(path)
        (failed if path.name.endswith("-error.json") else finished).append(record)
    names = {Cell(r["model"], r["task"], r["size"], r["seed"]) for r in finished}
    failed = [r for r in failed if Cell(r["model"], r["task"], r["size"], r["seed"]) not in names]
    return sorted(finished, key=_order), sorted(failed, key=_order)


def spread(cells: Sequence[Mapping[str, Any]]) -> dict[Key, tuple[float, float | None, int]]:
    """Per (model, task, size): mean error [cm], sample std over seeds (None for one), seeds."""
    errors: dict[Key, list[float]] = defaultdict(list)
    for cell in cells:
        errors[(cell["model"], cell["task"], cell["size"])].append(cell["error_cm"])
    return {key: (statistics.fmean(values),
                  statistics.stdev(values) if len(values) > 1 else None, len(values))
            for key, values in errors.items()}


def failures(cells: Sequence[Mapping[str, Any]]) -> dict[Key, tuple[int, float]]:
    """Per (model, task, size): the trainings above :data:`BOLD_BELOW_CM`, and the worst [cm]."""
    errors: dict[Key, list[float]] = defaultdict(list)
    for cell in cells:
        errors[(cell["model"], cell["task"], cell["size"])].append(cell["error_cm"])
    return {key: (sum(not e < BOLD_BELOW_CM for e in values), max(values))
            for key, values in errors.items()}


def _shown(mean: float, std: float | None) -> str:
    text = f"{mean:.2f}" if std is None else f"{mean:.2f} ± {std:.2f}"
    return f"**{text}**" if mean < BOLD_BELOW_CM else text


def markdown_table(rows: Mapping[str, Mapping[tuple[str, int], str]], tasks: Sequence[str],
                   sizes: Sequence[int]) -> list[str]:
    """A Table II layout: a row per model, ``"<Task> 4 | 20 | 100"`` column groups."""
    header = ["Model"] + [f"{TASK_TITLES[t]} {s}" if k == 0 else str(s)
                          for t in tasks for k, s in enumerate(sizes)]
    lines = ["| " + " | ".join(header) + " |", "|---" + "|---:" * (len(header) - 1) + "|"]
    for model, values in rows.items():
        cells = [values.get((t, s), "—") for t in tasks for s in sizes]
        lines.append(f"| {model_title(model)} | " + " | ".join(cells) + " |")
    return lines


def no_image_reference(settings: ReproduceSimSettings, out: Path,
                       cells: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The no-image reference's error per (task, size, seed) of the cells present."""
    tests: dict[str, Dataset] = {}
    records = []
    for task, size, seed in sorted({(c["task"], c["size"], c["seed"]) for c in cells},
                                   key=lambda k: (ALL_TASKS.index(k[0]), k[1], k[2])):
        train_path = dataset_path(out, task, SeedStream.TRAIN, size, seed)
        test_path = dataset_path(out, task, SeedStream.TEST, settings.test_scenes, settings.seed)
        if not (train_path.is_file() and test_path.is_file()):
            continue  # a folder copied without its datasets: the row is left out
        if task not in tests:
            tests[task] = load_dataset(test_path)
        records.append({"model": NO_IMAGE, "task": task, "size": size, "seed": seed,
                        "error_cm": label_mean_error_cm(load_dataset(train_path), tests[task])})
    return records


def differences_markdown(stats: Mapping[Key, tuple[float, float | None, int]]) -> list[str]:
    """The cells where ours and the paper's differ by more than :data:`RATIO_FLAGGED`."""
    lines = ["| Model | Task | Size | Ours | Paper | Paper / ours | No image | Ours at the "
             "no-image level | Paper above it |", "|---|---|---:|---:|---:|---:|---:|---|---|"]
    for (model, task, size), (mean, _, _) in sorted(
            stats.items(), key=lambda kv: (model_order(kv[0][0]), ALL_TASKS.index(kv[0][1]),
                                           kv[0][2])):
        row = paper_row(model)
        if row is None or task not in PAPER_TABLE2_CM[row]:  # no paper row, a task beyond it
            continue
        paper = PAPER_TABLE2_CM[row][task][SIZES.index(size)]
        ratio = paper / mean
        if 1 / RATIO_FLAGGED <= ratio <= RATIO_FLAGGED:
            continue
        reference = stats.get((NO_IMAGE, task, size))
        level = above = "—"
        if reference is not None:
            level = "yes" if mean > NEAR_NO_IMAGE * reference[0] else "no"
            above = "yes" if paper > reference[0] else "no"
        lines.append(f"| {model_title(model)} | {TASK_TITLES[task]} | {size} | {mean:.2f} | "
                     f"{paper:.2f} | {ratio:.2f} | "
                     f"{'—' if reference is None else f'{reference[0]:.2f}'} | {level} | "
                     f"{above} |")
    return lines if len(lines) > 2 else []


def table2_markdown(cells: Sequence[Mapping[str, Any]], failed: Sequence[Mapping[str, Any]],
                    made_by: str, reference: Sequence[Mapping[str, Any]] = (),
                    scene: str = "paper-sim") -> str:
    """``table2.md``: ours, then the paper's, in the layout of the cells present.

    ``reference`` holds the no-image reference's records (:func:`no_image_reference`); given,
    it makes the last row of our table and the reference column of the differences. On the
    ``yumi`` scene (grasp positions, offline) the paper has no such table: ours alone.
    """
    present = [*cells, *failed]
    models = sorted({c["model"] for c in present}, key=model_order)
    tasks = [t for t in ALL_TASKS if any(c["task"] == t for c in present)]
    sizes = [s for s in SIZES if any(c["size"] == s for c in present)]
    stats, above = spread(cells), failures(cells)
    most = max((n for _, _, n in stats.values()), default=0)
    ours: dict[str, dict[tuple[str, int], str]] = {m: {} for m in models}
    for record in failed:
        ours[record["model"]][(record["task"], record["size"])] = "failed"
    for (model, task, size), (mean, std, n) in stats.items():
        count, worst = above[(model, task, size)]
        ours[model][(task, size)] = _shown(mean, std) + (f" (n={n})" if n < most else "") + (
            f" [{count}/{n} > {BOLD_BELOW_CM:g}, worst {worst:.1f}]" if count and n > 1 else "")
    rows = [row for row in PAPER_MODELS if row in {paper_row(m) for m in models}]
    paper = {m: {(t, s): _shown(PAPER_TABLE2_CM[m][t][SIZES.index(s)], None)
                 if t in PAPER_TABLE2_CM[m] else "—" for t in tasks for s in sizes}
             for m in rows}
    references = spread(reference)
    if references:
        ours[NO_IMAGE] = {(t, s): _shown(mean, std)
                          for (_, t, s), (mean, std, _) in references.items()}
    paper_scene = scene == "paper-sim"
    differences = differences_markdown({**stats, **references}) if paper_scene else []
    test_scenes = {c["test_scenes"] for c in cells} or {"?"}
    title = ("Table II in simulation: mean position error [cm]" if paper_scene else
             f"Offline on the `{scene}` scene: mean grasp position error [cm]")
    lines = [
        f"# {title}", "",
        f"Scene `{scene}`, {'/'.join(str(n) for n in sorted(test_scenes, key=str))} untrained "
        "test scenes per task. Each cell: mean ± sample standard deviation over the training "
        f"seeds ({most} per cell{'' if most == 1 else ', fewer where marked n='}); **bold**: "
        f"below {BOLD_BELOW_CM:g} cm, as in the paper; `[k/n > {BOLD_BELOW_CM:g}, worst w]`: "
        f"k of the cell's n trainings ended above {BOLD_BELOW_CM:g} cm, the worst at w cm (a "
        "mean can hide a failed training). Columns: task, then training set size.",
        "", *markdown_table(ours, tasks, sizes), ""]
    if any(c.get("per_condition_error_cm") or len(c.get("per_target_error_cm") or ()) > 1
           for c in cells):
        lines += ["## Per condition and head, the worst training", "",
                  "Each cell's worst training by its worst condition or head: a Query that "
                  "memorised its images shows here, where the cell's mean hides it.", "",
                  *worst_conditions_markdown(cells), ""]
    if any(c.get("judged") for c in cells):
        lines += ["## Judged as the trials judge a pick", "",
                  "The grasp judge (docs/decisions/grasp-judge.md) on every test target: the "
                  "share it predicts picked, per training seed, then pooled over the seeds and "
                  "per object type, and the 95th percentile of the turn about the approach "
                  "axis [deg] and of the offset along the closing axis [mm], the worst seed's.",
                  "", *judged_markdown(cells), ""]
    if paper_scene:
        lines += ["## The paper's Table II", "",
                  "As published, in the same columns and with the same bold rule.", "",
                  *markdown_table(paper, tasks, sizes), ""]
    if differences:
        lines += [
            f"## Where ours and the paper's differ by more than {RATIO_FLAGGED:g}×", "",
            "Each such cell beside the no-image reference (the training-label mean). \"at the "
            f"no-image level\": our mean is above {NEAR_NO_IMAGE:g} × the reference, so the model "
            "learned where targets tend to be, not where this one is. \"Paper above it\": the "
            "paper's error exceeds what the reference scores on our table.", "",
            *differences, ""]
    lines += [made_by]
    if failed:
        lines += ["", "Failed cells (see `cells/<cell>-error.json`):"]
        lines += [f"- {Cell(r['model'], r['task'], r['size'], r['seed']).name}: {r['error']}"
                  for r in failed]
    return "\n".join(lines) + "\n"


def judged_markdown(cells: Sequence[Mapping[str, Any]]) -> list[str]:
    """Per (model, task, size): the judge's predicted success per seed, pooled, per object."""
    lines = ["| Model | Task | Size | Per seed [%] | Pooled [%] | Per object [%] | Yaw p95 | "
             "Closing p95 |", "|---|---|---:|---|---:|---|---:|---:|"]
    groups: dict[Key, list[Mapping[str, Any]]] = defaultdict(list)
    for cell in cells:
        if cell.get("judged"):
            groups[(cell["model"], cell["task"], cell["size"])].append(cell)
    for (model, task, size), group in groups.items():
        group = sorted(group, key=lambda c: c["seed"])
        alls = [c["judged"]["all"] for c in group]
        pooled = sum(a["predicted_success_rate"] * a["targets"] for a in alls) / sum(
            a["targets"] for a in alls)
        objects: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0])
        for cell in group:
            for name, g in cell["judged"]["per_object"].items():
                objects[name][0] += g["predicted_success_rate"] * g["targets"]
                objects[name][1] += g["targets"]
        per_seed = ", ".join(f"{100 * a['predicted_success_rate']:.0f}" for a in alls)
        per_object = ", ".join(f"{name} {100 * picked / n:.1f}"
                               for name, (picked, n) in sorted(objects.items()))
        yaw = max(a["errors"]["yaw_deg"]["p95"] for a in alls)
        closing = max(a["errors"]["closing_mm"]["p95"] for a in alls)
        lines.append(f"| {model_title(model)} | {TASK_TITLES[task]} | {size} | {per_seed} | "
                     f"{100 * pooled:.1f} | {per_object} | {yaw:.0f} | {closing:.1f} |")
    return lines


def worst_conditions_markdown(cells: Sequence[Mapping[str, Any]]) -> list[str]:
    """Per (model, task, size): the training whose worst condition or head is worst."""
    lines = ["| Model | Task | Size | Worst training | Its mean | Its worst condition / head |",
             "|---|---|---:|---|---:|---|"]
    groups: dict[Key, list[Mapping[str, Any]]] = defaultdict(list)
    for cell in cells:
        groups[(cell["model"], cell["task"], cell["size"])].append(cell)

    def parts(cell: Mapping[str, Any]) -> list[tuple[str, float]]:
        named = list((cell.get("per_condition_error_cm") or {}).items())
        heads = cell.get("per_target_error_cm") or []
        return named + ([(f"head {k}", e) for k, e in enumerate(heads)] if len(heads) > 1
                        else [])

    for (model, task, size), group in groups.items():
        worst = max(group, key=lambda c: max([e for _, e in parts(c)] or [c["error_cm"]]))
        name, error = max(parts(worst) or [("mean", worst["error_cm"])], key=lambda p: p[1])
        lines.append(f"| {model_title(model)} | {TASK_TITLES[task]} | {size} | seed "
                     f"{worst['seed']} | {worst['error_cm']:.2f} | {name} {error:.2f} |")
    return lines


def write_reports(settings: ReproduceSimSettings, out: Path, wall_time_s: float,
                  computed: int, session: dict[str, Any] | None = None
                  ) -> tuple[list[Path], list[dict[str, Any]], list[str]]:
    """Writes every report from the cells present: (paths written, failed cells, notes).

    ``session``: the provenance of the run that writes them (:mod:`harness.provenance`).
    """
    cells, failed = read_cells(out)
    seeds = sorted({c["seed"] for c in cells})
    made_by = (f"Made by `{settings.command(out)}`: training seeds "
               f"{', '.join(str(s) for s in seeds) or '—'}, {settings.steps} optimiser steps "
               f"per phase, test scenes from the test stream of seed {settings.seed}; last run "
               f"{duration(wall_time_s)} wall time, {computed} cell(s) computed, "
               f"{len(cells) + len(failed) - computed} kept from earlier runs.")
    stats, above = spread(cells), failures(cells)
    reference = no_image_reference(settings, out, cells)
    table = {
        "cells": [{k: c.get(k) for k in ("model", "task", "size", "seed", "error_cm",
                                         "per_condition_error_cm", "per_target_error_cm",
                                         "per_stage_error_cm", "judged", "train_s")}
                  for c in cells],
        "means": [{"model": m, "task": t, "size": s, "error_cm": mean, "std_cm": std,
                   "seeds": n, "above_5cm": above[(m, t, s)][0],
                   "worst_cm": above[(m, t, s)][1]}
                  for (m, t, s), (mean, std, n) in stats.items()],
        "no_image_reference": reference,
        "settings": settings.run_identity() | {
            "command": settings.command(out), "models": list(settings.models),
            "tasks": list(settings.tasks), "sizes": list(settings.sizes),
            "seeds": list(settings.training_seeds), "workers": settings.worker_count(),
            "model_configs": {f.model: f.to_json() for f in settings.model_configs}},
        "wall_time_s": wall_time_s, "cells_computed": computed,
        "failed": [{k: r[k] for k in ("model", "task", "size", "seed", "error")}
                   for r in failed],
        "provenance": session,
    }
    paths = [out / "table2.json", out / "table2.md", out / "table2.png"]
    write_json(paths[0], table)
    text = table2_markdown(cells, failed, made_by, reference, settings.scene)
    write_text(paths[1], text)
    above_line = [Cell(c["model"], c["task"], c["size"], c["seed"]).name for c in cells
                  if c["model"] == "kqv" and not c["error_cm"] < BOLD_BELOW_CM]
    notes = [f"WARNING: {len(above_line)} kqv training(s) ended above {BOLD_BELOW_CM:g} cm: "
             f"{', '.join(above_line)}"] if above_line else []
    if cells:
        plot_table2(stats, paths[2], spread(reference))
    else:
        paths.pop()
        notes.append("no finished cell: table2.png not drawn")
    fig5, fig5_notes = draw_fig5(settings, out, cells)
    return paths + fig5, [dict(r) for r in failed], notes + fig5_notes
