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

That is the ``"product"`` reading. A map that also holds picks with every error at once
(``joint``) may be read ``"logistic"``: a logistic model, quadratic in the errors, fitted to
every pick of the type (the grid's cells and the joint picks), which sees what the product
cannot: two errors that each hold alone and miss together. Which reading a map takes is the
map's ``reading``; why: docs/decisions/grasp-judge.md.

A map may also carry a ``calibration`` (:class:`PlattScaling`), fitted on the picks of real
runs: it reads the map's chance as the probability that such a pick holds, keeping its order,
so every verdict stays what it was.
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
READINGS = ("product", "logistic")
"""How a map turns its picks into a chance (see the module docstring)."""
FEATURE_SCALE = (10.0, 10.0, 10.0, 30.0)
"""Units of the logistic reading's errors: closing, across, approach [mm], turn [deg]."""
L2_PENALTY = 1e-2
"""The logistic fit's ridge on every weight but the constant (keeps a clean grid finite)."""
RATE_CLIP = 1e-4
"""A chance is read as at least this and at most 1 minus it before its logit (the map's edges
give 0 and 1; a pick is never certain)."""


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
        reading: ``"product"`` or ``"logistic"`` (the module docstring).
        fitted: The logistic reading per type, fitted when the map is built; None for the
            product reading.
        calibration: How a real run's pick reads the map's chance as a probability
            (:meth:`probability`); None: as it is.

    """

    axes: MappingProxyType[str, MappingProxyType[str, AxisTolerance]]
    threshold: float
    provenance: MappingProxyType[str, Any]
    reading: str = "product"
    fitted: MappingProxyType[str, LogisticTolerance] | None = None
    calibration: PlattScaling | None = None

    def probability(self, rate: float) -> float:
        """The chance a real run's pick holds, given the map's ``rate`` for it.

        The map's own rate where it carries no calibration.
        """
        return rate if self.calibration is None else self.calibration(rate)

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
        if self.fitted is not None:
            error = np.array([[1000 * closing_m, 1000 * across_m, 1000 * approach_m,
                               math.degrees(yaw_rad)]])
            return float(self.fitted[object_type].rate(error)[0])
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
        reading = data.get("reading", "product")
        if reading not in READINGS:
            raise InvalidInputError("reading", reading, " or ".join(READINGS))
        fitted = None
        if reading == "logistic":
            fitted = MappingProxyType({t: LogisticTolerance.fit(*type_picks(entry))
                                       for t, entry in data["types"].items()})
        calibration = data.get("calibration")
        return cls(MappingProxyType(types), threshold, MappingProxyType(data.get("how", {})),
                   reading, fitted,
                   None if calibration is None else PlattScaling.from_json(calibration))

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


def quadratic_features(errors: np.ndarray) -> np.ndarray:
    """(n, 4) errors (closing, across, approach [mm], turn [deg]) -> (n, 15) features.

    The offsets across the fingers and along the closing axis count by their size (the
    gripper and the objects are symmetric about them), the approach by its sign, the turn
    folded into [0, 90]; then every square and product of two, and a constant.
    """
    closing, across, approach, yaw = np.asarray(errors, dtype=float).T
    yaw = np.abs((yaw + 90.0) % 180.0 - 90.0)
    base = np.stack([np.abs(closing), np.abs(across), approach, yaw], axis=1) / FEATURE_SCALE
    pairs = [base[:, i] * base[:, j] for i in range(4) for j in range(i, 4)]
    return np.column_stack([np.ones(len(base)), base, *pairs])  # (n, 15)


def sigmoid(z: np.ndarray) -> np.ndarray:
    """``1 / (1 + exp(-z))``, without overflow far from the boundary."""
    return np.exp(-np.logaddexp(0.0, -z))


def logit(rate: np.ndarray) -> np.ndarray:
    """``log(r / (1 - r))`` of rates clipped to [:data:`RATE_CLIP`, 1 - :data:`RATE_CLIP`]."""
    clipped = np.clip(rate, RATE_CLIP, 1.0 - RATE_CLIP)
    return np.log(clipped / (1.0 - clipped))


@dataclass(frozen=True)
class PlattScaling:
    """The map's chance read as a real pick's probability: ``σ(slope · logit(r) + offset)``.

    The map is measured on oracle picks moved one error at a time (and some at once); a
    trained model's picks err in every way at once, and the map's chance is not their rate
    (issue 63: 43 misses expected where 30 happened). Scaling fitted on real runs' picks
    (Platt 1999) maps it onto their rate and keeps its order, so no verdict changes.

    Attributes:
        slope, offset: The fitted scaling of the logit.
        fitted_on: Which runs and picks it was fitted on, and how (command, commit, date).

    """

    slope: float
    offset: float
    fitted_on: MappingProxyType[str, Any]

    def __call__(self, rate: float) -> float:
        """The probability for the map's ``rate``; 0 stays 0 (no grasp was given)."""
        if rate <= 0.0:
            return 0.0
        return float(sigmoid(self.slope * logit(np.array(rate)) + self.offset))

    @classmethod
    def fit(cls, rates: np.ndarray, held: np.ndarray, fitted_on: dict[str, Any]
            ) -> PlattScaling:
        """Maximum likelihood of ``held`` (n,) bool given the map's ``rates`` (n,) > 0.

        Newton's method on two parameters, started at no change (slope 1, offset 0).
        """
        features = np.stack([logit(rates), np.ones(len(rates))], axis=1)  # (n, 2)
        outcome = np.asarray(held, dtype=float)
        weights = np.array([1.0, 0.0])
        for _ in range(50):
            p = sigmoid(features @ weights)
            gradient = features.T @ (outcome - p)
            hessian = (features * (p * (1 - p))[:, None]).T @ features + 1e-9 * np.eye(2)
            step = np.linalg.solve(hessian, gradient)
            weights = weights + step
            if np.abs(step).max() < 1e-10:
                break
        return cls(float(weights[0]), float(weights[1]), MappingProxyType(dict(fitted_on)))

    def to_json(self) -> dict[str, Any]:
        """The scaling as ``grasp_tolerance.json``'s ``calibration`` keeps it."""
        return {"slope": self.slope, "offset": self.offset, "fitted_on": dict(self.fitted_on)}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> PlattScaling:
        """Reads :meth:`to_json`'s form; a slope must be positive (the order kept)."""
        slope, offset = float(data["slope"]), float(data["offset"])
        if not (math.isfinite(slope) and slope > 0 and math.isfinite(offset)):
            raise InvalidInputError("calibration", {"slope": slope, "offset": offset},
                                    "a finite slope > 0 and a finite offset")
        return cls(slope, offset, MappingProxyType(dict(data.get("fitted_on", {}))))


@dataclass(frozen=True)
class LogisticTolerance:
    """The logistic reading of one object type: ``P(held) = σ(w · features(error))``.

    Only within what was measured: a quadratic logit may turn up again far from its picks (a
    grasp 10 cm off read as likely to hold), so an error beyond the largest of its kind among
    the fitted picks (``reach``) is read as a miss: the map vouches for nothing it did not try.
    """

    weights: np.ndarray  # (15,)
    reach: np.ndarray  # (4,) the largest |closing|, |across|, |approach| [mm], turn [deg] fitted

    def rate(self, errors: np.ndarray) -> np.ndarray:
        """The chance each of ``errors`` (n, 4) holds, (n,)."""
        errors = np.asarray(errors, dtype=float)
        inside = (np.abs(errors) <= self.reach + 1e-9).all(axis=1)
        return np.where(inside, sigmoid(quadratic_features(errors) @ self.weights), 0.0)

    @classmethod
    def fit(cls, errors: np.ndarray, held: np.ndarray, weight: np.ndarray) -> LogisticTolerance:
        """Newton's method on the weighted log-likelihood, ridge :data:`L2_PENALTY`.

        ``held`` (n,) is the fraction held at each error, ``weight`` (n,) its picks.
        """
        x = quadratic_features(errors)  # (n, 15)
        ridge = L2_PENALTY * np.eye(x.shape[1])
        ridge[0, 0] = 0.0
        w = np.zeros(x.shape[1])
        for _ in range(100):
            p = sigmoid(x @ w)
            gradient = x.T @ (weight * (held - p)) - ridge @ w
            hessian = (x * (weight * p * (1 - p))[:, None]).T @ x + ridge
            step = np.linalg.solve(hessian, gradient)
            w += step
            if float(np.abs(step).max()) < 1e-9:
                break
        reach = np.abs(np.asarray(errors, dtype=float)).max(axis=0)
        reach[3] = 90.0  # every turn folds into [0, 90]: none lies beyond
        return cls(w, reach)


def type_picks(entry: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pick of a type's record: (errors (n, 4), fraction held (n,), picks (n,)).

    A grid cell is one row (its offset on its axis, the others 0; its picks as the weight);
    each joint pick is a row of its own.
    """
    rows, held, weight = [], [], []
    for axis, table in entry["axes"].items():
        column = AXES.index(axis)
        for offset, picked_row, trials_row in zip(table["offsets_mm"], table["picked"],
                                                  table["trials"], strict=True):
            if offset == 0.0 and axis != "closing":
                continue  # the zero offset is one set of picks, kept under every axis
            for yaw, picked, trials in zip(entry["yaw_deg"], picked_row, trials_row,
                                           strict=True):
                error = [0.0, 0.0, 0.0, yaw]
                error[column] = offset
                rows.append(error)
                held.append(picked / max(trials, 1))
                weight.append(trials)
    joint = entry.get("joint")
    if joint:
        rows += joint["errors"]
        held += [float(p) for p in joint["picked"]]
        weight += [1] * len(joint["picked"])
    return np.asarray(rows, float), np.asarray(held, float), np.asarray(weight, float)


DEFAULT_MAP_NAME = "grasp_tolerance.json"


@functools.cache
def default_tolerance_map() -> ToleranceMap:
    """The map shipped with gva, measured on the yumi scene (read once per process)."""
    with resources.as_file(resources.files("perception.judge") / DEFAULT_MAP_NAME) as path:
        return ToleranceMap.load(path)
