"""A container's opening (a bowl's, a plant pot's) from the points a depth camera saw of it: its rim's centre and
radius, for pouring into it.

Seen from above, a container's highest points are its rim, all round (the camera sees over the near wall onto the far
one). The rim is the band of points within RIM_BAND_M of the highest; a circle fitted to it across (x, y) in W (least
squares, then its outliers out) gives the opening's centre and radius, at the rim's height. A band that is no circle
(too few points, too little of the round seen, too far off a circle, or a size no container has) is no opening, and
said so.
"""

from dataclasses import dataclass

import numpy as np

RIM_BAND_M = 0.012  # m: the points this near the highest are the rim
MIN_RIM_POINTS = 30
MIN_RIM_COVERAGE = 0.5  # of the rim's round, in angle: seen from above, a container's rim shows all round
RIM_SECTORS = 24  # the round's parts counted for its coverage
MAX_RIM_RMS_M = 0.006  # m: the rim's points off the fitted circle, root mean square
RIM_OUTLIER_M = 0.015  # m: a rim point this far off the first circle is not the rim's
OPENING_RADIUS_M = (0.03, 0.3)  # m: the radii of the containers poured into


@dataclass(frozen=True)
class Opening:
    """A container's opening in W."""

    centre_W: np.ndarray  # (3,) m: the rim's centre, at the rim's height
    radius: float  # m: the rim's
    rim_points: int  # the seen points the circle was fitted to


def opening_of(points_W: np.ndarray, what: str = "the container") -> Opening:
    """The opening of a container whose seen points (N x 3, W, m; its own only: the table's and other objects' out)
    are given.

    Raises:
        ValueError: naming `what`: too few finite points, or a rim that is no container's opening (why, in figures).
    """
    points = np.asarray(points_W, dtype=float).reshape(-1, 3)
    points = points[np.all(np.isfinite(points), axis=1)]
    if len(points) < MIN_RIM_POINTS:
        raise ValueError(f"{what}: {len(points)} points seen; an opening needs at least {MIN_RIM_POINTS}")
    top = np.percentile(points[:, 2], 99.5)  # (a flying pixel above the rim is not its height)
    rim = points[points[:, 2] >= top - RIM_BAND_M]
    if len(rim) < MIN_RIM_POINTS:
        raise ValueError(f"{what}: {len(rim)} points on its rim; an opening needs at least {MIN_RIM_POINTS}")
    centre, radius = _circle(rim[:, :2])
    off = np.abs(np.linalg.norm(rim[:, :2] - centre, axis=1) - radius)
    rim = rim[off < RIM_OUTLIER_M]
    if len(rim) < MIN_RIM_POINTS:
        raise ValueError(f"{what}: its highest points lie on no circle (no rim seen)")
    centre, radius = _circle(rim[:, :2])
    rms = float(np.sqrt(np.mean((np.linalg.norm(rim[:, :2] - centre, axis=1) - radius) ** 2)))
    angles = np.arctan2(*(rim[:, :2] - centre).T[::-1])
    coverage = len(np.unique(np.floor((angles + np.pi) / (2 * np.pi) * RIM_SECTORS))) / RIM_SECTORS
    if rms > MAX_RIM_RMS_M or coverage < MIN_RIM_COVERAGE:
        raise ValueError(
            f"{what}: its rim is no opening: {1000 * rms:.1f} mm off a circle (at most {1000 * MAX_RIM_RMS_M:.0f} mm), "
            f"{100 * coverage:.0f}% of its round seen (at least {100 * MIN_RIM_COVERAGE:.0f}%)"
        )
    low, high = OPENING_RADIUS_M
    if not low <= radius <= high:
        raise ValueError(f"{what}: an opening {100 * radius:.1f} cm across its radius: not {low:g}-{high:g} m")
    return Opening(np.array([*centre, float(np.median(rim[:, 2]))]), float(radius), len(rim))


def _circle(xy: np.ndarray) -> tuple[np.ndarray, float]:
    """The least-squares circle (centre (2,), radius) through points (N x 2): x^2 + y^2 = 2 a x + 2 b y + c."""
    A = np.column_stack([2 * xy, np.ones(len(xy))])
    (a, b, c), *_ = np.linalg.lstsq(A, np.sum(xy**2, axis=1), rcond=None)
    return np.array([a, b]), float(np.sqrt(max(c + a * a + b * b, 0.0)))
