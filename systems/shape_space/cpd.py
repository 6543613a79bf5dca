"""Coherent Point Drift (Myronenko & Song, 2010): rigid and non-rigid, vectorised numpy.

Notation follows the paper: the target X (N x D) is data, the source Y (M x D) the
centroids of a Gaussian mixture that moves onto it. w in [0, 1) is the weight of the
uniform outlier component.

Non-rigid CPD moves Y to T = Y + G W, with G the Gaussian kernel (width beta) over Y.
The M-step's M x M linear system is solved through a low-rank eigendecomposition of G
(its top MAX_RANK eigenpairs, computed once) and the Woodbury identity, so an iteration
costs O(M N + M K^2) instead of O(M^3).
"""

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy.spatial.distance import cdist

LOW_RANK_TOLERANCE = 1e-10  # drops only numerically non-positive eigenvalues
MAX_RANK = 150  # the field's smooth kernel has few eigenvalues worth keeping


def _check(points: np.ndarray, name: str) -> np.ndarray:
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[0] < 4 or points.shape[1] not in (2, 3):
        raise ValueError(f"{name} must be an N x 2 or N x 3 array of at least 4 points, got shape {points.shape}")
    if not np.all(np.isfinite(points)):
        raise ValueError(f"{name} contains NaN or infinite coordinates")
    return points


def thinned(points: np.ndarray, count: int) -> np.ndarray:
    """At most `count` of the points (in their order), a seeded random choice."""
    if len(points) <= count:
        return points
    return points[np.sort(np.random.default_rng(0).choice(len(points), count, replace=False))]


def _initial_sigma2(X, Y) -> float:
    N, D = X.shape
    M = Y.shape[0]
    return float((M * np.sum(X**2) + N * np.sum(Y**2) - 2 * np.sum(X.sum(0) * Y.sum(0))) / (D * M * N))


