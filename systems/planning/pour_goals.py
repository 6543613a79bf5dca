"""Where a held can goes to pour: over a container's opening, then turned forward about a pivot between the hands
until its outflow points far enough down, the spout's tip then over the opening's centre.

Frames: W the world, O the object (origin on its support surface, z up). The tilt turns the object about the
horizontal axis across its outflow's vertical plane (k = z_W x the outflow's horizontal direction) through the
pivot, the midpoint of the two grasps, so both hands turn with it (the closure kept). Not about the line through
both grasps: on a watering can that line runs nearly along the spout (a rear and a top handle in the spout's plane),
and turning about it turns the spout sideways, never down.
"""

from dataclasses import dataclass

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RotationMatrix

from systems.perception.container_opening import Opening
from systems.shape_space.tool_frame import ToolFrame

POUR_CLEARANCE_M = 0.04  # m: the spout's tip this far above the opening's rim while it pours
MIN_OUTFLOW_RUN = 0.2  # of the outflow: its horizontal share, below which no direction to tilt it is defined


@dataclass(frozen=True)
class PourPoses:
    """The object's poses (X_WO) for a pour, and the held motion between them."""

    over_W: RigidTransform  # upright, placed so that the tilt puts the tip over the opening
    poured_W: RigidTransform  # tilted, the tip POUR_CLEARANCE_M above the opening's centre
    tilt_rad: float  # the turn about the pivot, rad (positive: the spout down)

    @property
    def tilt_motion_W(self) -> RigidTransform:
        """The held motion from over_W to poured_W (a turn about the pivot), in W."""
        return self.poured_W @ self.over_W.inverse()


def outflow_elevation(X_WO: RigidTransform, tool_O: ToolFrame) -> float:
    """The angle of the object's outflow above the horizontal, rad (negative: pointing down)."""
    return float(np.arcsin(np.clip(tool_O.moved(X_WO).axis[2], -1.0, 1.0)))


def pour_poses(
    X_WO: RigidTransform,
    tool_O: ToolFrame,
    pivot_O: np.ndarray,
    opening: Opening,
    tilt_below_rad: float,
    clearance: float = POUR_CLEARANCE_M,
) -> PourPoses:
    """The poses of a pour from the object at X_WO (upright, as held), its outflow to point tilt_below_rad below the
    horizontal, its tip `clearance` (m) above the opening's centre; pivot_O (3,): the turn's centre (the grasps'
    midpoint), in O.

    Raises:
        ValueError: an outflow nearly vertical (no direction to tilt it in).
    """
    outflow = tool_O.moved(X_WO).axis
    run = np.linalg.norm(outflow[:2])
    if run < MIN_OUTFLOW_RUN:
        raise ValueError(f"the outflow {np.round(outflow, 2)} is nearly vertical: no direction to pour in")
    across = np.cross([0.0, 0.0, 1.0], np.append(outflow[:2] / run, 0.0))  # the tilt's axis: the spout down for > 0
    tilt = outflow_elevation(X_WO, tool_O) + tilt_below_rad
    pivot_W = X_WO.multiply(np.asarray(pivot_O, dtype=float))
    turn = RigidTransform(pivot_W) @ RigidTransform(RotationMatrix(AngleAxis(tilt, across))) @ RigidTransform(-pivot_W)
    tilted = turn @ X_WO
    target = opening.centre_W + [0.0, 0.0, clearance]
    shift = RigidTransform(target - tilted.multiply(tool_O.tip))
    return PourPoses(shift @ X_WO, shift @ tilted, float(tilt))
