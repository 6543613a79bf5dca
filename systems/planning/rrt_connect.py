"""RRT-Connect (Kuffner and LaValle 2000) in the planned joints' space, then shortcuts: a sampled collision-free
path for STOMP to start again from where it is stuck in a reach (its noise draws local moves; a reach from under
the table past boxes at its edge can need a path no local move finds).

Every state and segment is judged by a caller's batched test (STOMP's sphere model), segments at states no joint
turns more than `check_step_rad` apart, so each extension and each shortcut costs two batches at most. The tree
grows by `step_rad` at most per extension (the largest joint change); random draws come from the caller's
generator and the work is bounded by draws, never by the clock, so a seed gives one path (the deadline only stops
it early).
"""

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RrtConfig:
    step_rad: float = 1.5  # the largest joint change of one extension
    check_step_rad: float = 0.02  # segments judged at states no joint turns more than this apart (as STOMP's)
    max_draws: int = 1000  # random configurations drawn before giving up
    shortcuts: int = 40  # random shortcuts tried on the path found


class _Tree:
    """Configurations (rows) and each one's parent index (-1 at the root)."""

    def __init__(self, root: np.ndarray, capacity: int):
        self.nodes = np.empty((capacity, len(root)))
        self.parent = np.empty(capacity, int)
        self.nodes[0], self.parent[0], self.size = root, -1, 1

    def nearest(self, q: np.ndarray) -> int:
        return int(np.argmin(np.abs(self.nodes[: self.size] - q).max(axis=1)))

    def add(self, q: np.ndarray, parent: int) -> int:
        if self.size == len(self.nodes):
            self.nodes = np.concatenate([self.nodes, np.empty_like(self.nodes)])
            self.parent = np.concatenate([self.parent, np.empty_like(self.parent)])
        self.nodes[self.size], self.parent[self.size] = q, parent
        self.size += 1
        return self.size - 1

    def path_to_root(self, i: int) -> list[np.ndarray]:
        path = []
        while i >= 0:
            path.append(self.nodes[i])
            i = self.parent[i]
        return path


def _segment_clear(a: np.ndarray, b: np.ndarray, valid: Callable, check_step: float) -> bool:
    """Whether the segment a -> b is clear at states no joint turns more than check_step apart (b included, a
    taken as clear): every eighth state first, where a blocked segment is mostly found, then the others."""
    steps = max(1, int(np.ceil(np.abs(b - a).max() / check_step)))
    s = np.arange(1, steps + 1) / steps
    coarse = np.zeros(steps, bool)
    coarse[7::8] = coarse[-1] = True
    return all(valid(a + t[:, None] * (b - a)).all() for t in (s[coarse], s[~coarse]) if len(t))


def _grow(tree: _Tree, target: np.ndarray, valid, config: RrtConfig, connect: bool) -> tuple[int, bool]:
    """Grows the tree from its nearest node towards target by steps of step_rad at most: one step (extend) or
    until blocked (connect). Returns the last node added (-1: none) and whether it reached target."""
    last, added = tree.nearest(target), -1
    while True:
        a = tree.nodes[last]
        distance = np.abs(target - a).max()
        if distance <= 0:
            return last, True
        reaches = distance <= config.step_rad
        b = target if reaches else a + (target - a) * (config.step_rad / distance)
        if not _segment_clear(a, b, valid, config.check_step_rad):
            return added, False
        last = added = tree.add(b, last)
        if reaches or not connect:
            return added, reaches


def rrt_connect(
    q_start: np.ndarray,
    q_goal: np.ndarray,
    valid: Callable[[np.ndarray], np.ndarray],
    lower: np.ndarray,
    upper: np.ndarray,
    rng: np.random.Generator,
    config: RrtConfig = RrtConfig(),
    deadline: float = np.inf,
) -> np.ndarray | None:
    """A path (K x n, q_start to q_goal, rad) whose straight segments `valid` finds clear, shortened by random
    shortcuts; None when max_draws draws (or the deadline, time.perf_counter()) pass without one.

    Args:
        valid: B x n configurations -> B bools (clear of collision); the ends are taken as valid.
        lower, upper: the joint limits (n), where configurations are drawn.
    """
    from_start = _Tree(np.asarray(q_start, float), 256)
    trees = [from_start, _Tree(np.asarray(q_goal, float), 256)]
    for _ in range(config.max_draws):
        if time.perf_counter() > deadline:
            return None
        q = rng.uniform(lower, upper)
        grown, _ = _grow(trees[0], q, valid, config, connect=False)
        if grown >= 0:
            last, met = _grow(trees[1], trees[0].nodes[grown], valid, config, connect=True)
            if met:
                ours, theirs = trees[0].path_to_root(grown), trees[1].path_to_root(last)
                path = ours[::-1] + theirs[1:]
                path = path if trees[0] is from_start else path[::-1]
                return shortcut(np.array(path), valid, rng, config)
        trees.reverse()
    return None


def shortcut(path: np.ndarray, valid: Callable, rng: np.random.Generator, config: RrtConfig) -> np.ndarray:
    """The path with random pairs of its points joined straight where that segment is clear (config.shortcuts
    tries), then with points left out where their neighbours see each other."""
    path = list(path)
    for _ in range(config.shortcuts):
        if len(path) < 3:
            break
        i, j = sorted(rng.choice(len(path), 2, replace=False))
        if j - i < 2:
            continue
        if _segment_clear(path[i], path[j], valid, config.check_step_rad):
            path = path[: i + 1] + path[j:]
    i = 0
    while i + 2 < len(path):
        if _segment_clear(path[i], path[i + 2], valid, config.check_step_rad):
            del path[i + 1]
        else:
            i += 1
    return np.array(path)
