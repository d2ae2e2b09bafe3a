"""The reports of ``gva reproduce real``, rebuilt from every trial folder of every seed's folder.

``table3.json`` (per model, task and variant: each seed's successes, their mean and spread,
and every seed's trials pooled; each baseline against kqv and each variant against the clean
world, paired on the same trials) and ``table3.md`` (laid out like the paper's Table III, then
intervals, the paired comparisons, held-out checks, failure reasons and GIFs). A trial folder
of an interrupted run counts the trials it has, marked ``*``. What each file holds:
``docs/reproducing.md``.
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence
from collections.abc import Set as AbstractSet
from pathlib import Path
from typing import Any, NamedTuple

from experiments.table3.check_gate import (
    CHECK_FAILED,
    USED_MARK,
    CheckUse,
    FailedChecks,
    check_use,
    checks_markdown,
    failed_checks,
    marks_note,
)
from experiments.table3.folder import history_wall_time_s, read_checks, read_failed, read_gifs
from experiments.table3.layout import seed_folder
from experiments.table3.pairing import PairedSets, baseline_comparisons, variant_comparisons
from experiments.table3.plugins import served_models
from experiments.table3.settings import (
    OPEN_LOOP,
    PLAIN,
    REFERENCE_MODEL,
    ReproduceRealSettings,
    Unit,
)
from experiments.table3.trial_sets import (
    TrialSetResult,
    first_pick_errors_cm,
    read_trial_sets,
    split_task,
    variant_order,
)
from experiments.tables import ALL_TASKS, TASK_TITLES, TASKS, model_order, model_title
from harness.paired_statistics import CONFIDENCE, SIGNIFICANCE
from harness.run_files import write_json, write_text
from harness.run_report import duration
from perception.remote.client import announced_metadata
from sim.tasks.task_spec import TargetSelection
from sim.tasks.task_toml import load_task
from sim.tasks.variants import variant_title
from sim.trials.records import TrialOutcome, TrialRecord
from sim.world.sensor import SensorConfig

PAPER_TABLE3 = {"single": 27, "multiple": 28, "selected-type": 26, "selected-position": 27}
"""The paper's Table III: successful picks of 30 on the real YuMi, 20 demonstrations each."""
PAPER_TRIALS = 30
EXAMPLES = 3
"""Failed trials quoted per row in the failure reasons."""
REASON_CHARS = 200
"""A quoted reason is cut to this length (a planner's reason lists every arm and via pose)."""


def row_title(model: str, variant: str) -> str:
    """The row title of a model under a variant."""
    if variant == PLAIN:
        return model_title(model)
    if variant == OPEN_LOOP:
        return f"{model_title(model)}, open loop (same checkpoint)"
    return f"{model_title(model)}, {variant_title(variant)}"


def has_distractors(result: TrialSetResult) -> bool:
    """Whether some trial of the set presents a distractor."""
    return any(o.get("distractor") for r in result.records for o in r.objects)


def shared_target_type(task: str, record: TrialRecord) -> bool:
    """Whether a distractor has a target's type in the trial.

    Nothing in the image tells such a distractor from the target (a side condition at most).
    """
    distractors = {o["type"] for o in record.objects if o.get("distractor")}
    if load_task(task).targets is TargetSelection.ALL:
        targets = {o["type"] for o in record.objects if not o.get("distractor")}
    else:
        targets = {record.target} if record.target else set()
    return bool(distractors & targets)


