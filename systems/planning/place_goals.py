"""Where the object is believed to be during a pick, and the held moves that take it to a place target.

Frames: W the world, O the object (origin on its support surface, z up). The belief starts where
perception saw the object; every held move that was planned moves it by the hands' achieved motion,
and a look at the object in the hands replaces it with what the tracker found.
"""

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from systems.messages import ObjectBelief, PlaceGoal

# The place task sets the object down to this height above the table: a little into it, so that the object
# rests on the table before the hands open (held above it, it drops and turns when let go), m.
PLACE_CLEARANCE = -0.003
# Where no plan sets the object down on a place target, it is set down these distances off it (m), each towards the
# robot first, then away, then to either side: within the place's tolerance (2 cm), a hand that came within the
# planner's clearance of a box beside the target clears it (drills over the box, test_0 and test_2 at yaw 0: the right
# palm 0.2-0.3 mm short of the 5 mm a plan keeps from the box's edge). The nearer first: a set-down lands up to a
# centimetre off its goal, and 1 cm off left test_2 2.0 cm from the target.
PLACE_NUDGES_M = (0.005, 0.01)


def place_motion(
    goal: PlaceGoal, belief: ObjectBelief, target_W: RigidTransform
) -> tuple[RigidTransform, RigidTransform | None]:
    """The held move of a carry or set-down towards target_W (X_WO on the table) from where the object is
    believed to be, as (X_motion_W, carried_motion_W): the carry also gives the object's motion since it
    was seen (the planner keeps the perceived object, moved by it, clear of the scene); a set-down None."""
    now = belief.now_W
    if goal == PlaceGoal.CARRY:  # over the target, turned about the vertical to its yaw, at the carried height
        turn = RollPitchYaw(target_W.rotation()).yaw_angle() - RollPitchYaw(now.rotation()).yaw_angle()
        over = RigidTransform(
            RotationMatrix.MakeZRotation(turn) @ now.rotation(), [*target_W.translation()[:2], now.translation()[2]]
        )
        return over @ now.inverse(), now @ belief.seen_W.inverse()
    if goal != PlaceGoal.SET_DOWN:
        raise ValueError(f"unknown place goal {goal!r}: one of {', '.join(PlaceGoal)}")
    # Onto the target, PLACE_CLEARANCE above the table (down, and what a look found still to turn).
    down = RigidTransform(target_W.rotation(), target_W.translation() + [0.0, 0.0, PLACE_CLEARANCE])
    return down @ now.inverse(), None


def nudged_targets(target_W: RigidTransform, nudges=PLACE_NUDGES_M) -> list[RigidTransform]:
    """The place target (X_WO on the table) moved by each of `nudges` (m) along -x, +x, -y, +y of W (towards the
    robot first), its orientation kept: where to set the object down when no plan sets it down on the target."""
    directions = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
    return [RigidTransform(target_W.rotation(), target_W.translation() + n * d) for n in nudges for d in directions]
