"""Convex outlines on the table: objects' footprints seen from above (M x 2 arrays of x, y, m, in any one frame,
either winding). Used to draw scenes apart, to pack the drop zone and to judge where objects ended."""

import numpy as np
from scipy.spatial import ConvexHull


def convex_outline(points_xy: np.ndarray) -> np.ndarray:
    """The convex hull of points (N x 2, m) as an outline (M x 2, counter-clockwise)."""
    points_xy = np.asarray(points_xy, float)
    return points_xy[ConvexHull(points_xy).vertices]


def inside(points: np.ndarray, outline: np.ndarray) -> np.ndarray:
    """Which points (P x 2) lie inside (or on) the convex outline (M x 2)."""
    edge = np.roll(outline, -1, axis=0) - outline
    offset = points[:, None] - outline[None]
    cross = edge[None, :, 0] * offset[..., 1] - edge[None, :, 1] * offset[..., 0]
    return np.all(cross >= 0, axis=1) | np.all(cross <= 0, axis=1)


def edge_distances(points: np.ndarray, outline: np.ndarray) -> np.ndarray:
    """Each point's (P x 2) distance to the closed outline's edges (M x 2), m."""
    a, b = outline, np.roll(outline, -1, axis=0)
    edge = b - a
    t = np.clip(np.einsum("pmk,mk->pm", points[:, None] - a[None], edge) / np.einsum("mk,mk->m", edge, edge), 0, 1)
    nearest = a[None] + t[..., None] * edge[None]
    return np.linalg.norm(points[:, None] - nearest, axis=2).min(axis=1)


def _edges_cross(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether an edge of outline a crosses an edge of outline b (strictly; touching is a distance of 0)."""

    def turn(p, q, r):  # the sign of (q - p) x (r - p), over every pair of (a's edge, b's point) or the reverse
        (u, v), (w, z) = np.moveaxis(q - p, -1, 0), np.moveaxis(r - p, -1, 0)
        return np.sign(u * z - v * w)

    a0, a1 = a[:, None], np.roll(a, -1, axis=0)[:, None]
    b0, b1 = b[None], np.roll(b, -1, axis=0)[None]
    return bool(np.any((turn(a0, a1, b0) * turn(a0, a1, b1) < 0) & (turn(b0, b1, a0) * turn(b0, b1, a1) < 0)))


def gap_between(a: np.ndarray, b: np.ndarray) -> float:
    """The distance between two convex outlines (m); 0 where they meet or one holds the other."""
    if inside(a, b).any() or inside(b, a).any() or _edges_cross(a, b):
        return 0.0
    return float(min(edge_distances(a, b).min(), edge_distances(b, a).min()))


def distance_to(outline: np.ndarray, point) -> float:
    """A point's (x, y) distance to a convex outline (m); 0 inside it."""
    point = np.asarray(point, float)[None]
    return 0.0 if inside(point, outline)[0] else float(edge_distances(point, outline)[0])


def outlines_apart(a: np.ndarray, b: np.ndarray, gap: float) -> bool:
    """Whether two convex outlines stand at least `gap` (m) apart and do not touch."""
    return gap_between(a, b) >= max(gap, 1e-9)