def table3_json(sets: Sequence[TrialSetResult]) -> dict[str, Any]:
    """The tables of ``table3.json`` (without settings and timing)."""
    models: dict[str, dict[str, Any]] = {}
    variants: dict[str, dict[str, dict[str, Any]]] = {}
    against_clean: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for paired in variant_comparisons(sets):
        against_clean.setdefault((paired.model, paired.variant, paired.task), []).append(
            paired.entry())
    for result in sets:
        if result.variant == PLAIN:
            models.setdefault(result.model, {})[result.task] = result.entry()
        elif result.variant == OPEN_LOOP:
            models.setdefault(result.model, {})[f"{result.task}-{result.variant}"] = (
                result.entry())
        else:
            entry = result.entry() | {"against_clean": against_clean.get(
                (result.model, result.variant, result.task), [])}
            if has_distractors(result):
                entry["shared_target_type"] = sum(shared_target_type(result.task, r)
                                                  for r in result.records)
            variants.setdefault(result.model, {}).setdefault(result.variant, {})[
                result.task] = entry
    against: dict[str, dict[str, list[dict[str, Any]]]] = {}
    for paired in baseline_comparisons(sets):
        against.setdefault(paired.model, {}).setdefault(paired.task, []).append(paired.entry())
    return {"tasks": models.get(REFERENCE_MODEL, {}), "models": models,
            "variants": {"difference": "variant - plain", "models": variants},
            "against_kqv": {"reference": REFERENCE_MODEL,
                            "difference": f"model - {REFERENCE_MODEL}", "models": against},
            "paper": {t: {"successes": k, "n": PAPER_TRIALS} for t, k in PAPER_TABLE3.items()}}


def _cell(result: TrialSetResult | None, failed: AbstractSet[int] = frozenset()) -> str:
    """``29/30`` for one seed; ``28.6 ± 1.1 (29, 30, 27, 28, 29)`` for several.

    ``failed``: the seeds whose checkpoint failed its check; a seed without trials reads
    ``check failed``, one with trials is marked ``†``.
    """
    if result is None:
        return CHECK_FAILED if failed else "—"
    seeds = {seed for seed, _ in result.per_seed}
    mark = ("*" if result.unfinished else "") + (USED_MARK if seeds & failed else "")
    missing = "".join(f"; seed {seed}: {CHECK_FAILED}" for seed in sorted(failed - seeds))
    if len(result.per_seed) == 1:
        summary = result.summary
        return f"{summary.successes}/{summary.n}{mark}{missing}"
    return (f"{result.mean:.1f} ± {result.std:.1f}{mark} "
            f"({', '.join(str(count) for count in result.counts)}){missing}")


def _interval(result: TrialSetResult | None, failed: AbstractSet[int] = frozenset()) -> str:
    if result is None:
        return CHECK_FAILED if failed else "—"
    low, high = result.summary.wilson95
    errors = first_pick_errors_cm(result.records)
    error = f"; {statistics.median(errors):.1f} cm" if errors else ""
    return f"{100 * low:.0f}-{100 * high:.0f} %{error}"


def _columns(sets: Sequence[TrialSetResult], failed: FailedChecks | None = None
             ) -> tuple[str, ...]:
    """The tables' columns: the paper's tasks, then any task beyond it that was run."""
    run = {s.task for s in sets} | {task for _, task in failed or {}}
    return TASKS + tuple(t for t in ALL_TASKS if t not in TASKS and t in run)


def _header(tasks: Sequence[str]) -> list[str]:
    return ["| | " + " | ".join(TASK_TITLES[t] for t in tasks) + " |",
            "|---" + "|---:" * len(tasks) + "|"]


def _paper(task: str) -> str:
    """The paper's count, or a dash for a task it did not run."""
    return f"{PAPER_TABLE3[task]}/{PAPER_TRIALS}" if task in PAPER_TABLE3 else "—"


def _rows(sets: Sequence[TrialSetResult], failed: FailedChecks | None = None,
          variants: Sequence[str] = (PLAIN,)) -> list[tuple[str, str]]:
    """(model, variant) of each row: plain rows first, models in the paper's order.

    A model whose checkpoint failed its check has a row per variant, trials or not.
    """
    rows = {(s.model, s.variant) for s in sets} | {(m, v) for m, _ in failed or {}
                                                   for v in variants}
    return sorted(rows, key=lambda r: (variant_order(r[1]), model_order(r[0])))


