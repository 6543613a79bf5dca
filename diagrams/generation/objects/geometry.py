"""Watertight mesh primitives used to assemble object instances.

All lengths are in metres and all points are expressed in the object frame O
(z up, origin at the centre of the supporting face on the table).
"""

import numpy as np
import trimesh


def convex_loft(rings: list[np.ndarray]) -> trimesh.Trimesh:
    """Convex hull of a stack of closed rings (each an (n, 3) array)."""
    return trimesh.convex.convex_hull(np.vstack(rings))


def ellipse_ring(center, radius_x: float, radius_y: float, sections: int = 48) -> np.ndarray:
    """Points of an ellipse in the plane z = center[2]."""
    return superellipse_ring(center, radius_x, radius_y, 2.0, sections)


def superellipse_ring(center, radius_x: float, radius_y: float, exponent: float, sections: int = 48) -> np.ndarray:
    """Points of the superellipse |x/rx|^n + |y/ry|^n = 1 in the plane z = center[2] (n = 2: an ellipse; larger
    n: a box with rounded corners)."""
    angles = np.linspace(0.0, 2.0 * np.pi, sections, endpoint=False)
    c, s = np.cos(angles), np.sin(angles)
    shape = 2.0 / exponent
    ring = np.stack(
        [radius_x * np.sign(c) * np.abs(c) ** shape, radius_y * np.sign(s) * np.abs(s) ** shape, np.zeros_like(c)],
        axis=1,
    )
    return ring + np.asarray(center, dtype=float)


