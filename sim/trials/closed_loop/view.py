"""What a frame shows of a target while the arm is in view (issue 36's closed loop).

A self-filtered frame (:meth:`sim.world.head_camera.HeadCamera.render_rgbd`) carries the robot's
own pixels as ``robot_mask``; a closed loop heeds a re-prediction only where the camera sees the
target followed, or the grasp named stands in plain view (:mod:`sim.trials.closed_loop.loop`), and
a demonstration keeps only the approach images that show every target
(:mod:`harness.inputs.collector`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from control.depth_obstacles import DepthObstacleConfig
from perception.camera import RgbdFrame

_DISK = np.array([(r * math.cos(a), r * math.sin(a)) for r, n in ((0.0, 1), (1 / 3, 8),
                                                                 (2 / 3, 16), (1.0, 24))
                  for a in np.linspace(0.0, 2 * math.pi, n, endpoint=False)])
"""Points of the unit disk (49: its centre and three rings), where a footprint is looked at."""
STANDING_RADIUS_M = 0.015
"""How near a grasp's point the depth image must show something standing [m]: within the
narrowest target's half-width about its grasp (the sponge's 17.5 mm), so a target there shows."""
STANDING_HEIGHT_M = DepthObstacleConfig.table_z_m + DepthObstacleConfig.min_height_m
"""How high above the table a point must be to stand there [m]: the depth obstacles' (lower is
the table)."""


def in_plain_view(frame: RgbdFrame, grasp_m: np.ndarray, radius_m: float) -> bool:
    """Whether ``frame`` shows all of the footprint about ``grasp_m`` and something stands there.

    Something: a depth point above :data:`STANDING_HEIGHT_M` within :data:`STANDING_RADIUS_M`
    of the grasp (level distance). Where the arm hides the target followed, a grasp named in
    plain view over an object is one the camera can vouch for (a target moved out from under
    the arm); one named on bare table or behind the arm is a guess.
    """
    if hidden_share(frame, grasp_m, radius_m) > 0.0:
        return False
    points = frame.points_world().reshape(-1, 3)
    near = np.hypot(points[:, 0] - grasp_m[0], points[:, 1] - grasp_m[1]) < STANDING_RADIUS_M
    return bool((points[near, 2] > STANDING_HEIGHT_M).any())  # NaN (no depth) compares False


def hidden_share(frame: RgbdFrame, center_m: np.ndarray, radius_m: float) -> float:
    """The share of the level disk of ``radius_m`` about ``center_m`` that ``frame`` cannot see.

    Hidden: behind the robot's own pixels (``frame.robot_mask``) or outside the image. 0 for a
    frame without a robot mask (not self-filtered: the arm at rest, out of the way).
    """
    if frame.robot_mask is None:
        return 0.0
    points = np.column_stack([np.asarray(center_m)[:2] + radius_m * _DISK,
                              np.full(len(_DISK), float(center_m[2]))])
    height, width = frame.robot_mask.shape
    uv = np.nan_to_num(np.round(frame.camera.project(points)), nan=-1.0)  # NaN: behind it
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < width) & (uv[:, 1] >= 0) & (uv[:, 1] < height)
    u, v = uv[inside].astype(int).T
    hidden = (~inside).sum() + frame.robot_mask[v, u].sum()
    return float(hidden / len(_DISK))


@dataclass(frozen=True)
class ViewVerdict:
    """Whether a closed loop heeds a re-prediction, by what the frame shows.

    Args:
        unheeded: Why it is not heeded, in words; None: it is.
        unconfirmed_m: A grasp named in plain view once, to be confirmed by the next look
            (None: nothing waits for confirmation).

    """

    unheeded: str | None
    unconfirmed_m: np.ndarray | None = None


def unheeded_reason(frame: RgbdFrame, followed_m: np.ndarray, named_m: np.ndarray,
                    radius_m: float, once_m: np.ndarray | None, same_m: float) -> ViewVerdict:
    """Why a closed loop does not heed a re-prediction (heeded: none), and what to remember.

    Heeded where ``frame`` shows the footprint about the grasp followed (``followed_m``).
    Where the arm hides any of it, heeded only if the grasp named (``named_m``) stands in plain
    view (:func:`in_plain_view`) two looks in a row, within ``same_m`` of the look before
    (``once_m``): a target moved out from under the arm stays where it went, a guess at what
    the arm hides does not hold still. The verdict's ``unconfirmed_m`` is the plain-view grasp
    to hand the next look as ``once_m``.
    """
    hidden = hidden_share(frame, followed_m, radius_m)
    if hidden == 0.0:
        return ViewVerdict(None)
    share = f"the arm hides {100 * hidden:.0f} % of the target's footprint"
    if not in_plain_view(frame, named_m, radius_m):
        return ViewVerdict(f"{share}, and nothing stands in plain view where the grasp now is")
    if once_m is not None and float(np.linalg.norm(named_m - once_m)) <= same_m:
        return ViewVerdict(None)
    return ViewVerdict(f"{share}; the grasp named stands in plain view, the next look must "
                       "confirm it", named_m)
