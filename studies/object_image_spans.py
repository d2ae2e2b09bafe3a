"""How large the Table III objects appear through each robot's camera [px].

The heatmap focus (``KqvConfig.focus_window_px``) reads a window about the densest part of an
attention map; whether an object fits such a window is a question of its size in the image.
This projects every corner of each object's primitives (their bounding boxes) through a robot's
calibrated camera, the object standing anywhere on the workspace (x 0.40-0.55 m, y +-0.20 m)
at 8 yaws, and states per object: its span (the larger side of its image box) and its reach
(the farthest corner from where its centre projects). Geometry only: no rendering, no model.

Usage:
    python studies/object_image_spans.py [--robots yumi,panda] [--out FILE]
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import numpy as np
from results_file import write_record

from perception.camera import PinholeCamera
from perception.objects.catalog import get_object_spec
from perception.objects.object_spec import ObjectSpec, Primitive
from perception.poses import rot_rpy
from robots import ROBOT_NAMES, get_robot
from sim.world.head_camera import camera_config

OBJECTS = ("sponge", "spray_bottle", "mug")
"""The objects Table III's tasks place."""
WORKSPACE_X_M = (0.40, 0.55)
WORKSPACE_Y_M = (-0.20, 0.20)
GRID = (4, 5, 8)
"""Samples along x, along y and of the yaw over a half turn."""


@dataclass(frozen=True)
class ImageSpan:
    """One object's size in one camera's image over the workspace [px]."""

    robot: str
    object_type: str
    span_min_px: float
    span_median_px: float
    span_max_px: float
    reach_min_px: float
    reach_max_px: float


def _corners(primitive: Primitive) -> np.ndarray:
    """The primitive's bounding-box corners in the object frame, (8, 3) [m]."""
    half = [s / 2 for s in primitive.size_m]
    box = np.array(list(itertools.product(*[(-h, h) for h in half])))
    return box @ rot_rpy(primitive.rpy_rad).T + np.array(primitive.position_m)


def image_span(robot: str, camera: PinholeCamera, spec: ObjectSpec) -> ImageSpan:
    """``spec``'s span and reach through ``camera`` over the workspace grid."""
    points = np.concatenate([_corners(p) for p in spec.primitives])
    spans, reaches = [], []
    for x, y, yaw in itertools.product(np.linspace(*WORKSPACE_X_M, GRID[0]),
                                       np.linspace(*WORKSPACE_Y_M, GRID[1]),
                                       np.linspace(0.0, math.pi, GRID[2], endpoint=False)):
        world = points @ rot_rpy((0.0, 0.0, yaw)).T + np.array([x, y, 0.0])
        pixels = np.asarray(camera.project(world))
        centre = np.asarray(camera.project(np.array([[x, y, spec.height_m / 2]])))[0]
        spans.append(float((pixels.max(axis=0) - pixels.min(axis=0)).max()))
        reaches.append(float(np.linalg.norm(pixels - centre, axis=1).max()))
    return ImageSpan(robot, spec.name, min(spans), float(np.median(spans)), max(spans),
                     min(reaches), max(reaches))


def main(argv: list[str] | None = None) -> list[ImageSpan]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default=",".join(ROBOT_NAMES),
                        help="comma-separated robot names (default: every robot)")
    parser.add_argument("--out", type=Path, default=None, help="also write the rows as JSON")
    args = parser.parse_args(argv)
    rows = []
    for robot in args.robots.split(","):
        config = camera_config(get_robot(robot))
        for name in OBJECTS:
            row = image_span(robot, config.pinhole, get_object_spec(name))
            rows.append(row)
            print(f"{robot:6s} {name:13s} span {row.span_min_px:5.1f}-{row.span_max_px:5.1f} px "
                  f"(median {row.span_median_px:5.1f}), reach {row.reach_min_px:5.1f}-"
                  f"{row.reach_max_px:5.1f} px; the focus window: {config.focus_window_px} px")
    if args.out is not None:
        write_record(args.out, [asdict(r) for r in rows], indent=1, announce=False)
    return rows


if __name__ == "__main__":
    main()
