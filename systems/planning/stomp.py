"""STOMP (Kalakrishnan et al. 2011) for both arms and the torso: joint-space keyframes of the planned joints (14, or
15 with the torso yaw), start and goal fixed.

Each iteration draws noisy rollouts around the current trajectory (noise shaped by the inverse of the
finite-difference acceleration metric R, so it is smooth), evaluates each cost term per rollout and keyframe
(systems/planning/stomp_costs.py), turns the costs into per-keyframe probabilities and averages the noise with them,
smooths the update with M (R^-1 with columns scaled) and keeps the best rollouts for the next iteration. It stops as
soon as the trajectory is a solution (systems/planning/stomp_checks.py), or at the iteration or time limit. It starts
from a first trajectory and, stuck, starts again (systems/planning/stomp_starts.py).

With hand constraints (systems/planning/hand_constraints.py), the sampling respects them: the noise of each rollout
lies in the constraints' tangent space at the current trajectory, and each rollout is projected back onto them
(rollout_projection_steps Gauss-Newton steps) before it is scored; the update is projected too (projection_steps),
which STOMP-New did not do. With both set to 0, only the tangent-space noise and the cost terms keep the constraints.
"""

import time
from dataclasses import dataclass, replace

import numpy as np

from systems.planning.closure import ClosureConstraint, OrientationConstraint
from systems.planning.dynamics import Payload
from systems.planning.hand_constraints import HandConstraints
from systems.planning.heap import keep_freed_heap
from systems.planning.kinematics import relative_pose
from systems.planning.obstacles import Obstacles
from systems.planning.stomp_checks import Checked, SolutionChecks
from systems.planning.stomp_config import SamplingConfig, StompConfig
from systems.planning.stomp_costs import TERMS, SphereCosts, StompProblem
from systems.planning.stomp_starts import FirstTrajectories, keyframes_through, resample, straight_line
from systems.planning.world import LIMIT_TOLERANCE_RAD, PlanningWorld

FIRST_DRAWN = "collision-free as first drawn"


@dataclass
class StompResult:
    success: bool
    trajectory: np.ndarray  # keyframes x n
    iterations: int
    seconds: float
    min_clearance_m: float  # smallest sphere-model clearance along the keyframes
    message: str = ""


def _smoothing_matrices(free: int) -> tuple[np.ndarray, np.ndarray]:
    """R^-1 (noise covariance) and M (update smoothing) for `free` interior keyframes."""
    A = np.zeros((free + 2, free))
    for i in range(free):
        A[i, i], A[i + 1, i], A[i + 2, i] = 1.0, -2.0, 1.0
    R = A.T @ A
    R_inv = np.linalg.inv(R)
    M = R_inv / (free * R_inv.max(axis=0))
    return R_inv / R_inv.max(), M


@dataclass
class _Search:
    """The optimisation's state from one iteration to the next."""

    theta: np.ndarray  # N x n: the current trajectory (updated in place)
    std: float  # rad: the noise's, shrinking each iteration
    kept: np.ndarray  # R x N x n: the best rollouts so far, sampled again beside the new ones
    kept_terms: np.ndarray  # R x N x len(TERMS): their cost terms
    watching: bool = False  # each transition's least clear share of the way is watched too (a held move's restart)

    def start_again(self, theta: np.ndarray, std: float) -> None:
        """From theta with noise std, no rollouts kept."""
        self.theta, self.std = theta, std
        self.kept, self.kept_terms = self.kept[:0], self.kept_terms[:0]


class NextFirstTrajectory:
    """An unconstrained plan's restart: from the next of its first trajectories, with the initial noise. At the first
    restart, the hands' Cartesian via paths go first, and before them a path RRT-Connect samples (where the plan has
    iterations left to use it)."""

    def __init__(self, starts: FirstTrajectories, problem: StompProblem, trajectories: list, rng, config, start: float):
        """trajectories: the first trajectories left, best first. config: the plan's StompConfig; start: when the
        plan started (time.perf_counter())."""
        self.starts, self.problem, self.trajectories, self.rng = starts, problem, trajectories, rng
        self.config, self.start = config, start

    def __call__(self, search: _Search, iteration: int) -> Checked | None:
        """Starts the search again; returns the sampled path's verdict where one was sampled."""
        if not self.trajectories:
            return None
        sampled = None
        if iteration == self.config.restarts.after:  # (made only when needed: about 15 ms)
            self.trajectories[:0] = self.starts.hand_via_trajectories(search.theta, self.problem.obstacles)
            if iteration < self.config.max_iterations and self.config.restarts.sampled_draws:
                deadline = self.start + self.config.time_limit_s
                path = self.starts.sampled_trajectory(search.theta, self.problem.obstacles, self.rng, deadline)
                if path is not None:
                    sampled = self.starts.checks.check(path, self.problem)
                    if sampled.solution:
                        return sampled
                    self.trajectories.insert(0, path)
        search.start_again(self.trajectories.pop(0), self.config.sampling.noise_std)
        return sampled


