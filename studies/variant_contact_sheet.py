"""A contact sheet of the built-in variants: what each looks like through the D435.

One row per variant (today's world first), one column per test scene of a task (the same
scenes in every row: looks and distractors have seed streams of their own), each image as a
model gets it (128 x 128, the head camera's D435 crop). Writes ``docs/figures/variants.png``::

    python studies/variant_contact_sheet.py --task multiple --scenes 5 --seed 0
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from sim.tasks.scene_picture import render_scene
from sim.tasks.scene_sampling import SeedStream, sample_scene
from sim.tasks.scene_specs import YUMI_SCENE
from sim.tasks.task_toml import load_task
from sim.tasks.variants import builtin_variants, variant_title, with_variant
from sim.world.sensor import SensorConfig, SensorKind

OUT = Path(__file__).resolve().parents[1] / "docs" / "figures" / "variants.png"


def show(axis: Any, image: Any, row_title: str | None = None) -> None:
    """One cell of a contact sheet: the image, no ticks, the row's title left of its first."""
    axis.imshow(image, interpolation="nearest")
    axis.set_xticks([])
    axis.set_yticks([])
    if row_title is not None:
        axis.set_ylabel(row_title, rotation=0, ha="right", va="center", fontsize=8)


def save_sheet(figure: Any, title: str, out: Path, dpi: int) -> None:
    """A contact sheet titled and written to ``out`` (its folder made)."""
    figure.suptitle(title, fontsize=9)
    figure.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out, dpi=dpi)
    print(f"wrote {out}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="multiple")
    parser.add_argument("--scenes", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    base = dataclasses.replace(load_task(args.task), camera=SensorConfig(SensorKind.D435))
    rows = [("today's world", base)] + [
        (f"{name}: {variant_title(name)}", with_variant(base, name)) for name in builtin_variants()]
    figure, axes = plt.subplots(len(rows), args.scenes,
                                figsize=(1.6 * args.scenes, 1.7 * len(rows)))
    for row, (title, task) in enumerate(rows):
        for column in range(args.scenes):
            scene = sample_scene(task, YUMI_SCENE, args.seed, SeedStream.TEST, column)
            show(axes[row][column], render_scene(scene, task), title if column == 0 else None)
    save_sheet(figure, f"{args.task}, test scenes 0-{args.scenes - 1} of seed {args.seed}, "
               "through the D435", args.out, dpi=90)


if __name__ == "__main__":
    main()
