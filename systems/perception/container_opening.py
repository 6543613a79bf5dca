"""A container's opening (a bowl's, a plant pot's) from the points a depth camera saw of it: its rim's centre and
radius, for pouring into it.

A bowl or a pot is round about a vertical axis: every height of its walls is a circle about the same centre. The
axis is fitted to all its seen points at once (`_axis`: the points in 5 mm slices of height, each point's distance
from the axis against its slice's mean distance, robust least squares), so that part of the round is enough: a
container at the image's edge, or cut in two by the can in front of it, shows a third of its rim or less, and a
circle fitted to that arc alone came out 5-45 mm off (2026-12-07, the pour's random placements), where the walls put
the axis within 2.5 mm (1.3 mm median). The rim is the band of points within RIM_BAND_M of the highest; the opening
is the circle about the axis through them (their median distance), at the rim's height. No opening, and said so: too
few points, a closed top (a box's, a cylinder's: its highest points fill the circle), walls that are no surface of
revolution, a rim off its circle, an axis the seen part leaves undetermined, or a size no container has. A sliver of
a closed top (a cylinder cut by the image's edge, a third of it seen) passes for an arc of a rim; the finder takes
the opening with the most rim points, and none with something seen over it (container_finder.points_over).

A bowl's walls are its inside on the far side and its outside on the near one, a wall's thickness apart: the axis
comes out about half that thickness off (3 mm on a 6 mm wall, noise-free views).
"""

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import median_abs_deviation

RIM_BAND_M = 0.012  # m: the points this near the highest are the rim
MIN_RIM_POINTS = 30
SLICE_M = 0.005  # m: the walls' slices of height, each a circle about the axis
MAX_WALL_SPREAD_M = 0.004  # m: the walls' points off their slices' circles, a robust standard deviation
MAX_RIM_RMS_M = 0.006  # m: the rim's points off the opening's circle, root mean square
MAX_CENTRE_SD_M = 0.005  # m: the axis's standard deviation, largest across, from the fit (a short arc: large); the pour
# needs the spout within the opening's radius less 1 cm of its centre (radii 5.5 cm and more)
MAX_CLOSED_SHARE = 0.1  # of the highest points, within half the radius of the axis: a top, not a rim (a disc: 25%)
RIM_OUTLIER_M = 0.015  # m: a rim point this far off the rim's median distance from the axis is not the rim's
OPENING_RADIUS_M = (0.03, 0.3)  # m: the radii of the containers poured into
LOSS_SCALE_M = 0.003  # m: residuals beyond this count less and less (soft-L1)


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
    centre, wall_spread, centre_sd = _axis(points, _circle(rim[:, :2])[0])
    distance = np.linalg.norm(rim[:, :2] - centre, axis=1)
    middle = np.median(distance)
    closed = float(np.mean(distance < 0.5 * middle))
    if closed > MAX_CLOSED_SHARE:
        raise ValueError(
            f"{what}: no opening: {100 * closed:.0f}% of its highest points lie within half its radius of its axis (a"
            f" closed top: at most {100 * MAX_CLOSED_SHARE:.0f}%)"
        )
    rim = rim[np.abs(distance - middle) < RIM_OUTLIER_M]
    if len(rim) < MIN_RIM_POINTS:
        raise ValueError(f"{what}: its highest points lie on no circle (no rim seen)")
    distance = np.linalg.norm(rim[:, :2] - centre, axis=1)
    radius = float(np.median(distance))
    rim_rms = float(np.sqrt(np.mean((distance - radius) ** 2)))
    faults = []
    if wall_spread > MAX_WALL_SPREAD_M:
        faults.append(f"its walls {1000 * wall_spread:.1f} mm off round (at most {1000 * MAX_WALL_SPREAD_M:.0f} mm)")
    if rim_rms > MAX_RIM_RMS_M:
        faults.append(f"its rim {1000 * rim_rms:.1f} mm off a circle (at most {1000 * MAX_RIM_RMS_M:.0f} mm)")
    if centre_sd > MAX_CENTRE_SD_M:
        faults.append(
            f"its axis known to {1000 * centre_sd:.1f} mm (at most {1000 * MAX_CENTRE_SD_M:.0f} mm: too little of "
            "its round seen)"
        )
    if faults:
        raise ValueError(f"{what}: no opening: {'; '.join(faults)}")
    low, high = OPENING_RADIUS_M
    if not low <= radius <= high:
        raise ValueError(f"{what}: an opening {100 * radius:.1f} cm across its radius: not {low:g}-{high:g} m")
    return Opening(np.array([*centre, float(np.median(rim[:, 2]))]), radius, len(rim))


def _axis(points: np.ndarray, first: np.ndarray) -> tuple[np.ndarray, float, float]:
    """The vertical axis the points (N x 3) lie round, from the first guess `first` (2,): (its (x, y), m; the
    spread of the points' distances off their slices' mean distances, m (a robust standard deviation: a bowl's
    inside bottom, seen from above, is no wall); the axis's standard deviation in its worst-known direction, m, from
    the fit's Gauss-Newton covariance and that spread)."""
    slices = np.floor((points[:, 2] - points[:, 2].min()) / SLICE_M).astype(int)
    counts = np.maximum(np.bincount(slices), 1)

    def slice_mean(values):
        return (
            np.stack([np.bincount(slices, column) for column in values.reshape(len(points), -1).T], 1) / counts[:, None]
        )

    def residuals(centre):
        distance = np.linalg.norm(points[:, :2] - centre, axis=1)
        return distance - slice_mean(distance)[slices, 0]

    solution = least_squares(residuals, first, loss="soft_l1", f_scale=LOSS_SCALE_M)
    centre = solution.x
    offset = points[:, :2] - centre
    radial = offset / np.maximum(np.linalg.norm(offset, axis=1), 1e-9)[:, None]
    jacobian = slice_mean(radial)[slices] - radial  # d(residual)/d(centre)
    spread = median_abs_deviation(solution.fun, scale="normal")  # (the residuals' robust standard deviation)
    information = jacobian.T @ jacobian
    worst = np.linalg.eigvalsh(information)[0]
    centre_sd = spread / np.sqrt(worst) if worst > 0 else np.inf
    return centre, float(spread), float(centre_sd)


def _circle(xy: np.ndarray) -> tuple[np.ndarray, float]:
    """The least-squares circle (centre (2,), radius) through points (N x 2): x^2 + y^2 = 2 a x + 2 b y + c."""
    A = np.column_stack([2 * xy, np.ones(len(xy))])
    (a, b, c), *_ = np.linalg.lstsq(A, np.sum(xy**2, axis=1), rcond=None)
    return np.array([a, b]), float(np.sqrt(max(c + a * a + b * b, 0.0)))
