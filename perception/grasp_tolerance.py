"""How far off a grasp may be and still hold each object: a map measured by physics, read as data.

``benchmarks/bench_grasp_tolerance.py`` runs oracle pick trials with the true grasp moved along
one axis of the grasp's own frame (closing, across, approach) and turned about the approach
axis, on a grid per object type, and counts the picks that held. This module reads that record
(``grasp_tolerance.json`` beside it, which says how it was made) and estimates the chance that
a grasp with a given error holds:

* along each axis, the picked fraction interpolated bilinearly in (offset, turn) and held at
  the grid's edge beyond it (the map reaches past where every pick fails);
* the axes combined as independent causes of a miss at the same turn: ``r0 · Π (r_axis / r0)``,
  with ``r0`` the fraction at no offset and that turn, each ratio at most 1;
* a pick predicted to hold when that chance is at least the map's ``threshold`` (0.5).

The combination and the threshold were fixed before the map was validated against real trials
(``gva judge``): docs/decisions/grasp-judge.md.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from perception.errors import InvalidInputError
from perception.files import FileError

TOLERANCE_FORMAT = 1
"""The version of ``grasp_tolerance.json``'s layout this module reads."""
AXES = ("closing", "across", "approach")
"""The grasp frame's axes a map measures, in the order of :class:`GraspError`'s fields."""
SIGNED_AXES = frozenset({"approach"})
"""Axes whose sign matters (too deep differs from too shallow); the others are symmetric."""


class ToleranceFileError(FileError):
    """A tolerance map that cannot be read."""

    kind = "grasp tolerance map"


@dataclass(frozen=True)
class AxisTolerance:
    """Picked fractions along one grasp axis, crossed with turns about the approach axis.

    Attributes:
        offsets_m: (O,) offsets along the axis [m], increasing; absolute values unless signed.
        yaws_rad: (Y,) turns about the approach axis [rad], increasing from 0.
        picked: (O, Y) picks that held.
        trials: (O, Y) picks tried.

    """

    offsets_m: np.ndarray
    yaws_rad: np.ndarray
    picked: np.ndarray
    trials: np.ndarray

    @property
    def rates(self) -> np.ndarray:
        """(O, Y) the fraction that held."""
        return self.picked / np.maximum(self.trials, 1)

    def rate(self, offset_m: float, yaw_rad: float) -> float:
        """The fraction that held at ``offset_m`` and ``yaw_rad``, bilinear, held at the edges."""
        return float(_bilinear(self.offsets_m, self.yaws_rad, self.rates, offset_m, yaw_rad))


def _bilinear(xs: np.ndarray, ys: np.ndarray, values: np.ndarray, x: float, y: float) -> float:
    """``values`` (X, Y) on the grid ``xs`` x ``ys``, interpolated at (x, y), clamped to it."""
    def locate(grid: np.ndarray, at: float) -> tuple[int, float]:
        at = min(max(at, float(grid[0])), float(grid[-1]))
        i = int(np.clip(np.searchsorted(grid, at, side="right") - 1, 0, len(grid) - 2))
        return i, (at - float(grid[i])) / float(grid[i + 1] - grid[i])

    i, tx = locate(xs, x)
    j, ty = locate(ys, y)
    top = (1 - ty) * values[i, j] + ty * values[i, j + 1]
    bottom = (1 - ty) * values[i + 1, j] + ty * values[i + 1, j + 1]
    return float((1 - tx) * top + tx * bottom)


@dataclass(frozen=True)
class ToleranceMap:
    """Per object type and grasp axis, how often a pick held at each (offset, turn).

    Attributes:
        axes: ``{object_type: {axis: AxisTolerance}}`` for each axis of :data:`AXES`.
        threshold: The estimated chance at or above which a pick is predicted to hold.
        provenance: How the map was made (command, commit, trials per cell, scenes).

    """

    axes: MappingProxyType[str, MappingProxyType[str, AxisTolerance]]
    threshold: float
    provenance: MappingProxyType[str, Any]

    @property
    def object_types(self) -> tuple[str, ...]:
        """The types the map holds."""
        return tuple(self.axes)

    def success_rate(self, object_type: str, closing_m: float, across_m: float,
                     approach_m: float, yaw_rad: float) -> float:
        """The estimated chance a grasp with these errors holds an ``object_type``, in [0, 1]."""
        if object_type not in self.axes:
            raise InvalidInputError("object type", object_type,
                                    f"one the tolerance map measured: {', '.join(self.axes)}")
        yaw_rad = abs(math.remainder(yaw_rad, math.pi))
        offsets = {"closing": closing_m, "across": across_m, "approach": approach_m}
        axes = self.axes[object_type]
        base = min(axes[axis].rate(0.0, yaw_rad) for axis in AXES)
        if base <= 0.0:
            return 0.0
        rate = base
        for axis in AXES:
            offset = offsets[axis] if axis in SIGNED_AXES else abs(offsets[axis])
            rate *= min(1.0, axes[axis].rate(offset, yaw_rad) / base)
        return rate

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ToleranceMap:
        """Builds a map from the data ``benchmarks/bench_grasp_tolerance.py`` writes."""
        if data.get("format") != TOLERANCE_FORMAT:
            raise InvalidInputError("format", data.get("format"), f"{TOLERANCE_FORMAT}")
        types: dict[str, MappingProxyType[str, AxisTolerance]] = {}
        for object_type, entry in data["types"].items():
            yaws = np.radians(np.asarray(entry["yaw_deg"], dtype=float))
            per_axis = {}
            for axis in AXES:
                cells = entry["axes"][axis]
                offsets = np.asarray(cells["offsets_mm"], dtype=float) / 1000
                picked = np.asarray(cells["picked"], dtype=float)
                trials = np.asarray(cells["trials"], dtype=float)
                if picked.shape != (len(offsets), len(yaws)) or trials.shape != picked.shape:
                    raise InvalidInputError(f"{object_type}.{axis} cells", picked.shape,
                                            f"({len(offsets)}, {len(yaws)}): offsets x yaws")
                increasing = np.all(np.diff(offsets) > 0) and np.all(np.diff(yaws) > 0)
                if 0.0 not in offsets or not increasing:
                    raise InvalidInputError(f"{object_type}.{axis} grid", offsets.tolist(),
                                            "increasing offsets that include 0, increasing yaws")
                per_axis[axis] = AxisTolerance(offsets, yaws, picked, trials)
            types[object_type] = MappingProxyType(per_axis)
        threshold = float(data["threshold"])
        if not 0.0 < threshold < 1.0:
            raise InvalidInputError("threshold", threshold, "in (0, 1)")
        return cls(MappingProxyType(types), threshold, MappingProxyType(data.get("how", {})))

    @classmethod
    def load(cls, path: Path) -> ToleranceMap:
        """Reads a map file; a missing or broken file is a :class:`ToleranceFileError`."""
        try:
            return cls.from_json(json.loads(Path(path).read_text()))
        except FileNotFoundError:
            raise ToleranceFileError(path, "not found (make one with python "
                                     "benchmarks/bench_grasp_tolerance.py)") from None
        except (ValueError, KeyError, TypeError) as error:
            raise ToleranceFileError(path, f"not a tolerance map: {error}") from None


DEFAULT_MAP_NAME = "grasp_tolerance.json"


@functools.cache
def default_tolerance_map() -> ToleranceMap:
    """The map shipped with gva, measured on the yumi scene (read once per process)."""
    with resources.as_file(resources.files("perception") / DEFAULT_MAP_NAME) as path:
        return ToleranceMap.load(path)
