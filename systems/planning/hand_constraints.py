"""The hands' equality constraints of a held move, their Jacobians, and the two ways STOMP respects them.

  closure:     the right grasp frame's pose in the left one's stays X_E1E2 (both hands hold one object);
  orientation: each hand's world orientation stays R_WE (or, upright_only, its tilt: the vertical seen
               from the hand).

The error e(q) stacks, per configuration, the closure's translation (m, in the left frame) and rotation
(small-angle rotation vector, rad) and each hand's orientation error. Its Jacobian de/dq is analytic, from
the end-effectors' geometric Jacobians (systems/planning/kinematics.py). With it:

  project(q):     damped Gauss-Newton steps to e = 0, the smallest joint change each step;
  tangent(q, dq): joint displacements dq moved into the constraints' tangent space (the null space of
                  de/dq): a small move along it keeps e = 0 to first order.
"""

from dataclasses import dataclass

import numpy as np

from systems.planning.kinematics import EndEffectors, relative_pose, skew

DAMPING = 1e-6  # of the Gauss-Newton and null-space solves, in the error's squared units
OFFSET_WEIGHT = 0.3  # of a move's position error (m) against the constraints' errors (m, rad)
MAX_STEP = 0.2  # rad: the largest joint change of one moving step (the full step overshoots near the reach's edge)


