"""Continuous collision checks of straight joint-space segments on the sphere model: a swept bound, no gaps.

Along a segment q(s) = q_a + s (q_b - q_a), s in [0, 1], a point fixed to the robot moves at most
L = sum_j |q_b,j - q_a,j| r_j, r_j bounding its distance from joint j's axis in every configuration
(sweep_radii). A clearance that is g_a and g_b at the segment's ends and changes at most as fast as the
points move (a distance to the scene, Lipschitz constant `lipschitz`; the gap between two spheres, both
moving) is at least (g_a + g_b - L) / 2 anywhere along it. Where that bound does not prove a segment clear,
it is halved and each half judged the same way (segments_clear), until a state in collision is found or
the halves are shorter than MIN_STEP_RAD (not proven: not clear).
"""

from collections.abc import Callable

import numpy as np

from systems.planning.kinematics import BatchedKinematics

MIN_STEP_RAD = 1e-4  # the shortest half judged; a clearance the bound cannot prove at this length is not clear
MAX_STATES = 20000  # states a check evaluates at most (then not proven: not clear)


def sweep_radii(kinematics: BatchedKinematics, position: int, points_B: np.ndarray) -> np.ndarray:
    """For points fixed to the tracked link at `position` (P x 3, m, in its body frame): an upper bound (P x n, m)
    on each point's distance from each planned joint's axis, in any configuration; 0 for joints that do not
    move it.

    The link's own joint: the exact distance (it does not change as the joint turns). An ancestor joint: the
    distance from its axis to the origin of the next joint down the chain (fixed in the ancestor's body), plus
    a bound on that origin's distance from the point (the chain's lengths, each rigid).
    """
    points_B = np.asarray(points_B, float)
    radii = np.zeros((len(points_B), kinematics.dof))
    anchor = np.column_stack([points_B, np.ones(len(points_B))])  # homogeneous, in the current link's body frame
    reach = np.zeros(len(points_B))  # bound on the distance from the anchor to the point, m
    while position >= 0:
        link = kinematics.links[position]
        if link.arm_dof >= 0:
            in_joint = anchor @ link.X_MB.T[:, :3]  # the anchor in the joint's frame: its origin is on the axis
            along = in_joint @ link.axis
            off_axis = np.linalg.norm(in_joint - along[:, None] * link.axis, axis=1)
            radii[:, link.arm_dof] = off_axis + reach
            reach = reach + np.linalg.norm(in_joint, axis=1)
            anchor = np.broadcast_to(link.X_PF[:, 3], anchor.shape)  # this joint's origin, in the parent's frame
        else:
            anchor = anchor @ link.X_PF.T  # a link fixed to its parent: X_PF is its constant pose there
        position = link.parent
    return radii


def segments_clear(
    theta: np.ndarray, gaps: Callable[[np.ndarray], np.ndarray], rates: np.ndarray, required: float
) -> bool:
    """Whether every straight segment between consecutive configurations of theta (N x n, rad) stays clear:
    each clearance above `required` (m) all along it.

    gaps(q): the clearances (K x C, m) at configurations q (K x n); rates (C x n): how fast each clearance can
    change per radian of each joint (m / rad; sweep_radii times the scene's Lipschitz constant, or the sum of
    two spheres' for the gap between them).
    """
    theta = np.asarray(theta, float)
    at = gaps(theta)
    if at.min() <= required:
        return False
    q_a, q_b, g_a, g_b = theta[:-1], theta[1:], at[:-1], at[1:]
    evaluated = len(theta)
    while len(q_a):
        swept = np.abs(q_b - q_a) @ rates.T  # K x C: how far each clearance may fall along each segment
        unproven = np.any(g_a + g_b - swept <= 2 * required, axis=1)
        q_a, q_b, g_a, g_b = q_a[unproven], q_b[unproven], g_a[unproven], g_b[unproven]
        if not len(q_a):
            return True
        if np.abs(q_b - q_a).max() < MIN_STEP_RAD or evaluated + len(q_a) > MAX_STATES:
            return False
        middle = 0.5 * (q_a + q_b)
        g_m = gaps(middle)
        evaluated += len(middle)
        if g_m.min() <= required:
            return False
        q_a, q_b = np.concatenate([q_a, middle]), np.concatenate([middle, q_b])
        g_a, g_b = np.concatenate([g_a, g_m]), np.concatenate([g_m, g_b])
    return True
