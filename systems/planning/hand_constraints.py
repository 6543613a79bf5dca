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


def rotation_error(R_desired: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Small-angle rotation vectors (B x 3) of R_desired^T R for rotations R (B x 3 x 3)."""
    R_error = np.einsum("ji,bjk->bik", R_desired, R)
    return 0.5 * np.column_stack(
        [R_error[:, 2, 1] - R_error[:, 1, 2], R_error[:, 0, 2] - R_error[:, 2, 0], R_error[:, 1, 0] - R_error[:, 0, 1]]
    )


@dataclass
class HandConstraints:
    """The constraints of one plan: the closure (X_E1E2, 4 x 4) and/or the hands' orientations (R_WE, two 3 x 3)."""

    end_effectors: EndEffectors
    lower: np.ndarray  # the 14 joints' limits, rad: projected configurations stay within them
    upper: np.ndarray
    X_E1E2: np.ndarray | None = None
    R_WE: list | None = None
    upright_only: bool = False

    def error_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """e (B x E) and de/dq (B x E x 14) at configurations q (B x 14)."""
        (X1, X2), (J1, J2) = self.end_effectors.jacobians(q)
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
        """Configurations (B x 14) moved towards e = 0 by `steps` damped Gauss-Newton steps, within the limits."""
        q = np.atleast_2d(q).copy()
        for _ in range(steps):
            error, jacobian = self.error_and_jacobian(q)
            JT = np.swapaxes(jacobian, 1, 2)
            damped = jacobian @ JT + DAMPING * np.eye(error.shape[1])
            q -= (JT @ np.linalg.solve(damped, error[..., None]))[..., 0]
            np.clip(q, self.lower, self.upper, out=q)
        return q

    def tangent(self, q: np.ndarray, displacements: np.ndarray) -> np.ndarray:
        """Displacements (R x B x 14, R sets of one per configuration of q, B x 14) with their components that
        change e removed: dq - J^T (J J^T)^-1 J dq at each configuration."""
        _, jacobian = self.error_and_jacobian(q)
        JT = np.swapaxes(jacobian, 1, 2)
        damped = jacobian @ JT + DAMPING * np.eye(jacobian.shape[1])
        change = np.einsum("beq,rbq->rbe", jacobian, displacements)
        correction = np.linalg.solve(damped[None], change[..., None])[..., 0]
        return displacements - np.einsum("bqe,rbe->rbq", JT, correction)
