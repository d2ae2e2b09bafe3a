"""Each head of kqv checkpoints on test scenes, read with the focus and on the whole heatmap.

Issue 75: a ``multiple`` checkpoint's spray-bottle head erred along its approach axis (the ray
readout's learned range), and the inference-only focus moves a bottle's attention point onto
its shoulder. This scores checkpoints head by head on one dataset, both ways, by the grasp
judge: the share predicted picked, the mean of the map's chances, and each error's mean and
worst (position, along the approach axis, across it, yaw)::

    python studies/score_heads.py --data TEST.gva CHECKPOINT [CHECKPOINT ...]

(``gva collect --scene yumi --task multiple --size 30 --seed S --stream test --out TEST.gva``.)
"""

from __future__ import annotations

import argparse
from pathlib import Path

from perception.learning.dataset_file import load_dataset
from perception.learning.evaluate import evaluate
from perception.learning.judged_errors import JudgedGroup
from perception.learning.validation import read_check
from perception.models.kqv import KqvModel
from perception.registry import load_model


def head_line(name: str, group: JudgedGroup) -> str:
    """``head 1 (60): judged 100.0 %, chance 99.6 %; position 1.14/2.42 cm, approach ...``."""
    e = group.errors
    return (f"{name} ({group.targets}): judged {100 * group.predicted_success_rate:.1f} %, "
            f"chance {100 * group.expected_success_rate:.1f} %; position "
            f"{e['position_cm'].mean:.2f}/{e['position_cm'].worst:.2f} cm, approach "
            f"{e['approach_mm'].mean:.1f}/{e['approach_mm'].worst:.1f} mm, across "
            f"{e['across_mm'].mean:.1f}/{e['across_mm'].worst:.1f} mm, yaw "
            f"{e['yaw_deg'].mean:.1f} deg")


def score(checkpoint: Path, data_path: Path) -> list[str]:
    """Lines: the checkpoint's check, then per reading (focus, whole) each head's line."""
    data, model = load_dataset(data_path), load_model(checkpoint)
    if not isinstance(model, KqvModel):
        raise SystemExit(f"{checkpoint} is not a kqv checkpoint")
    check = read_check(checkpoint)
    lines = [f"{checkpoint}: {check.headline() if check else 'no check'}"]
    for reading, read in (("focus", model), ("whole", model.read_with(focus_window_px=0))):
        judged = evaluate(read, data).judged
        if judged is None:
            raise SystemExit(f"{data_path}: no grasp-pose labels to judge")
        heads = judged.per_head or {"all": judged.all}
        lines += [f"  {reading} {head_line(name, group)}" for name, group in heads.items()]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="the test scenes")
    parser.add_argument("checkpoints", type=Path, nargs="+", help="kqv checkpoint folders")
    args = parser.parse_args()
    for checkpoint in args.checkpoints:
        print("\n".join(score(checkpoint, args.data)), flush=True)


if __name__ == "__main__":
    main()
