"""A grasp frame moved across its handle onto the handle the camera saw.

Outside the training family a handle is often larger, smaller or further out than the fitted shape's: the latent
fit (and its scale) puts the grasp 1-3 cm beside the handle the camera saw, and grasp_shift's point-to-plane steps,
whose matches reach 1.5 cm, do not bridge that. handle_centring() slides the fitted handle about a grasp frame G as
a rigid piece across the handle's axis x_G (in G's y-z plane, up to CENTRING_REACH) to where most of it lies on
seen points, and moves the grasp with it.

What it may not do, and why:
- move a grasp along its handle: a piece of a curved handle matches another bend of a larger one as well (a
  search along and across put rear grasps 3 cm along their arcs);
- move it further than CENTRING_REACH: a handle further off than that is not beside the fit but elsewhere, and a
  search that far found other parts (that search turned named poor fits into wrong grasps);
- move a grasp whose fitted handle already lies on what was seen: only a gain of CENTRING_GAIN in the share of the
  handle's fitted surface on seen points moves it, so a fit the shape space explains keeps its grasps.
"""

import numpy as np
from pydrake.math import RigidTransform
from scipy import ndimage

# Chosen on the tuning picks' first frames and the wider family's validation views, the in-family views unchanged
# (docs/shape_space.md, "A grasp follows its handle"; alternatives: docs/history/registration_parameters.md).
CENTRING_REACH = 0.03  # m: the largest move across the handle's axis
CENTRING_STEP = 0.003  # m: the grid of moves tried
CENTRING_MATCH = 0.004  # m: a fitted point this near a seen point lies on it
CENTRING_GAIN = 0.15  # the share of the fitted handle on seen points must rise by this much for a move
HANDLE_TUBE = 0.025  # m: the fitted handle about G: points this near its axis x_G ...
HANDLE_HALF_LENGTH = 0.03  # m: ... and this near G along it (the fingers' half span)
OCCUPANCY_CELL_M = 0.002  # m: the seen points' occupancy grid
NEAR_BEST = 0.05  # of the moves within this share of the best, the shortest is taken


def handle_centring(X_WG: RigidTransform, visible_model_W: np.ndarray, observed_W: np.ndarray) -> np.ndarray:
    """How far (3, W, m) to move the grasp frame X_WG across its handle: the move in G's y-z plane (at most
    CENTRING_REACH, on a CENTRING_STEP grid) that puts the most of the fitted handle about G (the fitted surface
    visible from the camera, N x 3 in W, within HANDLE_TUBE of x_G and HANDLE_HALF_LENGTH of G along it) within
    CENTRING_MATCH of the seen points (K x 3, W), the shortest of those within NEAR_BEST of the best. Zero where that
    share rises by less than CENTRING_GAIN, or where too little of the handle is fitted or seen to judge."""
    R, origin = X_WG.rotation().matrix(), X_WG.translation()
    handle = (np.asarray(visible_model_W) - origin) @ R  # in G
    handle = handle[(np.abs(handle[:, 0]) < HANDLE_HALF_LENGTH) & (np.hypot(handle[:, 1], handle[:, 2]) < HANDLE_TUBE)]
    reach = np.array([HANDLE_HALF_LENGTH, *(2 * [CENTRING_REACH + HANDLE_TUBE])]) + CENTRING_MATCH
    seen = (np.asarray(observed_W) - origin) @ R
    seen = seen[np.all(np.abs(seen) < reach, axis=1)]
    if len(handle) < 10 or len(seen) < 20:
        return np.zeros(3)
    occupied = _Occupancy(seen, reach, CENTRING_MATCH)
    at_grasp = occupied.share(handle[None])[0]
    if at_grasp > 1.0 - CENTRING_GAIN:
        return np.zeros(3)
    shares = occupied.share(handle[None] + _MOVES[:, None])
    if shares.max() < at_grasp + CENTRING_GAIN:
        return np.zeros(3)
    near_best = np.flatnonzero(shares >= shares.max() - NEAR_BEST)
    return R @ _MOVES[near_best[np.argmin(np.linalg.norm(_MOVES[near_best], axis=1))]]


def _moves() -> np.ndarray:
    """The moves tried (M x 3, m, in G): a CENTRING_STEP grid in the y-z plane within CENTRING_REACH."""
    steps = np.arange(-CENTRING_REACH, CENTRING_REACH + 1e-9, CENTRING_STEP)
    moves = np.stack(np.meshgrid(0.0, steps, steps, indexing="ij"), axis=-1).reshape(-1, 3)
    return moves[np.hypot(moves[:, 1], moves[:, 2]) <= CENTRING_REACH + 1e-9]


_MOVES = _moves()


class _Occupancy:
    """The cells of an OCCUPANCY_CELL_M grid over the box |p| < reach (3,) that lie within `radius` of the points
    (N x 3)."""

    def __init__(self, points: np.ndarray, reach: np.ndarray, radius: float):
        self.low = -reach
        self.shape = np.ceil(2 * reach / OCCUPANCY_CELL_M).astype(int) + 1
        cells = self._cells(points)
        cells = cells[np.all((cells >= 0) & (cells < self.shape), axis=1)]
        self.grid = np.zeros(self.shape, dtype=bool)
        self.grid[tuple(cells.T)] = True
        r = int(round(radius / OCCUPANCY_CELL_M))
        offsets = np.mgrid[-r : r + 1, -r : r + 1, -r : r + 1]
        self.grid = ndimage.binary_dilation(self.grid, structure=np.sum(offsets**2, axis=0) <= r * r)

    def _cells(self, points: np.ndarray) -> np.ndarray:
        return np.floor((points - self.low) / OCCUPANCY_CELL_M).astype(int)

    def share(self, point_sets: np.ndarray) -> np.ndarray:
        """For each of S sets of points (S x N x 3), the share in occupied cells (outside the grid: not)."""
        cells = self._cells(point_sets)
        inside = np.all((cells >= 0) & (cells < self.shape), axis=-1)
        cells = np.clip(cells, 0, self.shape - 1)
        return np.mean(self.grid[cells[..., 0], cells[..., 1], cells[..., 2]] & inside, axis=-1)
