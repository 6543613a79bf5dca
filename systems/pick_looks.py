"""The pick's looks at the object, read into its belief (for the PickSupervisor, systems/pick_supervisor.py): a look
before the approach (did the object move on the table?), a look at the held object, and a look after the place (does
it stand on its target?)."""

import logging
from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from systems.messages import ObjectBelief, ObjectEstimate, PickStatus, Targets

# A look before the approach corrects the grasps when the object moved on the table (its origin in x, y; its yaw)
# more than this since it was seen (a look's own error is a few millimetres and a degree or two), m and rad, at
# most this often per attempt.
MOVED_M = 0.01
MOVED_RAD = np.radians(4.0)
MAX_CORRECTIONS = 2
# A look after the place finds the object off its target by more than this (its origin in x, y; its yaw): the
# hands take it again, m and rad, at most this often per attempt. Only where it is clearly off (the judge allows
# 2 cm and 5 deg; a look's own error is up to about 1 cm and 2 deg): taking a can again disturbs it
# (docs/history/pick_parameters.md).
PLACED_M = 0.02
PLACED_RAD = np.radians(6.0)
MAX_PLACE_CORRECTIONS = 1


def read_look(found: ObjectEstimate, status: PickStatus, recheck: bool = False) -> bool:
    """Where the tracker found the object: the moves that follow start from there (a recheck: only where it moved
    more than MOVED_M or MOVED_RAD). If it did not find it, the pick goes on from where the object was believed to be.
    Whether the belief changed."""
    status.looks_read += 1
    logging.info("look: %s (%.3f s)", found.message, found.compute_s)
    if not found.found:
        logging.warning("look: %s; going on from where the object was believed to be", found.message)
        return False
    X_WO = found.X_WO
    if recheck:  # it stands on the table: a move is planar (the tracker's tilt is for objects in the hands)
        moved = standing(X_WO, status.belief.now_W)
        if moved.shift_m <= MOVED_M and abs(moved.turn_rad) <= MOVED_RAD:
            return False
        logging.warning("look: the object moved %.1f cm and %.1f deg", 100 * moved.shift_m, np.degrees(moved.turn_rad))
        X_WO = moved.X_WO
    status.belief = status.belief.looked(X_WO)
    return True


def placed_off_target(found: ObjectEstimate, status: PickStatus, target_W: RigidTransform) -> bool:
    """A look after the place: whether the object stands off target_W (PLACED_M, PLACED_RAD) and may be taken again
    (MAX_PLACE_CORRECTIONS); the belief then takes the look."""
    status.looks_read += 1
    if not found.found:
        logging.warning("look after the place: %s; not confirmed", found.message)
        return False
    X_WO = standing(found.X_WO, status.belief.now_W).X_WO
    off = standing(X_WO, target_W)
    shift, turn = off.shift_m, off.turn_rad
    logging.info("look after the place: %.1f cm and %.1f deg off the target", 100 * shift, np.degrees(turn))
    if (shift <= PLACED_M and abs(turn) <= PLACED_RAD) or status.place_corrections >= MAX_PLACE_CORRECTIONS:
        return False
    logging.warning("the object stands off the place target: taking it again")
    status.belief = status.belief.looked(X_WO)
    return True


@dataclass(frozen=True)
class PlanarMove:
    """A look at an object standing on the table, taken as a planar move from where it was before."""

    X_WO: RigidTransform  # before, turned about the vertical by the look's yaw, its origin moved in x, y to the look's
    shift_m: float  # that move's shift of the origin in x, y
    turn_rad: float  # its turn about the vertical


def standing(X_WO: RigidTransform, before_W: RigidTransform) -> PlanarMove:
    """A look at an object standing on the table (X_WO), taken as a planar move from before_W (the tracker's tilt is
    for objects in the hands)."""
    shift = float(np.linalg.norm(X_WO.translation()[:2] - before_W.translation()[:2]))
    turn = RollPitchYaw(X_WO.rotation() @ before_W.rotation().inverse()).yaw_angle()
    at = [*X_WO.translation()[:2], before_W.translation()[2]]
    return PlanarMove(RigidTransform(RotationMatrix.MakeZRotation(turn) @ before_W.rotation(), at), shift, turn)


def object_motion(belief: ObjectBelief, targets: Targets) -> RigidTransform | None:
    """A reach's or approach's correction (targets PREGRASP, GRASP): the object's motion since it was seen, where a
    look found one; None otherwise."""
    if targets not in (Targets.PREGRASP, Targets.GRASP) or belief.now_W.IsExactlyEqualTo(belief.seen_W):
        return None
    return belief.now_W @ belief.seen_W.inverse()
