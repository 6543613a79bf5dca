"""Where STOMP starts, and starts again: the first trajectories of a plan and the paths its restarts take.

STOMP is local: from under the table the straight joint-space line can lead it into a minimum it does not leave.
  - A held move (hand constraints) starts from the straight line projected onto the constraints, drawn first with
    few keyframes, else from a detour (systems/planning/stomp_detours.py) of the held object over or around what
    stands in its way.
  - An unconstrained plan (a reach) whose straight line is not a solution starts from the least colliding of it and
    paths through random joint-space via points. Stuck, it restarts first from a path RRT-Connect samples in the
    sphere model, then from paths that move both hands through Cartesian via points (back towards the robot and up
    above the goal, across, down to it: out from under the table and over what stands at its edge), least colliding
    first, then from the other joint-space ones.
"""

import itertools

import numpy as np

from systems.planning.hand_constraints import bounded_step
from systems.planning.obstacles import Obstacles
from systems.planning.rrt_connect import RrtConfig, rrt_connect
from systems.planning.stomp_checks import Checked, SolutionChecks
from systems.planning.stomp_config import StompConfig
from systems.planning.stomp_costs import SphereCosts, StompProblem
from systems.planning.stomp_detours import Detours

HAND_VIA_STEP_RAD = 0.3  # the largest joint change of one Gauss-Newton step towards a hand via point


def resample(path: np.ndarray, n: int) -> np.ndarray:
    """n configurations evenly spaced by joint-space length along the piecewise-linear `path` (K x n)."""
    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    if length[-1] <= 0:
        return np.repeat(path[:1], n, axis=0)
    targets = np.linspace(0.0, length[-1], n)
    return np.column_stack([np.interp(targets, length, path[:, j]) for j in range(path.shape[1])])


def keyframes_through(path: np.ndarray, n: int) -> np.ndarray:
    """n configurations along the piecewise-linear path (K x n, K <= n: each of its corners one of them; the
    segments given keyframes by their joint-space length, at least one each). With more corners than n, evenly
    spaced by length (resample)."""
    if len(path) > n:
        return resample(path, n)
    lengths = np.linalg.norm(np.diff(path, axis=0), axis=1)
    intervals = np.ones(len(lengths), int)
    for _ in range(n - 1 - len(lengths)):  # the next interval to the segment whose intervals are longest
        intervals[np.argmax(lengths / intervals)] += 1
    pieces = [
        a + np.linspace(0.0, 1.0, k + 1)[:-1, None] * (b - a)
        for a, b, k in zip(path[:-1], path[1:], intervals, strict=True)
    ]
    return np.concatenate([*pieces, path[-1:]])


def through_vias(start: np.ndarray, vias: np.ndarray, goal: np.ndarray, n: int) -> np.ndarray:
    """For each via point (V x n), n configurations evenly spaced by joint-space length along start -> via -> goal
    (V x n x n)."""
    first, second = vias - start, goal - vias
    length_1 = np.linalg.norm(first, axis=1, keepdims=True)
    length_2 = np.linalg.norm(second, axis=1, keepdims=True)
    t = np.linspace(0.0, 1.0, n)[None] * (length_1 + length_2)  # V x n, length travelled
    before = np.clip(t / np.maximum(length_1, 1e-12), 0.0, 1.0)[..., None]
    after = np.clip((t - length_1) / np.maximum(length_2, 1e-12), 0.0, 1.0)[..., None]
    return start + before * first[:, None] + after * second[:, None]


