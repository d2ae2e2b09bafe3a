"""What `kqv`'s type head buys in picks: a Table III run's trials again, the stated types dropped.

    python studies/check_type_head_picks.py --run runs/t3h --seeds 0 1 2 3 4 \
        [--model kqv] [--tasks single multiple selected-position] [--workers 2] \
        [--out benchmarks/results/type_head_picks.json]

The type head names the object type each head attends to, and a pick's grip follows it (the
catalog grasp's opening and pre-grasp distance); without a type the trial takes the default
grip. Its removal leaves the offline error unchanged to the last digit (the ablation's
``minus-type-head`` row: it trains after the pose on the frozen network), so only picks can
say what it is worth. Each trial here is the run's own trial (same checkpoint, task file,
seed, scene and settings) with the model's prediction passed through unchanged but for
``object_type``, and is paired with the run's record of that trial: McNemar's exact test
and Newcombe's interval pooled over the seeds, per task. ``selected-type`` is left out: its
condition names the type, and the head is off there.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from results_file import add_out_option, write_record

from harness.inputs.trial_settings import TrialSettings, load_trial_model
from harness.paired_statistics import PairedCounts, mcnemar_exact_p, newcombe_paired_interval
from harness.run_folder import PROVENANCE_KEY, differences, json_form
from perception.interface import NO_CONDITION, Condition, Prediction, RgbdFrame
from sim.trials.records import RECORD_FORMAT_VERSION
from sim.trials.trial_runner import TrialRunner
from sim.trials.trial_scenes import trial_scene

TASKS = ("single", "multiple", "selected-position")


class Untyped:
    """A loaded model whose predictions name no object type: every pick takes the default grip."""

    def __init__(self, model: Any) -> None:
        self._model = model

    def __getattr__(self, name: str) -> Any:
        return getattr(self._model, name)

    def predict_frame(self, frame: RgbdFrame, condition: Condition = NO_CONDITION) -> Prediction:
        """The model's prediction with each target's ``object_type`` left out."""
        return self._model.predict_frame(frame, condition).without_types()


@dataclass(frozen=True)
class RunSet:
    """A trial set of the run as it ran.

    Args:
        stored: Its ``run.json``, provenance left out.
        successes: Each trial's success, by index.

    """

    stored: dict[str, Any]
    successes: dict[int, bool]


def run_set_record(run: Path, seed: int, model: str, task: str) -> RunSet:
    """The run's record of one trial set."""
    folder = run / f"s{seed}" / "trials" / model / task
    successes = {}
    for line in (folder / "trials.jsonl").read_text().splitlines():
        record = json.loads(line)
        successes[record["index"]] = record["outcome"] == "success"
    stored = json.loads((folder / "run.json").read_text())
    stored.pop(PROVENANCE_KEY, None)
    return RunSet(stored, successes)


def run_set(run: Path, seed: int, model: str, task: str, keep_types: bool = False
            ) -> dict[str, Any]:
    """One trial set of the run again, untyped; its per-trial successes beside the run's.

    ``keep_types``: replay the trials as they ran (a check that the replay is the run's).
    """
    ran = run_set_record(run, seed, model, task)
    typed = ran.successes
    settings = TrialSettings(model=str(run / f"s{seed}" / "checkpoints" / model / task),
                             task=str(run / f"s{seed}" / "tasks" / f"{task}.toml"),
                             n=len(typed), seed=seed, robot=ran.stored.get("robot", "yumi"))
    differ = differences(ran.stored, {"format_version": RECORD_FORMAT_VERSION,
                                      **json_form(settings.identity())})
    if differ:  # the replay must be the run's trials but for the types (an open loop)
        raise SystemExit(f"{run}/s{seed} {model}/{task}: the run's trials differ from a replay "
                         f"in {', '.join(differ)}; check out the run's commit")
    loaded = load_trial_model(settings)
    built = loaded.factory(None, None)  # type: ignore[arg-type]  # a loaded checkpoint
    untyped: Any = built if keep_types else Untyped(built)
    started = time.perf_counter()
    successes = {}
    with TrialRunner(settings.task_spec, lambda world, camera: untyped, settings.settle_s,
                     settings.execution, obstacles=settings.obstacles,
                     robot=settings.description()) as runner:
        for index in sorted(typed):
            record = runner.run(trial_scene(settings.task_spec, seed, index), index, seed,
                                f"{model}-untyped")
            successes[index] = record.success
    return {"seed": seed, "task": task, "typed": [typed[i] for i in sorted(typed)],
            "untyped": [successes[i] for i in sorted(typed)],
            "wall_s": round(time.perf_counter() - started, 1)}


def _run_set(job: tuple[Path, int, str, str, bool]) -> dict[str, Any]:
    return run_set(*job)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, required=True, help="a gva reproduce real folder")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--model", default="kqv")
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--keep-types", action="store_true",
                        help="replay with the types stated: must equal the run's records")
    add_out_option(parser, "type_head_picks")
    args = parser.parse_args(argv)
    jobs = [(args.run, seed, args.model, task, args.keep_types)
            for task in args.tasks for seed in args.seeds]
    if args.workers == 1:
        sets = [_run_set(job) for job in jobs]
    else:  # spawned, not forked: a fork of a process that has run torch can hang in its pool
        with ProcessPoolExecutor(args.workers, mp_context=get_context("spawn")) as pool:
            sets = list(pool.map(_run_set, jobs))
    for s in sets:
        print(f"{s['task']} seed {s['seed']}: typed {sum(s['typed'])}/{len(s['typed'])}, "
              f"untyped {sum(s['untyped'])}/{len(s['untyped'])} ({s['wall_s']} s)")
    pooled = []
    for task in args.tasks:
        typed = [x for s in sets if s["task"] == task for x in s["typed"]]
        untyped = [x for s in sets if s["task"] == task for x in s["untyped"]]
        counts = PairedCounts.of(typed, untyped)
        interval = newcombe_paired_interval(counts)
        p = mcnemar_exact_p(counts)
        pooled.append({"task": task, "n": counts.n, "typed": counts.successes_a,
                       "untyped": counts.successes_b, "pairs": counts.to_dict(),
                       "untyped_minus_typed_pct": round(100 * (counts.successes_b
                                                               - counts.successes_a) / counts.n, 1),
                       "interval_pct": [round(100 * interval.low, 1),
                                        round(100 * interval.high, 1)],
                       "mcnemar_p": p})
        print(f"{task}, seeds {args.seeds}: typed {counts.successes_a}/{counts.n}, untyped "
              f"{counts.successes_b}/{counts.n}; untyped - typed "
              f"{pooled[-1]['untyped_minus_typed_pct']:+.1f} % "
              f"({pooled[-1]['interval_pct'][0]:+.1f} to {pooled[-1]['interval_pct'][1]:+.1f}), "
              f"exact McNemar p = {p:.2g}")
    result = {"machine": {"cpu_count": os.cpu_count(), "python": platform.python_version(),
                          "processor": platform.processor() or platform.machine()},
              "run": str(args.run), "model": args.model, "seeds": args.seeds,
              "pooled": pooled, "sets": sets}
    write_record(args.out, result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