def successes_table(sets: Sequence[TrialSetResult], checks: Sequence[Mapping[str, Any]] = (),
                    variants: Sequence[str] = (PLAIN,)) -> str:
    """The Table III layout: the paper's row, then a row per model and variant, ``k/30``.

    ``checks``: the held-out checks (:func:`failed_checks` marks their cells); ``variants``:
    the run's, for the rows of a model whose only checkpoints failed.
    """
    by_key = {(s.model, s.variant, s.task): s for s in sets}
    failed = failed_checks(checks)
    tasks = _columns(sets, failed)
    lines = [*_header(tasks), "| Paper (real YuMi, 20 demonstrations) | "
             + " | ".join(_paper(t) for t in tasks) + " |"]
    lines += [f"| {row_title(m, v)} | " + " | ".join(
        _cell(by_key.get((m, v, t)), failed.get((m, t), set())) for t in tasks)
        + " |" for m, v in _rows(sets, failed, variants)]
    return "\n".join(lines)


ROBOT_TITLES = {"yumi": "a simulated ABB YuMi", "panda": "a simulated Franka Panda"}
"""How ``table3.md`` names the robot of a run."""


def table3_markdown(sets: Sequence[TrialSetResult], made_by: str,
                    gifs: Mapping[str, Mapping[str, Any]] | None = None,
                    failed: Sequence[Mapping[str, Any]] = (),
                    checks: Sequence[Mapping[str, Any]] = (), *, robot: str,
                    variants: Sequence[str] = (PLAIN,)) -> str:
    """``table3.md``: the paper's row, ours, the variants' rows, then why trials failed."""
    by_key = {(s.model, s.variant, s.task): s for s in sets}
    unchecked = failed_checks(checks)
    columns = _columns(sets, unchecked)
    lines = [
        "# Table III in simulation: successful picks out of 30", "",
        f"Scene `yumi` ({ROBOT_TITLES.get(robot, robot)} in PyBullet): each model trained on "
        "oracle-verified "
        "demonstrations of each task, then pick trials at untrained positions with "
        "the model in the loop. A pick succeeds when the target's lowest point rose 5 cm and "
        "stayed pinched for 1 s; `multiple` needs all three picks. The paper's row is its real "
        "YuMi (20 demonstrations per task). Over several seeds (each moves the "
        "demonstrations, the weights and the test scenes) a cell is the mean ± standard "
        "deviation of the seeds' successes, each seed's count in brackets. `*`: some trials "
        "are still missing (the run was interrupted; run it again); the counts are of those "
        "present.", "",
        successes_table(sets, checks, variants), "", *marks_note(unchecked),
        "95 % Wilson interval of the success rate (every seed's trials pooled); median grasp "
        "position error of the first pick [cm]:", "", *_header(columns)]
    lines += [f"| {row_title(m, v)} | " + " | ".join(
        _interval(by_key.get((m, v, t)), unchecked.get((m, t), set())) for t in columns) + " |"
        for m, v in _rows(sets, unchecked, variants)]
    lines += ["", *comparisons_markdown(baseline_comparisons(sets)),
              *variants_markdown(variant_comparisons(sets)), *checks_markdown(checks),
              "## Failure reasons", ""]
    for task in ALL_TASKS:
        present = [s for s in sets if s.task == task]
        if not present:
            continue
        lines += [f"### {TASK_TITLES[task]}", ""]
        for result in sorted(present, key=lambda s: (variant_order(s.variant),
                                                     model_order(s.model))):
            lines += _reasons(result)
        lines.append("")
    if gifs:
        lines += ["## GIFs", "", "The first trials of each model and task recorded again: the "
                  "head camera's image with the attention points (numbered by head) beside a "
                  "camera watching the robot.", ""]
        lines += [f"- `{name}`: " + ", ".join(f"trial {t['index']} {t['outcome']}"
                                              for t in gif["trials"]) for name, gif in gifs.items()]
        lines.append("")
    lines += ["## How it was made", "", made_by]
    if failed:
        lines += ["", "Failed jobs, and checkpoints not tried for their held-out check "
                  "(see `s<seed>/errors/<job>.json`):"]
        lines += [f"- {r['job']}: {r['error']}" for r in failed]
    return "\n".join(lines) + "\n"


