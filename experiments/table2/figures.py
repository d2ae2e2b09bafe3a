"""The figures of ``gva reproduce sim``: Table II as a plot, and the paper's Fig. 5.

- ``table2.png``: error against training set size, one line per model, one panel per task.
- ``fig5.png``: like the paper's Fig. 5, the attention points of ``kqv`` (top) and
  ``keypoint-16`` (bottom) on three test images per task, at the largest size of the first seed.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure  # an Agg canvas of its own, no global backend state

from experiments.table2.settings import BOLD_BELOW_CM, SIZES, Key, ReproduceSimSettings
from experiments.tables import (
    ALL_TASKS,
    MODEL_TITLES,
    NO_IMAGE,
    TASK_TITLES,
    model_order,
    model_title,
)
from harness.run_files import dataset_path
from perception.drawing import draw_points, enlarge
from perception.files import atomic_write
from perception.interface import ConditionKind
from perception.learning.data import Dataset
from perception.learning.dataset_file import load_dataset
from perception.registry import load_model
from sim.tasks.scene_sampling import SeedStream

Y_TICKS_CM = (0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 50, 100, 200)
FINE_Y_TICKS_CM = (0.1, 0.15, 0.2, 0.3, 0.5, 0.7, 1, 1.5, 2, 3, 5, 7, 10, 15, 20, 30, 50, 70, 100)
"""Labelled errors on the plot's log axis, plain numbers; the fine ones within a decade."""
FIG5_MODELS = ("kqv", "keypoint-16")
FIG5_IMAGES = 3
FIG5_SCALE = 3  # the image enlarged 3 times before the dots are drawn: legible head numbers
FIG5_TASKS_ACROSS = 2  # task blocks side by side; four tasks make a 2 x 2 grid


def plot_table2(stats: Mapping[Key, tuple[float, float | None, int]], path: Path,
                reference: Mapping[Key, tuple[float, float | None, int]] | None = None) -> None:
    """``table2.png``: error [cm] against training set size (log-log), a panel per task.

    ``reference`` (the no-image reference's spread) is drawn as a dotted black line.
    """
    tasks = [t for t in ALL_TASKS if any(k[1] == t for k in stats)]
    models = sorted({k[0] for k in stats if k[0] != NO_IMAGE}, key=model_order)
    sizes = [s for s in SIZES if any(k[2] == s for k in stats)]
    figure = Figure(figsize=(3.6 * len(tasks) + 1.2, 3.8), layout="constrained")
    axes = figure.subplots(1, len(tasks), sharey=True, squeeze=False)[0]
    for axis, task in zip(axes, tasks, strict=True):
        for number, model in enumerate(models):
            points = [(s, stats[(model, task, s)]) for s in sizes if (model, task, s) in stats]
            if not points:
                continue
            dodge = 1.0 + 0.03 * (number - (len(models) - 1) / 2)  # bars side by side
            axis.errorbar([s * dodge for s, _ in points], [m for _, (m, _, _) in points],
                          yerr=[std or 0.0 for _, (_, std, _) in points], capsize=3,
                          marker="o", color=f"C{number}", label=model_title(model))
        floor = [(s, reference[(NO_IMAGE, task, s)][0]) for s in sizes
                 if reference and (NO_IMAGE, task, s) in reference]
        if floor:
            axis.plot([s for s, _ in floor], [m for _, m in floor], color="black",
                      linestyle=":", linewidth=1.5, label=MODEL_TITLES[NO_IMAGE].lower())
        axis.axhline(BOLD_BELOW_CM, color="grey", linestyle="--", linewidth=1,
                     label=f"{BOLD_BELOW_CM:g} cm (paper's bold)")
        axis.set(xscale="log", yscale="log", title=TASK_TITLES[task],
                 xlabel="training scenes")
        axis.set_xticks(sizes, [str(s) for s in sizes])
        axis.set_xticks([], minor=True)
        axis.grid(True, alpha=0.3)
    low, high = axes[0].get_ylim()
    ticks = [v for v in (Y_TICKS_CM if high / low > 10 else FINE_Y_TICKS_CM) if low <= v <= high]
    axes[0].set_yticks(ticks, [f"{v:g}" for v in ticks])
    axes[0].set_yticks([], minor=True)
    axes[0].set_ylabel("mean position error [cm]")
    handles, labels = axes[0].get_legend_handles_labels()
    figure.legend(handles, labels, loc="outside right center", fontsize="small")
    atomic_write(path, lambda temporary: figure.savefig(temporary, format="png", dpi=110))


