"""A board's plane and the target marked on it, from the points a depth camera saw of them.

The target is a disc of a colour of its own (TARGET_RGB, a magenta no familiar object's palette has): its pixels are
those of that hue (target_pixels), and the board's points those within BOARD_RADIUS_M of the target's.
The board's points (N x 3, W) are fitted with a plane (RANSAC, then least squares over its inliers); its normal is
turned towards the camera. The target's points (the pixels of its colour, M x 3, W) are put onto the plane and their
centroid is the target. A board seen as no plane, or a target with too few points, is said so.
"""

from dataclasses import dataclass

import cv2
import numpy as np
import open3d as o3d

PLANE_INLIER_M = 0.005  # m: a board point this near the plane is on it
MIN_BOARD_POINTS = 100
MIN_PLANE_SHARE = 0.8  # of the board's points on its plane
MIN_TARGET_POINTS = 10
PLANE_SEED = 0  # RANSAC's draws (open3d seeds its own generator from this)
TARGET_RGB = (0.9, 0.1, 0.8)  # the target disc's colour, in [0, 1]
# A target pixel: red and blue each at least this many times green, and at least this bright (of 255). Shading and
# the sensor's colour noise keep the ratios; no other colour in the scenes has them.
TARGET_RATIO = 1.8
TARGET_MIN_LEVEL = 60
BOARD_RADIUS_M = 0.12  # m: the board's points are taken within this of the target's centroid


@dataclass(frozen=True)
class Board:
    """A board's plane and its target, in W."""

    normal_W: np.ndarray  # (3,) unit: out of the board, towards the camera
    target_W: np.ndarray  # (3,) m: the target's centre, on the plane


def target_pixels(rgb: np.ndarray) -> np.ndarray:
    """H x W bool: the pixels of the target's colour in an H x W x 3 (or 4) uint8 image, its largest blob only."""
    r, g, b = (rgb[..., i].astype(np.float32) for i in range(3))
    mask = (r >= TARGET_RATIO * g) & (b >= TARGET_RATIO * g) & (np.minimum(r, b) >= TARGET_MIN_LEVEL)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if count <= 1:
        return mask
    return labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))


def board_points(points_W: np.ndarray, target_points_W: np.ndarray) -> np.ndarray:
    """The seen points (N x 3, W) within BOARD_RADIUS_M of the target's points' centroid: the board about it."""
    points = _finite(points_W)
    target = _finite(target_points_W)
    if not len(target):
        return points[:0]
    return points[np.linalg.norm(points - target.mean(axis=0), axis=1) <= BOARD_RADIUS_M]


def board_of(board_points_W: np.ndarray, target_points_W: np.ndarray, viewpoint_W: np.ndarray) -> Board:
    """The board's plane (normal towards viewpoint_W, the camera's position) and its target's centre on it.

    Raises:
        ValueError: too few points of the board or of the target, or a board that is no plane.
    """
    board = _finite(board_points_W)
    target = _finite(target_points_W)
    if len(target) < MIN_TARGET_POINTS:
        raise ValueError(f"the board's target: {len(target)} points seen; at least {MIN_TARGET_POINTS} needed")
    if len(board) < MIN_BOARD_POINTS:
        raise ValueError(f"the board: {len(board)} points seen; its plane needs at least {MIN_BOARD_POINTS}")
    o3d.utility.random.seed(PLANE_SEED)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(board))
    _, inliers = cloud.segment_plane(PLANE_INLIER_M, 3, 200)
    if len(inliers) < MIN_PLANE_SHARE * len(board):
        raise ValueError(
            f"the board is no plane: {100 * len(inliers) / len(board):.0f}% of its points within "
            f"{1000 * PLANE_INLIER_M:.0f} mm of one (at least {100 * MIN_PLANE_SHARE:.0f}%)"
        )
    on_plane = board[inliers]
    centre = on_plane.mean(axis=0)
    normal = np.linalg.svd(on_plane - centre, full_matrices=False)[2][-1]
    if normal @ (np.asarray(viewpoint_W, dtype=float) - centre) < 0:
        normal = -normal
    seen = target.mean(axis=0)
    return Board(normal, seen - ((seen - centre) @ normal) * normal)


def _finite(points) -> np.ndarray:
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    return points[np.all(np.isfinite(points), axis=1)]