def straight_line(q_start: np.ndarray, q_goal: np.ndarray, n: int) -> np.ndarray:
    """n configurations evenly along the straight joint-space line from q_start to q_goal (n x dof)."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    return (1 - s) * q_start + s * q_goal


class FirstTrajectories:
    """A STOMP planner's first trajectories and restart paths (StompConfig's first_trajectories, detours, restarts)."""

    def __init__(self, costs: SphereCosts, checks: SolutionChecks, config: StompConfig):
        self.costs, self.checks, self.config = costs, checks, config
        self.detours = Detours(costs, checks, config.detours, config.costs.margin)
        self.lower, self.upper, self.dof = costs.lower, costs.upper, costs.dof

    def coarse(self, q_start: np.ndarray, q_goal: np.ndarray, problem: StompProblem) -> Checked | None:
        """A held move's first trajectory with first_trajectories.keyframes keyframes (the projected straight line,
        else one of the ranked detours: not the costlier search among all of them), where it is a solution; else
        None (also where that many keyframes are not fewer than the plan's)."""
        first = self.config.first_trajectories
        if not 2 < first.keyframes < self.config.keyframes:
            return None
        theta = np.linspace(q_start, q_goal, first.keyframes)
        theta[1:-1] = problem.constraints.project(theta[1:-1], first.projection_steps)
        clearance = self.costs.clearance(theta, problem.obstacles, held=problem.held)
        if min(clearance[0], clearance[-1]) < 0:
            return None  # (the plan with every keyframe says which end collides)
        checked = self.checks.check(theta, problem, clearance)
        if not checked.solution and self.config.detours.heights:
            checked = self.detours.detour(theta, problem, cheapest=False)
        return checked if checked.solution else None

    def first(
        self, theta: np.ndarray, problem: StompProblem, clearance: np.ndarray, rng, vias: bool
    ) -> tuple[Checked, list[np.ndarray]]:
        """The trajectory to start from, with its verdict, and (unconstrained plans) the other first trajectories to
        restart from, best first. theta: the straight line (or the given path), `clearance` its keyframes'; with
        `vias` (no path given), an unconstrained plan also considers paths through random joint-space via points."""
        checked = self.checks.check(theta, problem, clearance)
        restarts = []
        if not checked.solution and vias and problem.constraints is None:
            restarts = self.joint_via_trajectories(theta, problem.obstacles, rng)
            checked = self.checks.check(restarts.pop(0), problem)
        if not checked.solution and problem.constraints is not None and self.config.detours.heights:
            checked = self.detours.detour(theta, problem)
        return checked, restarts

    def joint_via_trajectories(self, straight: np.ndarray, obstacles: Obstacles, rng) -> list[np.ndarray]:
        """First trajectories (each N x n), least in collision first: the straight joint-space line and paths
        through via_candidates random configurations around its middle (joint-space std via_std)."""
        config = self.config.first_trajectories
        start, goal = straight[0], straight[-1]
        middle = 0.5 * (start + goal)
        vias = np.clip(
            middle + config.via_std * rng.standard_normal((config.via_candidates, self.dof)), self.lower, self.upper
        )
        candidates = np.concatenate([straight[None], through_vias(start, vias, goal, len(straight))])
        return self._least_colliding_first(candidates, obstacles)

    def _least_colliding_first(self, paths: np.ndarray, obstacles: Obstacles) -> list[np.ndarray]:
        """The paths (P x N x n) by their summed sphere-model shortfall, the least first (stable). Scored in small
        groups: a sphere pair counts where it comes near in any path of the group."""
        shortfall = np.concatenate(
            [
                self.costs.clearances(group, obstacles)[1].sum(axis=1)
                for group in np.array_split(paths, max(1, len(paths) // 4))
            ]
        )
        return [paths[i] for i in np.argsort(shortfall, kind="stable")]

    def sampled_trajectory(self, theta: np.ndarray, obstacles: Obstacles, rng, deadline: float) -> np.ndarray | None:
        """A trajectory (N x n, theta[0] to theta[-1]) along a path RRT-Connect found clear in the sphere model
        (by required_clearance), its corners kept as keyframes where there are few enough; None where it found
        none within restarts.sampled_draws draws or before `deadline` (time.perf_counter())."""
        required = self.config.costs.required_clearance
        path = rrt_connect(
            theta[0],
            theta[-1],
            lambda q: self.costs.clearance(q, obstacles) > required,
            self.lower,
            self.upper,
            rng,
            RrtConfig(max_draws=self.config.restarts.sampled_draws),
            deadline,
        )
        return None if path is None else keyframes_through(path, len(theta))

    def hand_via_trajectories(self, theta: np.ndarray, obstacles: Obstacles) -> list[np.ndarray]:
        """Trajectories to restart from (each N x n, from theta[0] to theta[-1]), least in collision first, that
        move both hands through two Cartesian via points: from the start pulled back along -x_W by each of
        hand_via_backs and raised to each of hand_via_heights above the higher goal hand, then above the goals at
        that height. From under the table, past a box at its edge, neither the straight line nor random joint-space
        vias lead STOMP out."""
        config = self.config.restarts
        if not (config.hand_via_heights and config.hand_via_backs):
            return []
        start, goal = theta[0], theta[-1]
        X1, X2 = self.costs.end_effectors.poses(np.stack([start, goal]))
        hands_start, hands_goal = np.stack([X1[0], X2[0]])[:, :3, 3], np.stack([X1[1], X2[1]])[:, :3, 3]
        raised, above = [], []
        for height, back in itertools.product(config.hand_via_heights, config.hand_via_backs):
            level = hands_goal[:, 2].max() + height
            raised.append(np.column_stack([hands_start[:, 0] - back, hands_start[:, 1], [level, level]]))
            above.append(np.column_stack([hands_goal[:, :2], [level, level]]))
        q_raised = self._hands_moved_to(np.repeat(start[None], len(raised), 0), np.array(raised))
        q_above = self._hands_moved_to(np.repeat(goal[None], len(above), 0), np.array(above))
        paths = np.stack(
            [resample(np.stack([start, a, b, goal]), len(theta)) for a, b in zip(q_raised, q_above, strict=True)]
        )
        return self._least_colliding_first(paths, obstacles)

    def _hands_moved_to(self, q: np.ndarray, targets_W: np.ndarray, steps: int = 12) -> np.ndarray:
        """Configurations (B x n) from q (B x n) with both grasp frames' origins as near targets_W (B x 2 x 3, m,
        left then right) as the joints' limits allow: damped Gauss-Newton steps on the hands' positions alone, each
        joint change at most HAND_VIA_STEP_RAD."""
        for _ in range(steps):
            (X1, X2), (J1, J2) = self.costs.end_effectors.jacobians(q)
            error = np.concatenate([X1[:, :3, 3] - targets_W[:, 0], X2[:, :3, 3] - targets_W[:, 1]], axis=1)
            jacobian = np.concatenate([J1[:, 3:], J2[:, 3:]], axis=1)
            q = bounded_step(q, error, jacobian, self.lower, self.upper, HAND_VIA_STEP_RAD)
        return q
