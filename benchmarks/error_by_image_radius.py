"""Grasp position error against the target's distance from the image centre (issue 48's figure).

    python benchmarks/error_by_image_radius.py runs/t3d-s10 runs/t3f-s10 \
        [--models kqv,kqv-mlp] [--out benchmarks/results/error_by_image_radius.json] \
        [--figure docs/figures/error_by_image_radius.png]

The paper's real misses came from "a strong distortion of the camera lenses, especially when
placed at the edge of the environment". Each pick of every ``gva reproduce real`` trial in the
given run folders (every seed, the plain task only) gives its grasp's position error and where
the head camera's calibration sees the target's true grasp point: the radius is the distance
from the image centre over the half-diagonal (0 at the centre, 1 at a corner). Picks are
grouped by the run's sensor and model; each group's picks are ranked by radius and cut into
thirds, and the outer third's mean error is set against the inner third's.
"""

from __future__ import annotations

import argparse
import itertools
import json
import statistics
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from results_file import write_record

from experiments.table3.settings import TASKS
from perception.camera import PinholeCamera
from robots.yumi import YUMI
from sim.trials.records import read_trial_records
from sim.world.head_camera import camera_config

BIN_WIDTH = 0.1
"""The figure's radius bins: a tenth of the half-diagonal each, out to the farthest target."""
MIN_BIN_PICKS = 20
"""A bin with fewer picks is left out of the figure (its mean is noise); the JSON keeps it."""


class Pick(NamedTuple):
    """One pick: where its target was in the image and how far off its grasp was."""

    radius: float  # distance from the image centre over the half-diagonal
    error_mm: float
    task: str
    seed: int


def radius(camera: PinholeCamera, point_m: list[float]) -> float:
    """The point's distance from the image centre, over the half-diagonal (1 at a corner)."""
    u_px, v_px = camera.project(np.asarray([point_m]))[0]
    ndc_x, ndc_y = camera.pixels_to_ndc(u_px, v_px)
    tan_x, tan_y = camera.tan_half_fov
    return float(np.hypot(ndc_x * tan_x, ndc_y * tan_y) / np.hypot(tan_x, tan_y))


def sensor_of(run: Path) -> str:
    """The run's sensor, as its ``run.json`` names it (absent: the ideal camera)."""
    identity = json.loads((run / "run.json").read_text())
    return str(identity.get("sensor", {"sensor": "ideal"})["sensor"])


def read_picks(run: Path, model: str, camera: PinholeCamera,
               seeds: set[int] | None = None) -> list[Pick]:
    """Every pick with a prediction of ``model``'s plain trials in ``run``'s seeds (None: all)."""
    picks = []
    for folder in sorted(run.glob(f"s*/trials/{model}/*")):
        if folder.name not in TASKS:  # a robustness variant: other light, other objects
            continue
        if seeds is not None and int(folder.parent.parent.parent.name[1:]) not in seeds:
            continue
        for record in read_trial_records(folder / "trials.jsonl"):
            for pick in record.picks:
                if pick.get("truth") is None or pick.get("position_error_m") is None:
                    continue
                picks.append(Pick(radius(camera, pick["truth"]["position_m"]),
                                  1000.0 * pick["position_error_m"], folder.name, record.seed))
    return picks


def summary(picks: list[Pick]) -> dict[str, Any]:
    """Mean error per radius bin, and of the inner and outer thirds of the picks by radius."""
    ranked = sorted(picks, key=lambda p: p.radius)
    third = len(ranked) // 3
    inner, outer = ranked[:third], ranked[len(ranked) - third:]
    edges = np.arange(0.0, max(p.radius for p in picks) + BIN_WIDTH, BIN_WIDTH)
    bins = []
    for low, high in itertools.pairwise(edges):
        inside = [p.error_mm for p in picks if low <= p.radius < high]
        bins.append({"radius": [float(low), float(high)], "picks": len(inside),
                     "mean_error_mm": statistics.fmean(inside) if inside else None})
    return {"picks": len(picks), "bins": bins,
            "inner_third": {"radius_max": inner[-1].radius,
                            "mean_error_mm": statistics.fmean(p.error_mm for p in inner),
                            "median_error_mm": statistics.median(p.error_mm for p in inner)},
            "outer_third": {"radius_min": outer[0].radius,
                            "mean_error_mm": statistics.fmean(p.error_mm for p in outer),
                            "median_error_mm": statistics.median(p.error_mm for p in outer)},
            "outer_over_inner": (statistics.fmean(p.error_mm for p in outer)
                                 / statistics.fmean(p.error_mm for p in inner))}


def figure(groups: dict[str, dict[str, Any]], path: Path) -> None:
    """Mean error per radius bin, one line per sensor and model."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(figsize=(6.0, 3.6), dpi=120)
    for name, group in groups.items():
        shown = [b for b in group["bins"] if b["picks"] >= MIN_BIN_PICKS]
        axes.plot([sum(b["radius"]) / 2 for b in shown], [b["mean_error_mm"] for b in shown],
                  marker="o", label=f"{name} (seeds {', '.join(map(str, group['seeds']))}: "
                  f"{group['picks']} picks)")
    axes.set_xlabel("target's distance from the image centre (1 = a corner)")
    axes.set_ylabel("mean grasp position error [mm]")
    axes.set_ylim(bottom=0)
    axes.grid(alpha=0.3)
    axes.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", type=Path, nargs="+", help="gva reproduce real folders")
    parser.add_argument("--models", default="kqv,kqv-mlp", help="comma-separated (%(default)s)")
    parser.add_argument("--seeds", default=None,
                        help="comma-separated seeds to read (default: every seed a run holds)")
    parser.add_argument("--out", type=Path,
                        default=Path("benchmarks/results/error_by_image_radius.json"))
    parser.add_argument("--figure", type=Path,
                        default=Path("docs/figures/error_by_image_radius.png"))
    args = parser.parse_args()
    camera = camera_config(YUMI).pinhole  # the YuMi's: the calibration every run's model had
    seeds = None if args.seeds is None else {int(s) for s in args.seeds.split(",")}
    groups: dict[str, dict[str, Any]] = {}
    for run in args.runs:
        for model in args.models.split(","):
            picks = read_picks(run, model, camera, seeds)
            if picks:
                name = f"{sensor_of(run)}, {model}"
                groups[name] = {"run": str(run), "seeds": sorted({p.seed for p in picks}),
                                "tasks": sorted({p.task for p in picks})} | summary(picks)
    for name, group in groups.items():
        print(f"{name}: {group['picks']} picks; mean error inner third "
              f"{group['inner_third']['mean_error_mm']:.1f} mm, outer third "
              f"{group['outer_third']['mean_error_mm']:.1f} mm "
              f"(x{group['outer_over_inner']:.2f}); medians "
              f"{group['inner_third']['median_error_mm']:.1f} and "
              f"{group['outer_third']['median_error_mm']:.1f} mm")
    write_record(args.out, {"runs": [str(r) for r in args.runs], "groups": groups}, indent=1,
                 announce=False)
    figure(groups, args.figure)
    print(f"wrote {args.out} and {args.figure}")


if __name__ == "__main__":
    main()