def circle_ring(center, axis, radius: float, sections: int = 24) -> np.ndarray:
    """Points of a circle of `radius` around `center`, normal to `axis`."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    angles = np.linspace(0.0, 2.0 * np.pi, sections, endpoint=False)
    return np.asarray(center, dtype=float) + radius * np.cos(angles)[:, None] * u + radius * np.sin(angles)[:, None] * v


def frustum(start, end, radius_start: float, radius_end: float, sections: int = 24):
    """Convex truncated cone from `start` to `end` (a cylinder when radii are equal)."""
    axis = np.asarray(end, dtype=float) - np.asarray(start, dtype=float)
    return convex_loft(
        [
            circle_ring(start, axis, radius_start, sections),
            circle_ring(end, axis, radius_end, sections),
        ]
    )


def box(size, center) -> trimesh.Trimesh:
    """Axis-aligned box of `size` (x, y, z) centred at `center`."""
    return trimesh.creation.box(extents=size, transform=trimesh.transformations.translation_matrix(center))


def tube(path: np.ndarray, radius: float, sections: int = 20) -> trimesh.Trimesh:
    """Watertight tube of constant radius swept along a polyline, with flat end caps.

    Args:
        path: (n, 3) points, n >= 2.
        radius: tube radius in metres.
        sections: vertices around each cross-section.
    """
    path = np.asarray(path, dtype=float)
    tangents = np.gradient(path, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    # Parallel-transport a normal along the path so rings do not twist.
    helper = np.array([0.0, 1.0, 0.0]) if abs(tangents[0][1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    normal = np.cross(tangents[0], helper)
    normal /= np.linalg.norm(normal)
    angles = np.linspace(0.0, 2.0 * np.pi, sections, endpoint=False)
    rings = []
    for point, tangent in zip(path, tangents, strict=True):
        normal = normal - tangent * np.dot(normal, tangent)
        normal /= np.linalg.norm(normal)
        binormal = np.cross(tangent, normal)
        rings.append(point + radius * np.cos(angles)[:, None] * normal + radius * np.sin(angles)[:, None] * binormal)
    vertices = np.vstack(rings + [path[:1], path[-1:]])
    n, m = len(path), sections
    faces = []
    for i in range(n - 1):
        for j in range(m):
            a, b = i * m + j, i * m + (j + 1) % m
            c, d = a + m, b + m
            faces += [[a, b, c], [b, d, c]]
    start_cap, end_cap = n * m, n * m + 1
    for j in range(m):
        faces.append([start_cap, (j + 1) % m, j])
        last = (n - 1) * m
        faces.append([end_cap, last + j, last + (j + 1) % m])
    mesh = trimesh.Trimesh(vertices=vertices, faces=np.array(faces), process=True)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def arc(center, radius: float, start_angle: float, end_angle: float, plane: str = "xz", samples: int = 24):
    """Points on a circular arc in the given coordinate plane ("xz" or "xy" or "yz").

    Angles are measured from the plane's first axis towards its second axis.
    """
    angles = np.linspace(start_angle, end_angle, samples)
    first, second = {"xz": (0, 2), "xy": (0, 1), "yz": (1, 2)}[plane]
    points = np.zeros((samples, 3))
    points[:, first] = radius * np.cos(angles)
    points[:, second] = radius * np.sin(angles)
    return points + np.asarray(center, dtype=float)


def convex_pieces_of_tube(path: np.ndarray, radius: float, pieces: int) -> list[trimesh.Trimesh]:
    """Splits a tube along its path into `pieces` convex hulls (for collision)."""
    bounds = np.linspace(0, len(path) - 1, pieces + 1).round().astype(int)
    hulls = []
    for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
        segment = path[lo : hi + 1]
        rings = [circle_ring(p, t, radius, 12) for p, t in zip(segment, np.gradient(segment, axis=0), strict=True)]
        hulls.append(convex_loft(rings))
    return hulls


def filleted_path(corners, radius: float, samples: int = 10) -> np.ndarray:
    """A polyline through `corners` (n x 3, m) with each inner corner replaced by a circular arc of `radius` (m),
    smaller where a segment is too short for it."""
    corners = np.asarray(corners, dtype=float)
    points = [corners[0]]
    for a, b, c in zip(corners[:-2], corners[1:-1], corners[2:], strict=True):
        u, v = (a - b) / np.linalg.norm(a - b), (c - b) / np.linalg.norm(c - b)
        half_angle = 0.5 * np.arccos(np.clip(np.dot(u, v), -1.0, 1.0))
        # The arc's tangent points lie `reach` from the corner; at most half of either segment.
        reach = min(radius / np.tan(half_angle), 0.5 * np.linalg.norm(a - b), 0.5 * np.linalg.norm(c - b))
        r = reach * np.tan(half_angle)
        centre = b + (u + v) / np.linalg.norm(u + v) * r / np.sin(half_angle)
        start, end = b + reach * u, b + reach * v
        e1 = (start - centre) / r
        e2 = (end - centre) - np.dot(end - centre, e1) * e1
        e2 /= np.linalg.norm(e2)
        sweep = np.pi - 2.0 * half_angle
        angles = np.linspace(0.0, sweep, samples)
        points.extend(centre + r * (np.cos(angles)[:, None] * e1 + np.sin(angles)[:, None] * e2))
    points.append(corners[-1])
    path = np.array(points)
    keep = np.r_[True, np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-6]
    return path[keep]


def resampled(path, spacing: float) -> np.ndarray:
    """The polyline `path` (n x 3) resampled at even arc length, about `spacing` apart (m), ends kept."""
    path = np.asarray(path, dtype=float)
    arc_length = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))]
    count = max(int(np.ceil(arc_length[-1] / spacing)), 1) + 1
    s = np.linspace(0.0, arc_length[-1], count)
    return np.column_stack([np.interp(s, arc_length, path[:, k]) for k in range(3)])


def short_tube_pieces(path, radius: float, piece_length: float = 0.03) -> list[trimesh.Trimesh]:
    """Convex pieces of a tube along `path`, each covering about `piece_length` of it (m): short enough that a
    piece round a bend fills little of the bend's inside (a D-handle keeps its opening for the fingers)."""
    path = np.asarray(path, dtype=float)
    length = np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1))
    pieces = max(int(np.ceil(length / piece_length)), 1)
    even = resampled(path, length / (4 * pieces))
    return convex_pieces_of_tube(even, radius, pieces)