def _reasons(result: TrialSetResult) -> list[str]:
    """The failure-reason lines of one row and task: counts, then example failed trials."""
    summary = result.summary
    counts = ", ".join(f"{outcome} {count}" for outcome, count in summary.outcomes.items()
                       if count)
    objects = ", ".join(f"{name} {c['picked']}/{c['attempted']}"
                        for name, c in summary.per_object.items())
    line = f"- **{row_title(result.model, result.variant)}**: {counts or 'no trials'}"
    line += f"; picks by object: {objects}" if objects else ""
    if result.variant != PLAIN and has_distractors(result):
        shared = sum(shared_target_type(result.task, r) for r in result.records)
        line += f"; a distractor has a target's type in {shared} of {summary.n} trials"
    if summary.judge is not None:
        line += f"; the grasp judge: {summary.judge.line()}"
    lines = [line]
    seeds = len(result.per_seed) > 1
    failures = [r for r in result.records if r.outcome is not TrialOutcome.SUCCESS]
    examples: list[TrialRecord] = []
    for record in failures:  # one of each outcome first, then in trial order
        if record.outcome not in {e.outcome for e in examples}:
            examples.append(record)
    examples += [r for r in failures if r not in examples]
    for record in sorted(examples[:EXAMPLES], key=lambda r: (r.seed, r.index)):
        off = (f", {100 * record.position_error_m:.1f} cm off"
               if record.position_error_m is not None else "")
        reason = record.reason if len(record.reason) <= REASON_CHARS else (
            record.reason[:REASON_CHARS - 3] + "...")
        where = f"seed {record.seed} trial {record.index}" if seeds else f"trial {record.index}"
        given = record.asked or {}
        asked = f', asked "{given.get("value")}"' if given.get("kind") == "text" else ""
        lines.append(f"  - {where} ({record.target or '?'}{off}{asked}): "
                     f"{record.outcome.value}: {reason}")
    return lines


def comparisons_markdown(comparisons: Sequence[PairedSets]) -> list[str]:
    """The section of each baseline against kqv, paired on the same trials; none without one."""
    if not comparisons:
        return []
    by_key = {(c.model, c.seed, c.task): c for c in comparisons}
    rows = sorted({(c.model, c.seed) for c in comparisons},
                  key=lambda row: (model_order(row[0]), row[1]))
    lines = [f"## Baselines against {model_title(REFERENCE_MODEL)}, paired on the same trials",
             "", f"Each baseline's trials against {REFERENCE_MODEL}'s on the same test scenes "
             f"(same seed, same trial index): the difference in success rate, baseline - "
             f"{REFERENCE_MODEL}, with its {100 * CONFIDENCE:.0f} % interval (Newcombe's hybrid "
             "score interval for paired proportions), and the two-sided exact McNemar test's "
             f"p. A negative difference with p < {SIGNIFICANCE:g}: the baseline is significantly "
             "worse (`gva compare`, docs/trials.md). `*`: only the trials both sets have are "
             "paired.", "", *_header(TASKS)]
    lines += [f"| {model_title(model)}, seed {seed} | "
              + " | ".join(by_key[model, seed, t].cell() if (model, seed, t) in by_key else "—"
                           for t in TASKS) + " |" for model, seed in rows]
    return [*lines, ""]


def variants_markdown(comparisons: Sequence[PairedSets]) -> list[str]:
    """The section of each model under each variant against its clean trials; none without."""
    if not comparisons:
        return []
    by_key = {(c.model, c.variant, c.seed, c.task): c for c in comparisons}
    rows = sorted({(c.model, c.variant, c.seed) for c in comparisons},
                  key=lambda row: (model_order(row[0]), variant_order(row[1]), row[2]))
    lines = ["## Each variant against the clean world, paired on the same trials", "",
             "Each model's trials under a variant against its own trials in the world it was "
             "trained in, on the same test scenes (same seed, same trial index): the "
             f"difference in success rate, variant - clean, with its {100 * CONFIDENCE:.0f} % "
             "interval and the exact McNemar test's p (`gva compare`). `*`: only the trials "
             "both sets have are paired.", "", *_header(TASKS)]
    lines += [f"| {row_title(model, variant)}, seed {seed} | "
              + " | ".join(by_key[model, variant, seed, t].cell()
                           if (model, variant, seed, t) in by_key else "—" for t in TASKS)
              + " |" for model, variant, seed in rows]
    return [*lines, ""]


