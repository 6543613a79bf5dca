"""The tube fitted to a handle's seen points: axis, radius and extent from a noisy half view."""

import numpy as np
import pytest

from systems.perception.tube_fit import MIN_POINTS, fit_tube

VIEWPOINT = np.array([-0.6, 0.0, 1.4])  # m: about where the chest camera sees the table from


def seen_half_tube(rng, axis, centre, radius, length, noise=0.002, count=1500):
    """Points of a tube's surface that face the viewpoint, each moved along its line of sight by depth noise."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    u = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    t, angle = rng.uniform(-length / 2, length / 2, count), rng.uniform(0, 2 * np.pi, count)
    normal = np.outer(np.cos(angle), u) + np.outer(np.sin(angle), v)
    points = centre + np.outer(t, axis) + radius * normal
    points = points[np.einsum("ij,ij->i", normal, VIEWPOINT - points) > 0]
    sight = VIEWPOINT - points
    sight /= np.linalg.norm(sight, axis=1, keepdims=True)
    return points + sight * rng.normal(0.0, noise, len(points))[:, None]


@pytest.mark.parametrize("seed", range(6))
def test_a_tube_seen_from_one_side_is_fitted_within_a_few_millimetres_and_degrees(seed):
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    centre, radius = np.array([0.5, 0.0, 0.9]) + rng.normal(0, 0.05, 3), rng.uniform(0.008, 0.02)
    points = seen_half_tube(rng, axis, centre, radius, 0.12)
    tube = fit_tube(points, VIEWPOINT, centre + rng.normal(0, 0.01, 3))
    assert np.degrees(np.arccos(min(1.0, abs(tube.axis @ axis)))) < 3.0
    off_axis = tube.point - centre
    assert np.linalg.norm(off_axis - (off_axis @ axis) * axis) < 0.002
    assert abs(tube.radius - radius) < 0.002
    assert tube.rms_m < 0.004
    assert tube.extent[0] < -0.015 and tube.extent[1] > 0.015  # the points within reach of the seed


def test_a_stray_cluster_beside_the_handle_pulls_the_axis_little():
    rng = np.random.default_rng(7)
    centre = np.array([0.45, 0.05, 0.95])
    points = seen_half_tube(rng, [1.0, 0.2, 0.0], centre, 0.012, 0.1)
    strays = centre + [0.0, 0.0, 0.02] + rng.normal(0.0, 0.004, (40, 3))  # flying pixels above it
    tube = fit_tube(np.vstack([points, strays]), VIEWPOINT, centre)
    axis = np.array([1.0, 0.2, 0.0]) / np.linalg.norm([1.0, 0.2, 0.0])
    assert np.degrees(np.arccos(abs(tube.axis @ axis))) < 5.0
    assert abs(tube.radius - 0.012) < 0.004


def test_too_few_points_near_the_seed_fit_nothing():
    rng = np.random.default_rng(3)
    points = seen_half_tube(rng, [0, 1, 0], np.array([0.5, 0.0, 0.9]), 0.012, 0.1)
    assert fit_tube(points, VIEWPOINT, [0.5, 0.3, 0.9]) is None  # the seed 25 cm off the handle
    assert fit_tube(points[: MIN_POINTS - 1], VIEWPOINT, [0.5, 0.0, 0.9]) is None
    with_nans = np.vstack([points, np.full((10, 3), np.nan)])
    assert fit_tube(with_nans, VIEWPOINT, [0.5, 0.0, 0.9]) is not None