def draw_fig5(settings: ReproduceSimSettings, out: Path, cells: Sequence[Mapping[str, Any]]
              ) -> tuple[list[Path], list[str]]:
    """``fig5.png``: attention points of kqv and keypoint-16 on test images; (paths, notes)."""
    chosen: dict[tuple[str, str], Mapping[str, Any]] = {}
    for record in cells:  # the largest size, then the first seed
        key = (record["model"], record["task"])
        if record["model"] in FIG5_MODELS and (key not in chosen or (
                -record["size"], record["seed"]) < (-chosen[key]["size"], chosen[key]["seed"])):
            chosen[key] = record
    models = [m for m in FIG5_MODELS if any(k[0] == m for k in chosen)]
    notes = [f"fig5.png: {m} has no finished cell in this folder; drawn without it"
             for m in FIG5_MODELS if m not in models]
    tasks = [t for t in ALL_TASKS if any(k[1] == t for k in chosen)]
    if not models:
        return [], ["fig5.png not drawn: neither kqv nor keypoint-16 has a finished cell in "
                    "this folder"]
    across = min(FIG5_TASKS_ACROSS, len(tasks))  # task blocks side by side
    down = -(-len(tasks) // across)
    figure = Figure(figsize=(2.3 * FIG5_IMAGES * across, 2.5 * len(models) * down + 0.5),
                    layout="constrained")
    axes = figure.subplots(len(models) * down, FIG5_IMAGES * across, squeeze=False)
    for axis in axes.flat:
        axis.set_axis_off()  # turned on where a panel is drawn
    for number, task in enumerate(tasks):
        block_row, block_column = divmod(number, across)
        test = load_dataset(dataset_path(out, task, SeedStream.TEST, settings.test_scenes,
                                         settings.seed))
        for row, model in enumerate(models):
            if (model, task) in chosen:
                first = block_row * len(models) + row, block_column * FIG5_IMAGES
                _draw_fig5_panels(axes[first[0], first[1]:first[1] + FIG5_IMAGES], test, model,
                                  chosen[(model, task)], out)
        axes[block_row * len(models), block_column * FIG5_IMAGES].set_title(
            TASK_TITLES[task], loc="left", fontsize="large", fontweight="bold")
    figure.suptitle("Attention points on test scenes, numbered by head\nbelow each image: "
                    "its condition (top-down tasks), its mean error")
    path = out / "fig5.png"
    atomic_write(path, lambda temporary: figure.savefig(temporary, format="png", dpi=100))
    return [path], notes


def _draw_fig5_panels(axes: np.ndarray, test: Dataset, model_name: str,
                      cell: Mapping[str, Any], out: Path) -> None:
    """One model's attention points on the first test images of a task, one per axis."""
    count = min(len(axes), len(test))
    predictions = load_model(out / cell["checkpoint"]).predict_samples(test, range(count))
    choices, names = test.metadata.condition_choices, test.condition_names()
    for k, (axis, prediction) in enumerate(zip(axes, predictions, strict=False)):
        image = test.images[k]  # (H, W, 3)
        panel = enlarge(image, image.shape[0] * FIG5_SCALE, image.shape[1] * FIG5_SCALE)
        draw_points(panel, prediction.attention_px, FIG5_SCALE)
        axis.set_axis_on()
        axis.set_xticks([])
        axis.set_yticks([])
        axis.imshow(panel)
        truth = test.labels[k, :, :3]  # (q, 3) [m]
        error_cm = 100 * np.mean([np.linalg.norm(target.position_m - truth[j])
                                  for j, target in enumerate(prediction.targets)])
        given = test.condition(k)
        wanted = "" if not choices else (f'"{given.value}"\n' if given.kind is ConditionKind.TEXT
                                         else f"{names[k]}, ")
        axis.set_xlabel(f"{wanted}{error_cm:.1f} cm")
    axes[0].set_ylabel(f"{model_title(model_name)}\n{cell['size']} scenes, seed {cell['seed']}")
