"""Pick trials of a barely trained model with the planning budget and without it (issue 65).

    python benchmarks/bench_plan_budget.py [--task multiple] [--n 10] [--steps 3]
        [--checkpoint FOLDER] [--out benchmarks/results/plan_budget.json]

A model trained for a few steps predicts grasps the planner cannot plan, and without a budget
the planner searches every grasp, arm and IK solution for each (issue 65: 5.5-6 s a trial
against 0.3-0.5 s). This trains a ``kqv`` checkpoint for ``--steps`` steps on ``--demos``
demonstrations (``gva collect`` + ``gva train``; or reuses ``--checkpoint``), runs the same
``--n`` trials with the default :class:`~control.pick.PlanBudget` and with none
(``PickPlannerConfig(budget=None)``), one of each in turn so both see the same load, and
prints the median wall time per trial of each. A trial's record may differ only where the
budget stopped a search that found no plan; the JSON lists every trial whose records differ
beyond their wall time. ``multiple`` by default: its weak grasps are the ones no arm reaches
(a single target's, at 3 steps, mostly plan and miss). About 3 minutes on the 2-core machine.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import statistics
import tempfile
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

from results_file import add_out_option, write_record

from control.pick import PickPlannerConfig, PlanBudget
from experiments.cli import main as gva
from harness.inputs.trial_settings import TrialSettings, load_trial_model
from sim.trials.planner_setup import make_planner
from sim.trials.trial_models import torch_threads
from sim.trials.trial_runner import TrialRunner
from sim.trials.trial_scenes import trial_scene

WALL_FIELDS = ("wall_time_s",)
"""The fields of a trial record that are wall time, and may differ between two runs."""


def weak_checkpoint(folder: Path, task: str, demos: int, steps: int, seed: int) -> Path:
    """A ``kqv`` checkpoint trained ``steps`` steps on ``demos`` demonstrations of ``task``."""
    data, out = folder / "demos.gva", folder / "kqv"
    if gva(["collect", "--scene", "yumi", "--task", task, "--size", str(demos), "--seed",
            str(seed), "--out", str(data), "--no-progress"]) != 0:
        raise SystemExit("gva collect failed")
    if gva(["train", "--model", "kqv", "--data", str(data), "--out", str(out), "--steps",
            str(steps), "--batch-size", "2", "--threads", "1", "--holdout", "0", "--seed",
            str(seed), "--no-progress"]) != 0:
        raise SystemExit("gva train failed")
    return out


def differences(first: dict[str, Any], second: dict[str, Any]) -> list[str]:
    """The fields, wall time aside, in which two trial records differ."""
    return sorted(k for k in first.keys() | second.keys()
                  if k not in WALL_FIELDS and first.get(k) != second.get(k))


def run(checkpoint: Path, task: str, n: int, seed: int) -> dict[str, Any]:
    """The ``n`` trials with the default budget and without one, in turn; their records."""
    settings = TrialSettings(str(checkpoint), task, n, seed)
    model = load_trial_model(settings)
    configs = {"budget": PickPlannerConfig(), "no_budget": PickPlannerConfig(budget=None)}
    records: dict[str, list[dict[str, Any]]] = {name: [] for name in configs}
    with contextlib.ExitStack() as stack:
        stack.enter_context(torch_threads(1))
        runners = {name: stack.enter_context(TrialRunner(
            settings.task_spec, model.factory, settings.settle_s, settings.execution,
            planner=make_planner(settings.description(), config),
            robot=settings.description())) for name, config in
            configs.items()}
        for index in range(n):
            for name, runner in runners.items():
                scene = trial_scene(runner.task, seed, index)
                record = runner.run(scene, index, seed, str(checkpoint))
                records[name].append(json.loads(record.to_json()))
                print(f"trial {index} {name}: {record.outcome.value}, "
                      f"{record.wall_time_s:.2f} s", flush=True)
    return records


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="multiple")
    parser.add_argument("--n", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0, help="seeds the demos, training, trials")
    parser.add_argument("--demos", type=int, default=2)
    parser.add_argument("--steps", type=int, default=3)
    parser.add_argument("--checkpoint", type=Path, help="reuse this checkpoint, train none")
    add_out_option(parser, "plan_budget")
    args = parser.parse_args()

    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        checkpoint = args.checkpoint or weak_checkpoint(Path(folder), args.task, args.demos,
                                                        args.steps, args.seed)
        records = run(checkpoint, args.task, args.n, args.seed)
    medians = {name: round(statistics.median(r["wall_time_s"] for r in rows), 3)
               for name, rows in records.items()}
    changed = [{"index": a["index"], "fields": differences(a, b),
                "budget": {"outcome": a["outcome"], "reason": a["reason"][:160]},
                "no_budget": {"outcome": b["outcome"], "reason": b["reason"][:160]}}
               for a, b in zip(records["budget"], records["no_budget"], strict=True)
               if differences(a, b)]
    result = {
        "machine": {"cpu_count": os.cpu_count(), "python": platform.python_version(),
                    "processor": platform.processor() or platform.machine()},
        "task": args.task, "n": args.n, "seed": args.seed,
        "model": "reused checkpoint" if args.checkpoint else
                 f"kqv, {args.steps} steps on {args.demos} demonstrations",
        "budget": asdict(PlanBudget()),
        "median_trial_wall_s": medians,
        "mean_trial_wall_s": {name: round(statistics.mean(r["wall_time_s"] for r in rows), 3)
                              for name, rows in records.items()},
        "outcomes": {name: [r["outcome"] for r in rows] for name, rows in records.items()},
        "trials_that_differ": changed,
        "planned_alike": all(c["no_budget"]["outcome"] in ("ik_unreachable", "plan_collision")
                             for c in changed),
        "bench_wall_s": round(time.perf_counter() - started, 1),
        "load_average_1_5_15min": [round(v, 2) for v in os.getloadavg()],
    }
    print(f"median wall time per trial: {medians['budget']} s with the budget, "
          f"{medians['no_budget']} s without ({args.n} trials each, {args.task})")
    print(f"trials whose records differ beyond wall time: {len(changed)} "
          f"(each a search without a plan: {result['planned_alike']})")
    write_record(args.out, result)


if __name__ == "__main__":
    main()
