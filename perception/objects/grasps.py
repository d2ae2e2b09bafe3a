"""Which grasp to take among an object's symmetric equivalents.

The canonical one (what the oracle returns and a model learns), and the alternatives a planner
may fall back on when the canonical one is blocked.
"""

from __future__ import annotations

import math

import numpy as np

from perception.objects.catalog import GraspSpec, ObjectSpec, Symmetry
from perception.poses import Pose, rot_z


def grasp_pose(spec: ObjectSpec, T_world_object: Pose) -> Pose:
    """Return the canonical grasp ``T_world_tcp`` of an object placed at ``T_world_object``.

    Among the grasps the object's symmetry allows, the one a robot at the origin facing +x takes
    most naturally; a deterministic function of the pose, continuous except at a few switch
    points (a network learns it from images):

    * two-fold (sponge): of the two half-turn equivalents, the one whose closing axis points
      most to the robot's left, seen along the line from the robot base to the object;
      switches where the closing axis is radial.
    * continuous (bottle) and none-but-turnable (mug): the turn about the object's vertical axis
      that brings the pre-grasp point nearest the robot base, i.e. a side grasp approaches along
      the line from the base, a rim grasp takes the rim point nearest the robot; the mug's turn
      is clamped short of the handle, so it switches where the handle faces the robot.
    """
    turn = _canonical_turn_rad(spec.grasp, T_world_object)
    return T_world_object.compose(Pose(np.zeros(3), rot_z(turn))).compose(spec.grasp.T_object_grasp)


def _canonical_turn_rad(grasp: GraspSpec, T_world_object: Pose) -> float:
    radial = T_world_object.position[:2].astype(float)
    norm = float(np.linalg.norm(radial))
    radial = radial / norm if norm > 1e-6 else np.array([1.0, 0.0])
    left = np.array([-radial[1], radial[0]])
    T_object_grasp = grasp.T_object_grasp
    closing_world = (T_world_object.rotation @ T_object_grasp.rotation[:, 0])[:2]
    if grasp.symmetry is Symmetry.TWO_FOLD:
        return 0.0 if float(closing_world @ left) >= 0.0 else math.pi
    pregrasp = T_object_grasp.position - grasp.pregrasp_distance_m * T_object_grasp.rotation[:, 2]
    offset = (T_world_object.rotation @ pregrasp)[:2]
    if np.linalg.norm(offset) < 1e-6:  # pre-grasp on the axis: close sideways instead
        reference, target = closing_world, left
    else:
        reference, target = offset, -radial
    turn = math.remainder(
        math.atan2(target[1], target[0]) - math.atan2(reference[1], reference[0]), 2.0 * math.pi
    )
    if grasp.symmetry is Symmetry.NONE:
        turn = max(-grasp.max_turn_rad, min(grasp.max_turn_rad, turn))
    return turn


ALTERNATIVE_STEP_RAD = math.radians(20.0)
"""The step between a continuously symmetric object's alternative grasps, about its axis."""
ALTERNATIVE_TURNS_RAD = (*(sign * k * ALTERNATIVE_STEP_RAD for k in range(1, 9)
                           for sign in (1.0, -1.0)), math.pi)
"""The whole circle in 20 degree steps, nearest the given grasp first: +-20, +-40, ... +-160,
180 degrees. The bottle is the same from every side, so a hand may take it from whichever side
is clear; the Panda's wide hand, between neighbours, often finds none within 40 degrees of the
given grasp (docs/decisions/robots.md)."""


def symmetric_alternatives(
    spec: ObjectSpec, T_world_grasp: Pose, turns_rad: tuple[float, ...] = ALTERNATIVE_TURNS_RAD
) -> tuple[Pose, ...]:
    """Grasps equivalent to ``T_world_grasp`` by the object's rotational symmetry.

    For an object the same after any turn (the bottle), the grasp turned by each of
    ``turns_rad`` about the object's vertical axis, which is found from the grasp itself (no
    knowledge of the true pose): a planner tries them, in order, when the given grasp is
    blocked. Other symmetries give none (a half turn of the sponge equals the gripper's own
    half turn).
    """
    if spec.grasp.symmetry is not Symmetry.CONTINUOUS:
        return ()
    T_world_object = spec.grasp.object_frame(T_world_grasp)
    return tuple(T_world_object.compose(Pose(np.zeros(3), rot_z(turn)))
                 .compose(spec.grasp.T_object_grasp) for turn in turns_rad)