class WiderNoise:
    """A held move's restart (it has no first trajectories to start again from): the same trajectory sampled with
    restarts.held_noise_std (its own noise has shrunk away), each transition's least clear share of the way watched
    from then on."""

    def __init__(self, noise_std: float):
        self.noise_std = noise_std

    def __call__(self, search: _Search, iteration: int) -> None:
        search.start_again(search.theta, self.noise_std)
        search.watching = True


class Stomp:
    """Plans joint-space trajectories for both arms with STOMP.

    Attributes:
        costs: the sphere model's clearances and the cost terms (SphereCosts).
        checks: whether a trajectory is a solution (SolutionChecks).
        starts: the first trajectories and restart paths (FirstTrajectories).
    """

    def __init__(self, world: PlanningWorld, config: StompConfig | None = None):
        """Args:
        world: the robot (batched kinematics, sphere model, grasp frames, joint limits) and the collision filters
            that decide which sphere pairs count. The scene to plan in is each plan's argument.
        config: fixed for this planner's life (default StompConfig()).
        """
        keep_freed_heap()
        self.world = world
        self.config = config or StompConfig()
        self.costs = SphereCosts(world, self.config.costs)
        self.checks = SolutionChecks(self.costs, self.config.costs)
        self.starts = FirstTrajectories(self.costs, self.checks, self.config)
        self.end_effectors = world.end_effectors
        self.lower, self.upper, self.dof = self.costs.lower, self.costs.upper, self.costs.dof
        self.noise_covariance, self.smoothing = _smoothing_matrices(self.config.keyframes - 2)
        self.noise_factor = np.linalg.cholesky(self.noise_covariance + 1e-12 * np.eye(len(self.noise_covariance)))

    def clearance(
        self, q: np.ndarray, obstacles: Obstacles, held: bool = False, poses=None, robot_pairs: bool = True
    ) -> np.ndarray:
        """The sphere model's smallest clearance (m) at each configuration (... x n): SphereCosts.clearance."""
        return self.costs.clearance(q, obstacles, held, poses, robot_pairs)

    def standing_at_ends(self, q_start: np.ndarray, q_goal: np.ndarray, obstacles: Obstacles) -> Obstacles:
        """The scene a plan from q_start to q_goal is judged in: as seen from where the robot stands and, where
        Drake's exact geometry finds the goal free (an IK goal), from the goal too (SphereCosts.standing_ends)."""
        ends = [q_start] if self.world.in_collision(q_goal) else [q_start, q_goal]
        return self.costs.standing_ends(np.stack(ends), obstacles)

    def constraints(self, X_desired=None, R_desired=None, upright_only: bool = False) -> HandConstraints:
        """The hand constraints: the relative hand pose X_E1E2 (X_desired) and/or the hands' world orientations."""
        return HandConstraints(self.end_effectors, self.lower, self.upper, X_desired, R_desired, upright_only)

    def project(
        self,
        q: np.ndarray,
        X_desired: np.ndarray | None,
        R_desired=None,
        steps: int | None = None,
        upright_only: bool = False,
    ) -> np.ndarray:
        """Configurations (B x n) moved back towards the desired relative hand pose X_E1E2 (X_desired)
        and/or the hands' desired world orientations (R_desired; with upright_only their tilt only): `steps`
        (default sampling.projection_steps) damped Gauss-Newton steps, each the smallest joint change."""
        steps = self.config.sampling.projection_steps if steps is None else steps
        return self.constraints(X_desired, R_desired, upright_only).project(q, steps)

    def plan(
        self,
        q_start: np.ndarray,
        q_goal: np.ndarray,
        obstacles: Obstacles,
        closure_constraint: ClosureConstraint | None = None,
        orientation_constraint: OrientationConstraint | None = None,
        initial_path: np.ndarray | None = None,
        payload: Payload | None = None,
        max_iterations: int | None = None,
    ) -> StompResult:
        """Plans from q_start to q_goal (both fixed).

        Args:
            initial_path: configurations (K x n, from q_start to q_goal) the first trajectory follows,
                resampled to the keyframes by path length; default the straight joint-space line.
            closure_constraint: keep the hands' relative pose as at q_start (both hands hold an object).
            orientation_constraint: keep both hands' world orientations (or with upright_only their tilt) as at
                q_start.
            payload: a held object's masses, for the torque term.
            max_iterations: fewer iterations than the config's (a first look at a goal among several).
        """
        config = self.config
        if max_iterations is not None:
            config = replace(config, max_iterations=min(max_iterations, config.max_iterations))
        rng = np.random.default_rng(config.seed)
        start = time.perf_counter()
        n = config.keyframes
        given = initial_path is not None
        theta = resample(np.asarray(initial_path, float), n) if given else straight_line(q_start, q_goal, n)
        for q, name in ((q_start, "start"), (q_goal, "goal")):
            if self.world.beyond_limits(q) > LIMIT_TOLERANCE_RAD:
                return StompResult(
                    False, theta, 0, 0.0, np.nan, f"the {name} configuration is outside the joint limits"
                )
        problem = self._problem(q_start, q_goal, obstacles, closure_constraint, orientation_constraint, payload)
        if problem.constraints is not None:
            coarse = None if given else self.starts.coarse(q_start, q_goal, problem)
            if coarse is not None:  # (a solution at 0 iterations)
                return _result(coarse, 0, start, FIRST_DRAWN, keyframes_through(coarse.trajectory, n))
            theta[1:-1] = problem.constraints.project(theta[1:-1], config.sampling.projection_steps)
        clearance = self.costs.clearance(theta, problem.obstacles, held=problem.held)  # the ends' among them
        if clearance[0] < 0 or clearance[-1] < 0:
            which, end = ("start", theta[0]) if clearance[0] < 0 else ("goal", theta[-1])
            contact = self.costs.deepest_contact(end, problem.obstacles, problem.held)
            message = f"the {which} configuration collides ({contact})"
            return StompResult(False, theta, 0, 0.0, float(clearance[[0, -1]].min()), message)
        required = config.costs.required_clearance
        if clearance[-1] <= required:  # (every keyframe of a solution is more than that clear; the goal is fixed)
            return StompResult(
                False, theta, 0, 0.0, float(clearance[-1]),
                f"the goal configuration is {1000 * clearance[-1]:.1f} mm from an obstacle (a plan keeps "
                f"{1000 * required:.0f} mm)",
            )  # fmt: skip
        first, restarts = self.starts.first(theta, problem, clearance, rng, vias=not given)
        if first.solution:  # nothing to optimise (0 iterations)
            return _result(first, 0, start, FIRST_DRAWN)
        if config.max_iterations == 0:  # the first trajectory alone was asked for
            return _result(first, 0, start, "the first trajectory collides")
        return self._optimise(first.trajectory, problem, restarts, rng, config, start)

    def _problem(self, q_start, q_goal, obstacles, closure_constraint, orientation_constraint, payload) -> StompProblem:
        """The plan's problem: the scene as judged from its ends (standing_at_ends), and the hand constraints to
        keep as they are at q_start."""
        obstacles = self.standing_at_ends(q_start, q_goal, obstacles)
        if closure_constraint is None and orientation_constraint is None:
            return StompProblem(obstacles, payload=payload)
        hands_start = self.end_effectors.poses(q_start[None])
        closure = orientation = None
        if closure_constraint is not None:
            closure = (closure_constraint, relative_pose(*hands_start)[0])
        if orientation_constraint is not None:
            orientation = (orientation_constraint, [X[0, :3, :3] for X in hands_start])
        upright_only = orientation_constraint is not None and orientation_constraint.upright_only
        constraints = self.constraints(
            closure[1] if closure else None, orientation[1] if orientation else None, upright_only
        )
        return StompProblem(obstacles, closure, orientation, constraints, payload)

    def _optimise(self, theta, problem: StompProblem, restarts: list, rng, config: StompConfig, start: float):
        """STOMP's iterations from theta until a solution, or the iteration or time limit (StompResult)."""
        sampling = config.sampling
        std = sampling.noise_std if problem.constraints is None else sampling.constrained_noise_std
        n = config.keyframes
        search = _Search(theta, std, np.empty((0, n, self.dof)), np.empty((0, n, len(TERMS))))
        restart = self._restart_policy(problem, restarts, rng, config, start)
        iteration = 0
        while True:
            iteration += 1
            rollouts, terms = self._rollouts(search, problem, rng, sampling)
            self._update(search, rollouts, terms, problem, sampling)
            elapsed = time.perf_counter() - start
            checked = self.checks.check(search.theta, problem)
            if checked.solution:
                return _result(checked, iteration, start, "collision-free", elapsed=elapsed)
            if restart is not None and iteration % config.restarts.after == 0:
                sampled = restart(search, iteration)
                if sampled is not None and sampled.solution:
                    return _result(sampled, iteration, start, "collision-free (sampled)")
                checked = checked if sampled is None else sampled  # (the last verdict, reported on a time-out)
            if iteration >= config.max_iterations or elapsed > config.time_limit_s:
                message = f"no collision-free trajectory after {iteration} iterations ({elapsed:.2f} s)"
                clearance = float(checked.clearance.min())
                return StompResult(False, search.theta, iteration, elapsed, clearance, message)

    def _restart_policy(self, problem: StompProblem, restarts: list, rng, config: StompConfig, start: float):
        """What the plan does every restarts.after iterations without a solution (None: nothing)."""
        if problem.constraints is None:
            return NextFirstTrajectory(self.starts, problem, restarts, rng, config, start)
        if config.restarts.held_noise_std:
            return WiderNoise(config.restarts.held_noise_std)
        return None

    def _rollouts(self, search: _Search, problem: StompProblem, rng, sampling: SamplingConfig):
        """New noisy rollouts about the current trajectory (K x N x n, within the joint limits and, where there are
        hand constraints, their noise in the constraints' tangent space and the rollouts projected onto them), with
        their cost terms (K x N x len(TERMS))."""
        theta, constraints, free = search.theta, problem.constraints, self.config.keyframes - 2
        draws = rng.standard_normal((sampling.rollouts, free, self.dof))
        noise = np.einsum("ij,kjd->kid", self.noise_factor, draws) * search.std
        rollouts = np.repeat(theta[None], sampling.rollouts, axis=0)
        if constraints is not None:
            noise = constraints.tangent(theta[1:-1], noise)
        rollouts[:, 1:-1] += noise
        np.clip(rollouts, self.lower, self.upper, out=rollouts)
        if constraints is not None and sampling.rollout_projection_steps:
            interior = constraints.project(rollouts[:, 1:-1].reshape(-1, self.dof), sampling.rollout_projection_steps)
            rollouts[:, 1:-1] = interior.reshape(sampling.rollouts, free, self.dof)
        watched = self.checks.least_clear_along(theta, problem.obstacles) if search.watching else None
        return rollouts, self.costs.cost_terms(rollouts, problem, watched)

    def _update(self, search: _Search, rollouts, terms, problem: StompProblem, sampling: SamplingConfig) -> None:
        """STOMP's update of the current trajectory from the new and the kept rollouts (the noise averaged with
        their per-keyframe probabilities, smoothed by M, within the limits, projected onto the hand constraints);
        the best of them kept, the noise shrunk."""
        theta = search.theta
        all_rollouts = np.concatenate([rollouts, search.kept])
        all_terms = np.concatenate([terms, search.kept_terms])
        weights = self._probabilities(all_terms, sampling.sensitivity)
        delta = np.einsum("kn,knd->nd", weights, all_rollouts - theta[None])[1:-1]
        theta[1:-1] += self.smoothing @ delta
        np.clip(theta, self.lower, self.upper, out=theta)
        if problem.constraints is not None and sampling.projection_steps:
            theta[1:-1] = problem.constraints.project(theta[1:-1], sampling.projection_steps)
        best = np.argsort(self.costs.total(all_terms).sum(axis=1))[: sampling.reused_rollouts]
        search.kept, search.kept_terms = all_rollouts[best], all_terms[best]
        search.std *= sampling.noise_decay

    def _probabilities(self, terms: np.ndarray, sensitivity: float) -> np.ndarray:
        """Per-keyframe probabilities of the rollouts (K x N) from their total cost-to-go (STOMP's)."""
        total = np.cumsum(self.costs.total(terms)[:, ::-1], axis=1)[:, ::-1]
        low, high = total.min(axis=0), total.max(axis=0)
        weights = np.exp(-sensitivity * (total - low) / np.maximum(high - low, 1e-12))
        return weights / weights.sum(axis=0)


def _result(checked: Checked, iterations: int, start: float, message: str, trajectory=None, elapsed=None):
    """The StompResult of a checked trajectory (`trajectory` in its place where given: the same path with more
    keyframes), `elapsed` (s) since `start` (time.perf_counter()) unless given."""
    elapsed = time.perf_counter() - start if elapsed is None else elapsed
    trajectory = checked.trajectory if trajectory is None else trajectory
    return StompResult(checked.solution, trajectory, iterations, elapsed, float(checked.clearance.min()), message)
