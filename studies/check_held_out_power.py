"""What a run's held-out checks saw of each head, beside what the head does on test scenes.

Issue 75: a ``multiple`` checkpoint whose spray-bottle head was judged picked 55 % on 30 test
scenes passed its check, which saw 4 held-out scenes (3 of 4 judged picked against a 75 %
floor). This reads, for each checkpoint of a ``gva reproduce real`` folder, the held-out
scenes its training held out (re-split exactly as the training split them, and checked against
its ``check.json``), and scores each head there two ways: the share of targets the grasp judge
predicts picked (what the check reads) and the mean of the judge's calibrated probabilities
(smoother where targets are near misses); with ``--test TASK=FILE`` also on test scenes::

    python studies/check_held_out_power.py runs/vt --seeds 0-4 --tasks multiple
        [--test multiple=test-multiple-s{seed}.gva]

One line per checkpoint and head: ``held-out share / mean p (targets); test share / mean p``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from perception.learning.dataset_file import load_dataset
from perception.learning.evaluate import predict_dataset
from perception.learning.judged_errors import judge_predictions
from perception.learning.validation import CheckConfig, split_scenes
from perception.registry import load_model


def per_head(model: object, data: object) -> dict[str, tuple[float, float, int]]:
    """Per head, else per condition value: (share judged picked, mean probability, targets)."""
    judged = judge_predictions(predict_dataset(model, data), data)  # type: ignore[arg-type]
    if judged is None:
        raise SystemExit("no grasp-pose labels to judge")
    parts = judged.per_head or judged.per_condition or {"all": judged.all}  # as the check
    return {name: (g.predicted_success_rate, g.mean_probability, g.targets)
            for name, g in parts.items()}


def seeds_of(text: str) -> list[int]:
    """``0-4`` or ``0,2,5``."""
    if "-" in text:
        low, high = text.split("-")
        return list(range(int(low), int(high) + 1))
    return [int(s) for s in text.split(",")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a gva reproduce real folder")
    parser.add_argument("--seeds", default="0", help="seeds, e.g. 0-4")
    parser.add_argument("--tasks", default="multiple", help="comma-separated tasks")
    parser.add_argument("--model", default="kqv", help="the model's folder name")
    parser.add_argument("--test", action="append", default=[],
                        help="TASK=FILE: a test set per task; {seed} is the seed")
    args = parser.parse_args()
    tests = dict(item.split("=", 1) for item in args.test)
    holdout = CheckConfig().holdout
    for seed in seeds_of(args.seeds):
        for task in args.tasks.split(","):
            folder = args.run / f"s{seed}"
            checkpoint = folder / "checkpoints" / args.model / task
            data = load_dataset(next((folder / "datasets").glob(f"{task}-train-*.gva")))
            held = split_scenes(data, holdout, seed)[1]
            recorded = json.loads((checkpoint / "check.json").read_text())
            assert held is not None and sorted(set(held.scene_keys())) == \
                recorded["held_out_scenes"], "the split is not the training's"
            model = load_model(checkpoint)
            seen = per_head(model, held)
            test = per_head(model, load_dataset(tests[task].format(seed=seed))) \
                if task in tests else {}
            for head, (share, p, n) in seen.items():
                line = f"s{seed} {task} {head}: held-out {100 * share:.0f} % / {p:.2f} ({n})"
                if head in test:
                    t_share, t_p, t_n = test[head]
                    line += f"; test {100 * t_share:.1f} % / {t_p:.3f} ({t_n})"
                print(line + ("" if recorded["passed"] else "  [check failed]"), flush=True)


if __name__ == "__main__":
    main()
