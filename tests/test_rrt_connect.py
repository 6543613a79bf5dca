"""RRT-Connect on a plane with a wall (a narrow gap in it), and the keyframes STOMP places along its path."""

import numpy as np

from systems.planning.rrt_connect import RrtConfig, rrt_connect
from systems.planning.stomp_starts import keyframes_through

LOWER, UPPER = np.array([-1.0, -1.0]), np.array([1.0, 1.0])


def _wall(gap_from: float = 0.6, gap_to: float = 0.7):
    """Valid states: all but the wall |x| < 0.05, except where gap_from < y < gap_to."""

    def valid(q: np.ndarray) -> np.ndarray:
        q = np.atleast_2d(q)
        return (np.abs(q[:, 0]) >= 0.05) | ((q[:, 1] > gap_from) & (q[:, 1] < gap_to))

    return valid


def _dense_clear(path: np.ndarray, valid, step: float = 0.005) -> bool:
    for a, b in zip(path[:-1], path[1:], strict=True):
        s = np.linspace(0.0, 1.0, max(2, int(np.abs(b - a).max() / step) + 2))[:, None]
        if not valid(a + s * (b - a)).all():
            return False
    return True


def test_rrt_connect_finds_the_gap_in_a_wall_and_is_repeatable_by_seed():
    start, goal = np.array([-0.8, -0.8]), np.array([0.8, -0.8])
    valid = _wall()
    config = RrtConfig(step_rad=0.3, check_step_rad=0.01, max_draws=2000)
    path = rrt_connect(start, goal, valid, LOWER, UPPER, np.random.default_rng(3), config)
    assert path is not None
    np.testing.assert_array_equal(path[0], start)
    np.testing.assert_array_equal(path[-1], goal)
    assert _dense_clear(path, valid)
    assert np.any((np.abs(path[:, 0]) < 0.3) & (path[:, 1] > 0.4))  # it goes through the gap, up at y 0.6-0.7
    again = rrt_connect(start, goal, valid, LOWER, UPPER, np.random.default_rng(3), config)
    np.testing.assert_array_equal(path, again)
    # The shortcuts leave no corner whose neighbours see each other.
    assert len(path) <= 4


def test_rrt_connect_gives_up_after_its_draws_where_no_path_exists():
    valid = _wall(gap_from=2.0, gap_to=3.0)  # the gap outside the limits
    config = RrtConfig(step_rad=0.3, check_step_rad=0.01, max_draws=200)
    start, goal = np.array([-0.8, 0.0]), np.array([0.8, 0.0])
    assert rrt_connect(start, goal, valid, LOWER, UPPER, np.random.default_rng(0), config) is None
    open_wall = _wall()
    assert rrt_connect(start, goal, open_wall, LOWER, UPPER, np.random.default_rng(0), config, deadline=0.0) is None


def test_the_keyframes_keep_the_paths_corners():
    path = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 3.0], [0.0, 3.0]])
    theta = keyframes_through(path, 16)
    assert theta.shape == (16, 2)
    for corner in path:
        assert np.any(np.all(theta == corner, axis=1))
    # every keyframe on the path: each lies on one of its segments
    on_path = (theta[:, 1] == 0) | (theta[:, 0] == 1) | (theta[:, 1] == 3)
    assert on_path.all()
    # the long middle segment holds most keyframes
    assert np.sum((theta[:, 0] == 1) & (theta[:, 1] > 0) & (theta[:, 1] < 3)) >= 8
    # more corners than keyframes: evenly spaced along the path instead
    zigzag = np.column_stack([np.arange(20.0), np.arange(20) % 2])
    assert keyframes_through(zigzag, 16).shape == (16, 2)
