"""Which points of a surface sampling a camera sees: hidden point removal."""

import numpy as np
from scipy.spatial import ConvexHull


def visible_from(points_W: np.ndarray, viewpoint_W: np.ndarray) -> np.ndarray:
    """Which points (N x 3, W) of a surface sampling are visible from the viewpoint (3, W): a boolean mask, by
    hidden point removal (Katz et al. 2007): the points flipped about a sphere around the viewpoint (radius 100
    times the farthest point's distance) that are vertices of their convex hull with the viewpoint.

    (As open3d's hidden_point_removal, the same masks on the registration's point sets; scipy's qhull lets other
    threads run meanwhile, open3d's call does not.)"""
    relative = np.asarray(points_W, dtype=float) - viewpoint_W
    distance = np.linalg.norm(relative, axis=1)
    radius = 100.0 * float(distance.max())
    flipped = relative + (2 * (radius - distance) / distance)[:, None] * relative
    vertices = ConvexHull(np.vstack([flipped, np.zeros(3)])).vertices
    mask = np.zeros(len(relative), dtype=bool)
    mask[vertices[vertices < len(relative)]] = True
    return mask
