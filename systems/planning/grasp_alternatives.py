"""A grasp is a family: a parallel hand holds a handle (along the grasp frame's x_G) from around it as well as
from the annotated side, and anywhere along it where the fingers still close on the handle alone.

Each alternative is a transform X_GG' of the grasp frame G on the right: rolled about x_G through G (the
approach axis z_G turns about the handle), or slid along x_G. A pre-grasp P follows its grasp:
P' = G X_GG' X_GP, as a transform of P on the right X_GP^-1 X_GG' X_GP.
"""

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

# Rolls about the handle axis (rad), tried in turn where the grasp as perceived is out of a hand's reach.
GRASP_ROLLS = (0.35, -0.35, 0.7, -0.7)
# Slides along the handle axis (m), tried after the rolls; only those handle_slides() finds on the handle.
HANDLE_SLIDES = (0.015, -0.015, 0.03, -0.03)
# The fingers span 6 cm along the handle (sdf/centauro/hand.sdf): the handle must reach this far either side of
# a slid grasp (m).
FINGER_HALF_SPAN = 0.03
# The object's points this near the handle's axis (m) are what the fingers may meet closing on it; among them a
# point farther from the axis than the handle's surface at the grasp (by more than the tolerance, m) is another
# part (a housing, a knob, a bend of a curved handle) where the slid fingers would close on something else.
HANDLE_NEIGHBOURHOOD = 0.06
HANDLE_RADIUS_TOLERANCE = 0.005
# Along the fingers' span no gap in the object's points may be longer than this (m): the handle is there.
MAX_POINT_GAP = 0.012


def handle_slides(points_W: np.ndarray, X_WG: RigidTransform, slides=HANDLE_SLIDES) -> list[float]:
    """Those of `slides` (m along x_G) at which the fingers close on the handle alone, judged on the object's
    points (N x 3 in W: the registered shape, or the true surface): over the fingers' span about the slid grasp
    the points near the axis are all on the handle's surface (no farther from the axis than it is at G), with no
    gap. An empty list where the points show no handle at G."""
    if points_W is None or len(points_W) == 0:
        return []
    p_G = X_WG.inverse().multiply(np.asarray(points_W, float).T).T
    along, radius = p_G[:, 0], np.hypot(p_G[:, 1], p_G[:, 2])
    near = radius < HANDLE_NEIGHBOURHOOD
    along, radius = along[near], radius[near]
    at_grasp = np.abs(along) < 0.5 * MAX_POINT_GAP
    if not at_grasp.any():
        return []
    surface = np.percentile(radius[at_grasp], 90)  # the handle's radius at the grasp
    kept = []
    for slide in slides:
        span = np.abs(along - slide) <= FINGER_HALF_SPAN
        if not span.any() or radius[span].max() > surface + HANDLE_RADIUS_TOLERANCE:
            continue
        stations = np.sort(np.concatenate([along[span], [slide - FINGER_HALF_SPAN, slide + FINGER_HALF_SPAN]]))
        if np.diff(stations).max() <= MAX_POINT_GAP:
            kept.append(slide)
    return kept


def grasp_alternatives(X_WG: RigidTransform, points_W: np.ndarray | None) -> list[RigidTransform]:
    """X_GG' of one hand's grasps in the order they are tried: G itself, rolled by each of GRASP_ROLLS, then slid
    by each of handle_slides() (on the object's points, N x 3 in W; none without them)."""
    rolls = [RigidTransform(RotationMatrix.MakeXRotation(angle)) for angle in GRASP_ROLLS]
    slides = [RigidTransform([slide, 0.0, 0.0]) for slide in handle_slides(points_W, X_WG)]
    return [RigidTransform(), *rolls, *slides]


def pregrasp_alternatives(X_GP: RigidTransform, alternatives: list[RigidTransform]) -> list[RigidTransform]:
    """The pre-grasp P (at X_GP from its grasp) as it follows each alternative X_GG', as transforms of P on the
    right (P -> P')."""
    return [X_GP.inverse() @ X_GG @ X_GP for X_GG in alternatives]
