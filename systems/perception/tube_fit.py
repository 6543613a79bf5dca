"""A straight piece of tube fitted to a handle's seen points: its axis, radius and seen extent.

A handle is locally a tube. A depth camera sees its near half: a strip of points on a half cylinder, with a few
millimetres of noise and, at its silhouette, flying pixels. fit_tube() takes the points within TUBE_REACH of a
seed point (where the grasp is expected), starts from two guesses of the axis (the points' longest principal
direction, and the direction their surface normals leave out) and fits a cylinder to them by robust least squares
(soft-L1 residuals, so that a stray point pulls little): the distance of each point from the axis minus the radius,
beside a weak prior on the radius (the tube of a handle a hand holds). The piece is straight: along a curved handle
(an arch, a loop) the fit is the tangent tube at the seed, which is why TUBE_REACH is short against the bends of
real handles (4 cm and more).

All points and directions are in one frame (W in the pick), metres.
"""

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

TUBE_REACH = 0.035  # m: the points within this of the seed are fitted
RADIUS_GUESS = 0.013  # m: a handle's tube radius without other knowledge (handles are 1.6-4 cm thick)
RADIUS_RANGE = (0.005, 0.03)  # m: a fitted radius outside this is no handle a hand holds
RADIUS_PRIOR_WEIGHT = 0.2  # of a point's residual, per RADIUS_GUESS of radius off the guess: a weak prior
NORMAL_NEIGHBOURS = 12
MIN_POINTS = 25  # fewer points near the seed: nothing to fit
LOSS_SCALE = 0.003  # m: residuals beyond this count less and less (soft-L1)


@dataclass(frozen=True)
class Tube:
    """A straight tube: the foot of the seed on its axis, the axis (unit), the radius, where the fitted points lie
    along the axis from that foot (lowest, highest; m), how well they lie on the surface, and how many there were."""

    point: np.ndarray
    axis: np.ndarray
    radius: float
    extent: tuple[float, float]
    rms_m: float
    points: int

    def along(self, point: np.ndarray) -> float:
        """The signed distance (m) along the axis from the tube's point to the foot of `point`."""
        return float(np.dot(np.asarray(point, float) - self.point, self.axis))


def fit_tube(points: np.ndarray, viewpoint: np.ndarray, seed: np.ndarray, reach: float = TUBE_REACH) -> Tube | None:
    """The tube through the points (N x 3, m) within `reach` of `seed` (3,), seen from `viewpoint` (3,); None where
    fewer than MIN_POINTS lie there or no fit has a radius within RADIUS_RANGE."""
    points = np.asarray(points, float)
    points = points[np.all(np.isfinite(points), axis=1)]
    seed = np.asarray(seed, float)
    near = points[np.linalg.norm(points - seed, axis=1) < reach]
    if len(near) < MIN_POINTS:
        return None
    centroid = near.mean(axis=0)
    towards_camera = np.asarray(viewpoint, float) - centroid
    towards_camera /= np.linalg.norm(towards_camera)
    fits = [_fitted(near, centroid, axis, towards_camera) for axis in _axis_guesses(near, towards_camera)]
    fits = [f for f in fits if f is not None]
    if not fits:
        return None
    axis, point, radius, residuals = min(fits, key=lambda f: np.mean(np.abs(f[3])))
    foot = point + np.dot(seed - point, axis) * axis
    along = (near - foot) @ axis
    low, high = np.percentile(along, [2, 98])
    return Tube(foot, axis, radius, (float(low), float(high)), float(np.sqrt(np.mean(residuals**2))), len(near))


def _axis_guesses(points: np.ndarray, towards_camera: np.ndarray) -> list[np.ndarray]:
    """Two first guesses of the axis: the longest principal direction of the points, and the direction least in
    their estimated normals (a cylinder's normals all lie across its axis)."""
    centred = points - points.mean(axis=0)
    _, vectors = np.linalg.eigh(centred.T @ centred)
    longest = vectors[:, -1]
    k = min(NORMAL_NEIGHBOURS, len(points))
    _, neighbours = cKDTree(points).query(points, k)
    local = points[neighbours] - points[neighbours].mean(axis=1, keepdims=True)
    _, local_vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))
    normals = local_vectors[:, :, 0]
    _, normal_vectors = np.linalg.eigh(normals.T @ normals)
    across_normals = normal_vectors[:, 0]
    guesses = [longest]
    if abs(np.dot(across_normals, longest)) < 0.95:
        guesses.append(across_normals)
    return guesses


def _fitted(points: np.ndarray, centroid: np.ndarray, axis0: np.ndarray, towards_camera: np.ndarray):
    """(axis, a point on it, radius, residuals) of the cylinder fitted from the first guess `axis0`; None where the
    radius leaves RADIUS_RANGE. Parameters: the axis turned from axis0 about two directions across it, the axis's
    point moved across it from behind the centroid, the radius."""
    u = np.cross(axis0, towards_camera)
    if np.linalg.norm(u) < 1e-6:  # the axis points at the camera: any direction across it will do
        u = np.cross(axis0, [1.0, 0.0, 0.0] if abs(axis0[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis0, u)
    # The visible half's centroid lies about 2r/pi nearer the camera than the axis.
    behind = -np.dot(towards_camera, v) * v - np.dot(towards_camera, u) * u
    behind /= max(np.linalg.norm(behind), 1e-9)
    start = centroid + (2.0 / np.pi) * RADIUS_GUESS * behind

    def cylinder(x):
        axis = axis0 + x[0] * u + x[1] * v
        axis = axis / np.linalg.norm(axis)
        point = start + x[2] * u + x[3] * v
        return axis, point, x[4]

    def residuals(x):
        axis, point, radius = cylinder(x)
        offset = points - point
        across = offset - np.outer(offset @ axis, axis)
        distance = np.sqrt(np.einsum("ij,ij->i", across, across))
        prior = RADIUS_PRIOR_WEIGHT * LOSS_SCALE * (radius - RADIUS_GUESS) / RADIUS_GUESS
        return np.append(distance - radius, prior * np.sqrt(len(points)))

    solution = least_squares(
        residuals, np.array([0.0, 0.0, 0.0, 0.0, RADIUS_GUESS]), loss="soft_l1", f_scale=LOSS_SCALE, max_nfev=60
    )
    axis, point, radius = cylinder(solution.x)
    if not RADIUS_RANGE[0] <= radius <= RADIUS_RANGE[1]:
        return None
    return axis, point, float(radius), solution.fun[:-1]