def rotation_error(R_desired: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Small-angle rotation vectors (B x 3) of R_desired^T R for rotations R (B x 3 x 3); R_desired is one rotation
    (3 x 3) or one per configuration (B x 3 x 3)."""
    R_error = np.swapaxes(R_desired, -1, -2) @ R
    return 0.5 * (R_error[:, _ROWS, _COLUMNS] - R_error[:, _COLUMNS, _ROWS])


_ROWS, _COLUMNS = np.array([2, 0, 1]), np.array([1, 2, 0])  # the entries (2, 1), (0, 2), (1, 0) of a rotation


@dataclass
class HandConstraints:
    """The constraints of one plan: the closure (X_E1E2, 4 x 4) and/or the hands' orientations (R_WE, two 3 x 3)."""

    end_effectors: EndEffectors
    lower: np.ndarray  # the planned joints' limits, rad: projected configurations stay within them
    upper: np.ndarray
    X_E1E2: np.ndarray | None = None
    R_WE: list | None = None
    upright_only: bool = False

    def error_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """e (B x E) and de/dq (B x E x n) at configurations q (B x n)."""
        return self.error_and_jacobian_from(*self.end_effectors.jacobians(q))

    def error_and_jacobian_from(self, poses, jacobians) -> tuple[np.ndarray, np.ndarray]:
        """error_and_jacobian() from both end-effectors' poses and Jacobians (EndEffectors.jacobians())."""
        (X1, X2), (J1, J2) = poses, jacobians
        errors, jacobians = [], []
        if self.X_E1E2 is not None:
            R1_T = np.swapaxes(X1[:, :3, :3], 1, 2)
            X12 = relative_pose(X1, X2)
            errors.append(X12[:, :3, 3] - self.X_E1E2[:3, 3])
            errors.append(rotation_error(self.X_E1E2[:3, :3], X12[:, :3, :3]))
            # d/dt R1^T (p2 - p1) = R1^T (v2 - v1 + (p2 - p1) x w1); the relative rotation's rate is R1^T (w2 - w1).
            offset = skew(X2[:, :3, 3] - X1[:, :3, 3])
            jacobians.append(R1_T @ (J2[:, 3:] - J1[:, 3:] + offset @ J1[:, :3]))
            jacobians.append(self.X_E1E2[:3, :3].T @ (R1_T @ (J2[:, :3] - J1[:, :3])))
        if self.R_WE is not None:
            for X, J, R in zip((X1, X2), (J1, J2), self.R_WE, strict=True):
                if self.upright_only:
                    # The vertical seen from the hand, R^T e_z, turns at R^T (e_z x w).
                    errors.append(X[:, 2, :3] - R[2])
                    jacobians.append(np.swapaxes(X[:, :3, :3], 1, 2) @ skew(np.array([0.0, 0.0, 1.0])) @ J[:, :3])
                else:
                    errors.append(rotation_error(R, X[:, :3, :3]))
                    jacobians.append(R.T @ J[:, :3])
        return np.concatenate(errors, axis=1), np.concatenate(jacobians, axis=1)

    def project(self, q: np.ndarray, steps: int) -> np.ndarray:
        """Configurations (B x n) moved towards e = 0 by `steps` damped Gauss-Newton steps, within the limits."""
        q = np.atleast_2d(q).copy()
        for _ in range(steps):
            q = bounded_step(q, *self.error_and_jacobian(q), self.lower, self.upper)
        return q

    def moved(self, q: np.ndarray, offsets_W: np.ndarray, steps: int = 10) -> np.ndarray:
        """Configurations (B x n) with the left grasp frame (and the object held) moved by offsets_W (B x 3, m, in
        W) from q where the constraints allow it: damped Gauss-Newton steps of the constraints' error stacked with
        the offset's (weighted OFFSET_WEIGHT: the constraints come first), each joint change at most MAX_STEP,
        then `steps` // 2 plain projection steps."""
        q = np.atleast_2d(q).copy()
        target = None
        for _ in range(steps):
            poses, jacobians = self.end_effectors.jacobians(q)
            error, jacobian = self.error_and_jacobian_from(poses, jacobians)
            X1, J1 = poses[0], jacobians[0]
            if target is None:  # (from the poses at the given q)
                target = X1[:, :3, 3] + offsets_W
            error = np.concatenate([error, OFFSET_WEIGHT * (X1[:, :3, 3] - target)], axis=1)
            jacobian = np.concatenate([jacobian, OFFSET_WEIGHT * J1[:, 3:]], axis=1)
            q = bounded_step(q, error, jacobian, self.lower, self.upper, MAX_STEP)
        return self.project(q, steps // 2)

    def tangent(self, q: np.ndarray, displacements: np.ndarray) -> np.ndarray:
        """Displacements (R x B x n, R sets of one per configuration of q, B x n) with their components that
        change e removed: dq - J^T (J J^T)^-1 J dq at each configuration."""
        _, jacobian = self.error_and_jacobian(q)
        JT = np.swapaxes(jacobian, 1, 2)
        damped = jacobian @ JT + DAMPING * np.eye(jacobian.shape[1])
        change = np.einsum("beq,rbq->rbe", jacobian, displacements)
        correction = np.linalg.solve(damped[None], change[..., None])[..., 0]
        return displacements - np.einsum("bqe,rbe->rbq", JT, correction)


def bounded_step(
    q: np.ndarray, error: np.ndarray, jacobian: np.ndarray, lower, upper, max_step: float | None = None
) -> np.ndarray:
    """One damped Gauss-Newton step towards error = 0 (B x E, Jacobian B x E x n), scaled to at most max_step
    (rad) per joint if given, within the joints' limits: a joint the step would push beyond its limit is pinned
    at the limit and the rest of the error solved by the other joints (up to 3 times; clipped after). Clipping
    alone stalls where every step pushes a joint beyond its limit again."""
    lower, upper = np.broadcast_to(lower, q.shape), np.broadcast_to(upper, q.shape)  # (per joint, or B x n)
    moved = np.empty_like(q)
    rows = np.arange(len(q))  # the configurations still being solved: those a step pushed beyond a limit
    pinned = np.zeros_like(q)  # their pinned joints' moves to their limits
    free = np.ones_like(q)
    residual, J = error, jacobian  # (nothing pinned yet)
    for _ in range(4):
        JT = np.swapaxes(J, 1, 2)
        damped = J @ JT + DAMPING * np.eye(error.shape[1])
        step = (JT @ np.linalg.solve(damped, residual[..., None]))[..., 0]
        if max_step is not None:
            step *= np.minimum(1.0, max_step / np.maximum(np.abs(step).max(axis=1, keepdims=True), 1e-12))
        moved[rows] = q[rows] + pinned - step
        beyond = (moved[rows] < lower[rows]) | (moved[rows] > upper[rows])
        again = beyond.any(axis=1)
        if not again.any():
            break
        # Only the configurations with a joint newly pinned are solved again (the others' steps would not change).
        rows, beyond = rows[again], beyond[again]
        pinned = np.where(beyond, np.clip(moved[rows], lower[rows], upper[rows]) - q[rows], pinned[again])
        free = free[again] * ~beyond
        residual = error[rows] + np.einsum("beq,bq->be", jacobian[rows], pinned)
        J = jacobian[rows] * free[:, None, :]
    return np.clip(moved, lower, upper)
