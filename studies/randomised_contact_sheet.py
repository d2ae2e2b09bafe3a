"""A contact sheet of scenes that teach shape: randomised looks, labelled by the catalog.

One row per task, one column per training scene, each image as the dataset holds it (128 x
128 through the D435) with each target's labelled grasp marked (a dot where the grasp is, its
projection through the dataset's camera). The scenes are collected as ``gva collect --labels
catalog --looks randomised`` collects them (a few seconds). Writes
``docs/figures/randomised_scenes.png``::

    python studies/randomised_contact_sheet.py --scenes 8 --seed 0
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from variant_contact_sheet import save_sheet, show  # studies/, beside this script

from harness.inputs.collector import CollectSettings, LabelSource, LookSource, collect

OUT = Path(__file__).resolve().parents[1] / "docs" / "figures" / "randomised_scenes.png"
TASKS = ("single", "multiple", "selected-type", "selected-position")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    figure, axes = plt.subplots(len(TASKS), args.scenes,
                                figsize=(1.5 * args.scenes, 1.6 * len(TASKS)))
    with tempfile.TemporaryDirectory() as folder:
        for row, task in enumerate(TASKS):
            data = collect(CollectSettings("yumi", task, args.scenes, seed=args.seed,
                                           every_condition=False, labels=LabelSource.CATALOG,
                                           looks=LookSource.RANDOMISED),
                           Path(folder) / f"{task}.gva", progress=False)
            firsts = [n for n, record in enumerate(data.scenes) if "taken" not in record]
            for column, sample in enumerate(firsts[:args.scenes]):
                axis = axes[row][column]
                show(axis, data.images[sample], data.metadata.task if column == 0 else None)
                camera = data.camera(sample)
                assert camera is not None  # a yumi dataset records its camera
                uv = camera.project(data.labels[sample][:, :3])
                axis.plot(uv[:, 0], uv[:, 1], "o", ms=3, mfc="white", mec="black", mew=0.6)
    save_sheet(figure, f"training scenes 0-{args.scenes - 1} of seed {args.seed}, randomised "
               "looks, through the D435; dots: the catalog's grasp labels", args.out, dpi=80)


if __name__ == "__main__":
    main()
