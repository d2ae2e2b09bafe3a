"""The features of a gva LeRobot folder: their column keys, info.json's entry and stats.json's.

:mod:`perception.learning.lerobot_format` writes and reads the folder; this module says what
each feature is to LeRobot: its key, dtype, shape and names (``info.json``'s ``features``) and
LeRobot's statistics of its values (``meta/stats.json``, each episode's ``stats/...`` columns).
``docs/lerobot.md`` maps every column to what it came from.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from perception.interface import LabelKind
from perception.learning.data import JOINT_NAMES_KEY, Dataset

FPS = 1  # pick stages are not sampled at a rate: timestamp = frame_index / FPS [s]
IMAGE_KEY = "observation.images.head"
CONDITION_KEY = "observation.condition"
STATE_KEY = "observation.state"  # the robot's joint positions [rad, m] when the image was taken
DEPTH_KEY = "observation.depth.head"  # float32 depth along the optical axis [m], per pixel
PRESENT_KEY = "action.target_present"  # not observation.* nor "action": policies skip it
QUANTILES = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}

_INDEX_KEYS = ("frame_index", "episode_index", "index", "task_index")
_LABEL_NAMES = {LabelKind.POSITION: ("x_m", "y_m", "z_m"),
                LabelKind.GRASP_POSE: ("x_m", "y_m", "z_m", "r00", "r01", "r02",
                                       "r10", "r11", "r12", "r20", "r21", "r22")}


def info_features(data: Dataset) -> dict[str, dict[str, Any]]:
    """info.json's features: dtype, shape and names of every column."""
    meta, condition_size = data.metadata, data.conditions.shape[1]
    h, w = meta.image_height_px, meta.image_width_px
    features: dict[str, dict[str, Any]] = {
        IMAGE_KEY: {"dtype": "image", "shape": [h, w, 3], "names": ["height", "width", "channels"]},
        "action": {"dtype": "float32", "shape": [meta.targets * meta.label_dim],
                   "names": [f"target{k}.{name}" for k in range(meta.targets)
                             for name in _LABEL_NAMES[meta.label_kind]]},
        PRESENT_KEY: {"dtype": "float32", "shape": [meta.targets],
                      "names": [f"target{k}" for k in range(meta.targets)]},
    }
    if condition_size:
        names = (list(meta.condition_choices) if meta.condition_kind.one_hot
                 else [f"c{i}" for i in range(condition_size)])
        features[CONDITION_KEY] = {"dtype": "float32", "shape": [condition_size], "names": names}
    if data.joint_positions is not None:
        joints = list(meta.extra[JOINT_NAMES_KEY])
        features[STATE_KEY] = {"dtype": "float32", "shape": [len(joints)], "names": joints}
    if data.depths_m is not None:
        features[DEPTH_KEY] = {"dtype": "float32", "shape": [h, w], "names": ["height", "width"]}
    features["timestamp"] = {"dtype": "float32", "shape": [1], "names": None}
    features |= {key: {"dtype": "int64", "shape": [1], "names": None} for key in _INDEX_KEYS}
    for feature in features.values():
        feature["fps"] = FPS
    return features


def all_stats(columns: dict[str, np.ndarray], images: np.ndarray,
               depths_m: np.ndarray | None) -> dict[str, dict]:
    """LeRobot's stats per feature: images per channel in [0, 1] as (3, 1, 1), vectors per entry.

    Depth gets one set over all its finite pixels, shape (1,) (it broadcasts over the image;
    a pixel that sees nothing holds inf, which JSON cannot).
    """
    stats = {IMAGE_KEY: _stats(images.reshape(-1, 3) / 255.0, len(images), (3, 1, 1))}
    if depths_m is not None:
        finite = depths_m[np.isfinite(depths_m)].astype(np.float64).reshape(-1, 1)
        stats[DEPTH_KEY] = _stats(finite, len(depths_m), (1,))
    for key, column in columns.items():
        values = column.astype(np.float64).reshape(len(column), -1)
        stats[key] = _stats(values, len(column), (values.shape[1],))
    return stats


def _stats(values: np.ndarray, count: int, shape: tuple[int, ...]) -> dict[str, list]:
    """min, max, mean, std, count and quantiles of ``values`` (M, D) over M, each as ``shape``."""
    result = {"min": values.min(axis=0), "max": values.max(axis=0),
              "mean": values.mean(axis=0), "std": values.std(axis=0)}
    result |= {key: np.quantile(values, q, axis=0) for key, q in QUANTILES.items()}
    out: dict[str, list] = {key: value.reshape(shape).tolist() for key, value in result.items()}
    out["count"] = [count]
    return out
