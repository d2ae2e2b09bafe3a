"""The look-alike block's pull on ``kqv``'s attention, before and after the focus (issue 49).

    python studies/attention_focus_figure.py --model RUN/s11/checkpoints/kqv/single \
        --data TESTS/d435/s11/datasets/single-distractor-test-30-s11.gva [--count 3] \
        [--min-error-cm 2] [--out docs/figures/distractor_focus.png]

(RUN: a ``gva reproduce real`` folder; TESTS: ``check_distractor_offline.py``'s cached test
scenes, ``runs/distractor-offline/test-scenes``.)

For the first ``--count`` scenes of the dataset where the whole heatmap's attention point puts
the grasp more than ``--min-error-cm`` off the target (the failure the figure explains), one
figure each, two rows: row 0 reads the whole heatmap (``focus_window_px = 0``, the paper and
gva before issue 49), row 1 the heatmap focused on its densest part (the checkpoint's own
setting, ``KqvConfig.focus_window_px``). The caption states each row's grasp error. The same
network weights serve both rows; only the reading of the heatmap differs.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from perception.drawing import BACKGROUND, GAP_PX, AttentionRow, attention_figure, write_png
from perception.learning.dataset_file import load_dataset
from perception.models.kqv import KqvModel
from perception.registry import load_model


def main(argv: Sequence[str] | None = None) -> int:
    """Draws the figure: a two-row attention figure per chosen scene, stacked."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    parser.add_argument("--model", type=Path, required=True, help="a kqv checkpoint folder")
    parser.add_argument("--data", type=Path, required=True, help="a dataset with the block")
    parser.add_argument("--count", type=int, default=3, help="scenes drawn (3)")
    parser.add_argument("--scale", type=int, default=2, help="image enlarged this many times (2)")
    parser.add_argument("--min-error-cm", type=float, default=2.0,
                        help="draw scenes whose whole-heatmap grasp is this far off (2.0)")
    parser.add_argument("--out", type=Path, default=Path("docs/figures/distractor_focus.png"))
    args = parser.parse_args(argv)
    focused = load_model(args.model)
    if not isinstance(focused, KqvModel):
        parser.error(f"argument --model: {str(args.model)!r} is not allowed: a kqv checkpoint "
                     f"(it holds {focused.name})")
    dataset = load_dataset(args.data)
    focused.spec.check_dataset(dataset)
    models = (focused.read_with(focus_window_px=0), focused)
    figures: list[np.ndarray] = []
    for index in range(len(dataset)):
        image, condition = dataset.images[index:index + 1], dataset.conditions[index:index + 1]
        truth = dataset.labels[index, 0, :3]
        predictions = [m.predict_batch(image, condition)[0] for m in models]
        errors_cm = [100 * float(np.linalg.norm(p.targets[0].position_m - truth))
                     for p in predictions]
        if errors_cm[0] <= args.min_error_cm:
            continue
        rows = [AttentionRow(p.attention_px, p.heatmaps, label=r)
                for r, p in enumerate(predictions)]
        figures.append(attention_figure(image[0], rows, args.scale, caption=[
            f"test scene {index}: row 0 whole heatmap, grasp {errors_cm[0]:.1f} cm off; "
            f"row 1 focused, {errors_cm[1]:.1f} cm off"]))
        if len(figures) == args.count:
            break
    if not figures:
        print(f"no scene of {args.data} puts the whole-heatmap grasp more than "
              f"{args.min_error_cm} cm off")
        return 1
    width = max(f.shape[1] for f in figures)
    stacked = np.full((sum(f.shape[0] + GAP_PX for f in figures), width, 3), BACKGROUND,
                      dtype=np.uint8)
    top = 0
    for figure in figures:
        stacked[top:top + figure.shape[0], :figure.shape[1]] = figure
        top += figure.shape[0] + GAP_PX
    print(f"wrote {write_png(args.out, stacked)} ({len(figures)} scene(s))")
    return 0


if __name__ == "__main__":
    sys.exit(main())