class Reports(NamedTuple):
    """What :func:`write_reports` wrote and found."""

    paths: list[Path]  # table3.json, table3.md and the GIFs
    failed: list[dict[str, Any]]  # jobs that raised, checkpoints not tried: job, error
    notes: list[str]
    table: str  # the successes table, as in table3.md


def write_reports(settings: ReproduceRealSettings, out: Path, wall_time_s: float,
                  session: dict[str, Any] | None = None) -> Reports:
    """Writes ``table3.json`` and ``table3.md`` from what the folder holds.

    ``session``: the provenance of the run that writes them (:mod:`harness.provenance`).
    """
    seeds = list(settings.training_seeds)
    sets = read_trial_sets(out, seeds, settings.n)
    gifs, failed = read_gifs(out, seeds), read_failed(out, seeds)
    checks = [check | {"cells": check_use(settings, seed_folder(out, check["seed"]),
                                          Unit(check["model"], check["task"])).value}
              for check in read_checks(out, seeds)]
    variants = tuple(dict.fromkeys(split_task(s.task_name)[1] for s in settings.trial_sets()))
    all_runs_s = history_wall_time_s(out)
    named = (f"seed {seeds[0]}" if len(seeds) == 1 else
             f"seeds {seeds[0]}-{seeds[-1]}, each its own")
    turns = "in turn" if settings.balance_types else "at random"
    made_by = (f"Made by `{settings.command(out)}`: {settings.demos} demonstrations per task "
               f"(training stream of {named}), {settings.steps} optimiser steps, "
               f"{settings.n} trials per task (test stream of the same seed), the "
               f"demonstrations' object types {turns} where a scene draws one type, seen "
               f"through the {settings.sensor.value} sensor, {settings.worker_count()} worker "
               "process(es). Last run: "
               f"{duration(wall_time_s)} wall time; every run into this folder together: "
               f"{duration(all_runs_s)}.")
    served = served_models(settings.models)
    if plugins := settings.plugins():  # tried as they are: no demonstrations, no training
        made_by += (" Plug-ins, untrained, on the same test scenes: " + ", ".join(
            f"`{plugin}`" + (f" (served at {served[plugin]})" if plugin in served else "")
            for plugin in plugins) + ".")
    table = {"seeds": seeds} | table3_json(sets) | {
        "gifs": gifs,
        "settings": settings.shared_identity() | {
            "command": settings.command(out), "models": list(settings.models),
            "tasks": list(settings.tasks), "variants": list(settings.variants),
            "balance_types": settings.balance_types,
            "use_failed_checkpoints": settings.use_failed_checkpoints,
            "sensor": SensorConfig(settings.sensor).to_json(), "workers": settings.worker_count(),
            "model_configs": {f.model: f.to_json() for f in settings.model_configs}} | (
                {"plugins": list(plugins)} if plugins else {}) | (
                {"served": {row: {"url": url, "announced": dict(announced_metadata(url))}
                            for row, url in served.items()}} if served else {}),
        "wall_time_s": wall_time_s, "wall_time_all_runs_s": all_runs_s, "failed": failed,
        "checks": checks, "provenance": session}
    paths = [out / "table3.json", out / "table3.md"]
    write_json(paths[0], table)
    text = table3_markdown(sets, made_by, gifs, failed, checks, robot=settings.robot,
                           variants=variants)
    write_text(paths[1], text)
    notes = [] if sets else ["no trials in this folder yet: the tables are empty"]
    notes += [f"WARNING: {c['model']} {c['task']} seed {c['seed']} failed its held-out check: "
              f"{c['reason']}" for c in checks if c["cells"] == CheckUse.USED.value]
    return Reports(paths + [out / name for name in gifs], failed, notes,
                   successes_table(sets, checks, variants))