def squared_distances(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The M x N squared distances between the rows of A (M x D) and of B (N x D), in float32 as |a|^2 + |b|^2 -
    2 a.b (fast; their rounding grows with |a|^2 and |b|^2: centre both first where the points lie far from 0)."""
    A32, B32 = np.asarray(A, np.float32), np.asarray(B, np.float32)
    squared = A32 @ B32.T
    squared *= -2.0
    squared += (A32**2).sum(1)[:, None]
    squared += (B32**2).sum(1)[None, :]
    return np.maximum(squared, 0.0, out=squared)


# exp(-70) = 4e-31, above float32's smallest normal number (exp(-87.3)); M such weights (M <= 1e4) beside the
# outlier term (at least 1e-13 for w >= 0.01 and sigma^2 >= 1e-8 m^2) change no float64 sum.
EXPONENT_FLOOR = -70.0


def gmm_posteriors(squared: np.ndarray, sigma2: float, w: float, dimension: int) -> np.ndarray:
    """Posteriors of M isotropic Gaussian centroids (variance sigma2) for N points in `dimension`-D, with a uniform
    outlier component of weight w, from the M x N squared distances: overwritten in place, returned.

    A point far from every centroid (its column underflows to 0) just contributes nothing. With an outlier
    component, the exponents are floored at EXPONENT_FLOOR: the weights below it are nothing beside the outlier
    term, and computed they would be subnormal numbers, on which every pass over P is 10-30 times slower.
    """
    M, N = squared.shape
    P = squared
    P *= squared.dtype.type(-0.5 / sigma2)
    if w > 0:
        np.maximum(P, EXPONENT_FLOOR, out=P)
    np.exp(P, out=P)
    c = (2 * np.pi * sigma2) ** (dimension / 2) * w / (1 - w) * M / N if w > 0 else 0.0
    denominator = P.sum(0, dtype=np.float64) + c
    inverse = np.divide(1.0, denominator, out=np.zeros_like(denominator), where=denominator > 0)
    P *= np.minimum(inverse, np.finfo(P.dtype).max).astype(P.dtype)
    return P


@dataclass
class PosteriorSums:
    """The E-step's sums over the posteriors P (M x N) of M centroids for N points, in float64."""

    P1: np.ndarray  # P 1 (M,): each centroid's total weight
    Pt1: np.ndarray  # P^T 1 (N,): each point's weight on the centroids (1 less its outlier share)
    PX: np.ndarray  # P X (M x D): each centroid's weighted sum of the points


def _e_step(X, T, sigma2, w) -> PosteriorSums:
    """The sums of the posteriors P (M x N) of the centroids T for the points X.

    The M x N work runs in float32 (twice the speed; the posteriors need no more), the
    sums come back in float64.
    """
    X32 = X.astype(np.float32)
    P = gmm_posteriors(squared_distances(T, X32), sigma2, w, X.shape[1])
    return PosteriorSums(P.sum(1, dtype=np.float64), P.sum(0, dtype=np.float64), (P @ X32).astype(np.float64))


@dataclass
class RigidResult:
    R: np.ndarray  # D x D rotation
    t: np.ndarray  # D translation
    s: float  # scale (1 unless estimated)
    transformed: np.ndarray  # s R y + t for every source point
    sigma2: float
    iterations: int

    def transform(self, points: np.ndarray) -> np.ndarray:
        """s R p + t for any points (K x D)."""
        return self.s * np.atleast_2d(points) @ self.R.T + self.t


def rigid_cpd(
    source: np.ndarray,
    target: np.ndarray,
    w: float = 0.0,
    estimate_scale: bool = False,
    max_iterations: int = 100,
    tolerance: float = 1e-5,
    upright: bool = False,
) -> RigidResult:
    """Rigid (optionally similarity) CPD moving `source` onto `target`.

    Stops when sigma^2 changes by less than `tolerance` relative to its value. upright (3D): turn only
    about the z axis and shift only along x and y (both clouds stand upright on the same plane).
    """
    X, Y = _check(target, "target"), _check(source, "source")
    D = X.shape[1]
    R, t, s = np.eye(D), np.zeros(D), 1.0
    sigma2 = _initial_sigma2(X, Y)
    T = Y
    for iteration in range(1, max_iterations + 1):  # noqa: B007 (the count is returned)
        sums = _e_step(X, T, sigma2, w)
        P1, Pt1, PX = sums.P1, sums.Pt1, sums.PX
        Np = P1.sum()
        mu_x, mu_y = Pt1 @ X / Np, P1 @ Y / Np
        A = PX.T @ Y - Np * np.outer(mu_x, mu_y)  # = X_hat^T P^T Y_hat
        if upright:  # the yaw maximising trace(A^T R_z(yaw))
            yaw = np.arctan2(A[1, 0] - A[0, 1], A[0, 0] + A[1, 1])
            R = np.eye(D)
            R[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
        else:
            U, _, Vt = np.linalg.svd(A)
            C = np.eye(D)
            C[-1, -1] = np.linalg.det(U @ Vt)
            R = U @ C @ Vt
        trace_AR = np.trace(A.T @ R)
        y_spread = np.sum(P1 * (Y**2).sum(1)) - Np * mu_y @ mu_y
        if estimate_scale:
            s = trace_AR / y_spread
        t = mu_x - s * R @ mu_y
        if upright:
            t[2] = 0.0  # R and t along x, y leave z alone: the best shift in x, y is unchanged
        x_spread = np.sum(Pt1 * (X**2).sum(1)) - Np * mu_x @ mu_x
        previous = sigma2
        sigma2 = max((x_spread - 2 * s * trace_AR + s * s * y_spread) / (Np * D), 1e-12)
        T = s * Y @ R.T + t
        if abs(previous - sigma2) <= tolerance * previous:
            break
    return RigidResult(R, t, s, T, sigma2, iteration)


INTERPOLATION_RIDGE = 1e-3  # relative to the kernel matrix's largest eigenvalue


class FieldInterpolator:
    """Gaussian-kernel ridge interpolation of vector fields known at fixed anchor points (factorised once)."""

    def __init__(self, anchors: np.ndarray, beta: float):
        self.anchors, self.beta = anchors, beta
        G = gaussian_kernel(anchors, anchors, beta)
        ridge = INTERPOLATION_RIDGE * np.abs(G).sum(1).max()  # the largest eigenvalue is at most this
        self.factor = scipy.linalg.cho_factor(G + ridge * np.eye(len(G)))

    def __call__(self, values: np.ndarray, points: np.ndarray) -> np.ndarray:
        """The field with `values` (M x D) at the anchors, evaluated at `points` (K x D)."""
        coefficients = scipy.linalg.cho_solve(self.factor, values)
        return gaussian_kernel(np.atleast_2d(points), self.anchors, self.beta) @ coefficients


def top_eigenpairs(G: np.ndarray, rank: int, power_iterations: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """The `rank` largest eigenpairs (ascending) of a symmetric PSD matrix, by randomised subspace iteration.

    Exact (numpy's eigh) when the matrix is not much larger than the rank.
    """
    M = len(G)
    if M <= 2 * rank:
        return np.linalg.eigh(G)
    basis = G @ np.random.default_rng(0).standard_normal((M, rank + 10))
    for _ in range(power_iterations):
        basis, _ = np.linalg.qr(basis)
        basis = G @ basis
    basis, _ = np.linalg.qr(basis)
    eigenvalues, vectors = np.linalg.eigh(basis.T @ G @ basis)
    return eigenvalues[-rank:], (basis @ vectors)[:, -rank:]


def gaussian_kernel(A: np.ndarray, B: np.ndarray, beta: float) -> np.ndarray:
    return np.exp(-cdist(A, B, "sqeuclidean") / (2 * beta**2))


@dataclass
class DeformableResult:
    source: np.ndarray  # Y, M x D
    beta: float
    transformed: np.ndarray  # Y + G W
    sigma2: float
    iterations: int

    def displacement(self, points: np.ndarray) -> np.ndarray:
        """The displacement field at any points (K x D), interpolated from the source's displacements.

        A Gaussian-kernel ridge interpolation (width beta) of V = T - Y: W itself grows without
        bound as sigma^2 -> 0 on a near-singular G, its smooth interpolant does not.
        """
        return FieldInterpolator(self.source, self.beta)(self.transformed - self.source, points)

    def warp(self, points: np.ndarray) -> np.ndarray:
        points = np.atleast_2d(points)
        return points + self.displacement(points)


def deformable_cpd(
    source: np.ndarray,
    target: np.ndarray,
    beta: float = 2.0,
    lam: float = 2.0,
    w: float = 0.0,
    max_iterations: int = 100,
    tolerance: float = 1e-5,
    landmarks: tuple[np.ndarray, np.ndarray] | None = None,
    landmark_weight: float = 20.0,
    initial_sigma2: float | None = None,
) -> DeformableResult:
    """Non-rigid CPD moving `source` onto `target` by a smooth displacement field.

    Args:
        beta: width of the Gaussian kernel of the field, in the points' units.
        lam: the field's smoothness weight (lambda).
        w: outlier weight in [0, 1).
        tolerance: stop when sigma^2 changes by less than this, relative.
        landmarks: optional known correspondences (L x D points in the source's frame, L x D
            where the field must take them), e.g. a grasp point annotated on both shapes. They
            join the field's points and pull on it like `landmark_weight` fully matched target
            points each; the result's source and transformed leave them out.
        initial_sigma2: the mixture's starting variance; default: the clouds' whole spread (they may
            start far apart). For clouds already aligned give a small one (a few cm squared): the wide
            early iterations otherwise pull every point to the middle and let it settle anywhere on the
            surface, and the field slides along it (37 mm RMS between two copies of one drill).
    """
    X, Y = _check(target, "target"), _check(source, "source")
    M, D = Y.shape
    if landmarks is not None:
        landmark_source, landmark_target = (np.asarray(a, dtype=float).reshape(-1, D) for a in landmarks)
        if len(landmark_source) != len(landmark_target):
            raise ValueError("landmarks: as many source as target points are needed")
        Y = np.vstack([Y, landmark_source])
        pull = np.full(len(landmark_source), landmark_weight)
        pull_X = landmark_weight * landmark_target
    G = gaussian_kernel(Y, Y, beta)
    eigenvalues, Q = top_eigenpairs(G, MAX_RANK)
    keep = eigenvalues > LOW_RANK_TOLERANCE * eigenvalues[-1]
    eigenvalues, Q = eigenvalues[keep], Q[:, keep]
    T = Y.copy()
    sigma2 = _initial_sigma2(X, Y[:M]) if initial_sigma2 is None else float(initial_sigma2)
    for iteration in range(1, max_iterations + 1):  # noqa: B007 (the count is returned)
        sums = _e_step(X, T[:M], sigma2, w)
        P1, PX = sums.P1, sums.PX
        if landmarks is not None:
            # The landmarks are no mixture centroids: each is pulled to its own fixed target.
            P1, PX = np.concatenate([P1, pull]), np.vstack([PX, pull_X])
        # Solve (G + lam sigma2 dP1^-1) W = dP1^-1 P X - Y, with G = Q L Q^T and Woodbury.
        P1 = np.maximum(P1, 1e-12)
        a = lam * sigma2 / P1  # the diagonal A
        b = PX / P1[:, None] - Y
        A_inv_b = b / a[:, None]
        A_inv_Q = Q / a[:, None]
        core = np.diag(1.0 / eigenvalues) + Q.T @ A_inv_Q
        W = A_inv_b - A_inv_Q @ np.linalg.solve(core, Q.T @ A_inv_b)
        T = Y + Q @ (eigenvalues[:, None] * (Q.T @ W))
        # sigma^2 from the mixture's points only.
        P1, PX, Tm = P1[:M], PX[:M], T[:M]
        Np = P1.sum()
        previous = sigma2
        sigma2 = float(np.sum(sums.Pt1 * (X**2).sum(1)) - 2 * np.sum(PX * Tm) + np.sum(P1 * (Tm**2).sum(1))) / (Np * D)
        sigma2 = max(sigma2, 1e-12)
        if abs(previous - sigma2) <= tolerance * previous:
            break
    return DeformableResult(Y[:M], beta, T[:M], sigma2, iteration)
