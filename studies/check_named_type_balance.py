"""Checkpoints scored on one dataset per named type: pick images and approach images apart.

Issue 66 asked why ``selected-type-moved``'s checkpoints failed their held-out check on the
spray bottle; this scores checkpoints trained on demonstrations that named the types at random
and in turn on the same TEST scenes: per named type, the mean grasp position and turn error and
the share the grasp judge predicts picked (docs/decisions/closed-loop.md, "The spray bottle").

    python studies/check_named_type_balance.py --data TEST.gva CHECKPOINT [CHECKPOINT ...]

``--whole-heatmap`` reads each ``kqv`` checkpoint on its whole heatmap, as it was trained,
instead of its inference-only focus (``KqvModel.read_with(focus_window_px=0)``): the spray
bottle that checkpoints failed on sat where the focus moved the attention point (issue 66).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from perception.learning.dataset_file import load_dataset
from perception.learning.evaluate import evaluate
from perception.models.kqv import KqvModel
from perception.registry import load_model

STAGES = ("pick", "approach")
"""A demonstration's image before its pick, and those along its approach (``--approach-hz``)."""


def score(checkpoint: Path, data_path: Path, whole_heatmap: bool = False) -> list[str]:
    """Lines: per stage and named type, ``mean cm / mean deg / judged %`` of ``checkpoint``."""
    data, model = load_dataset(data_path), load_model(checkpoint)
    if whole_heatmap:
        if not isinstance(model, KqvModel):
            raise SystemExit(f"--whole-heatmap: {checkpoint} is not a kqv checkpoint")
        model = model.read_with(focus_window_px=0)
    lines = []
    for stage in STAGES:
        for named in data.metadata.condition_choices:
            picked = [i for i, record in enumerate(data.scenes)
                      if record.get("stage", "pick") == stage
                      and record["condition"]["value"] == named]
            if not picked:
                continue
            result = evaluate(model, data.subset(picked))
            position = np.nanmean(np.array(result.position_errors_cm, dtype=float))
            turn = np.nanmean(np.array(result.angle_errors_deg, dtype=float))
            judged = result.judged.all.predicted_success_rate if result.judged else float("nan")
            lines.append(f"{checkpoint} {stage} {named} ({len(picked)} images): "
                         f"{position:.2f} cm, {turn:.1f} deg, judged picked {100 * judged:.0f} %")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="the dataset every "
                        "checkpoint is scored on (gva collect --stream test --approach-hz 10)")
    parser.add_argument("checkpoints", type=Path, nargs="+", help="checkpoint folders")
    parser.add_argument("--whole-heatmap", action="store_true",
                        help="read kqv checkpoints on the whole heatmap, without the focus")
    args = parser.parse_args()
    for checkpoint in args.checkpoints:
        print("\n".join(score(checkpoint, args.data, args.whole_heatmap)))


if __name__ == "__main__":
    main()
