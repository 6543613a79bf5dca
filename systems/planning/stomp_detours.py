"""A held move's detours: first trajectories with the held object carried over or around what stands in its straight
path (moved up and sideways along the way, as far as the hand constraints allow), ranked by how clear of the scene the
part of the robot that moves with it would be."""

import itertools
from dataclasses import dataclass

import numpy as np

from systems.planning.obstacles import Groups, Obstacles, placed
from systems.planning.stomp_checks import Checked, SolutionChecks
from systems.planning.stomp_config import DetourConfig
from systems.planning.stomp_costs import SphereCosts, StompProblem

DETOUR_BATCH = 8  # detours whose held part's clearances are found at once, smallest first (Detours.ranked)


@dataclass
class HeldPart:
    """Spheres that move with a held object (centres K x P x 3 at K keyframes, m, in W; radii P, m), grouped in
    clusters (cluster_of: P labels, e.g. each hand's bodies and the carried object's CLUSTER_RADIUS covering),
    each bounded at each keyframe by one sphere about its members' mean, so that only the clusters near the scene
    are placed sphere by sphere."""

    centres: np.ndarray
    radii: np.ndarray
    cluster_of: np.ndarray

    def __post_init__(self):
        present = np.zeros(self.cluster_of.max() + 1, bool)
        present[self.cluster_of] = True
        self.cluster_of = (np.cumsum(present) - 1)[self.cluster_of]  # (labels 0..C-1 in their order, none empty)
        clusters = self._clusters = Groups(self.cluster_of, self.cluster_of.max() + 1)
        members = np.zeros((len(clusters.count), len(self.radii)))
        members[self.cluster_of, np.arange(len(self.radii))] = 1.0
        self.cluster_centres = (members / clusters.count[:, None]) @ self.centres  # K x C x 3: each cluster's mean
        reach = np.linalg.norm(self.centres - self.cluster_centres[:, self.cluster_of], axis=2) + self.radii
        # K x C: each cluster's spheres lie within
        self.cluster_radii = np.maximum.reduceat(reach[:, clusters.members], clusters.first, axis=1)

    def gaps(self, obstacles: Obstacles, offsets: np.ndarray, margin: float) -> np.ndarray:
        """Clearances (T x K x P, m) of the spheres moved by each of T offsets per keyframe (T x K x 3, m, in W):
        exact below `margin` (m); elsewhere at least `margin` (that, or exact)."""
        bound = obstacles.distance(self.cluster_centres[None] + offsets[:, :, None]) - self.cluster_radii
        t, k, c = np.nonzero(bound < margin)  # the clusters near the scene, then each of their spheres
        near, p = self._clusters.expand(np.arange(len(c)), c)
        t, k = t[near], k[near]
        gaps = np.full((len(offsets),) + self.centres.shape[:2], margin)
        gaps[t, k, p] = obstacles.distance(self.centres[k, p] + offsets[t, k]) - self.radii[p]
        return gaps

    def shortfall(self, obstacles: Obstacles, offsets: np.ndarray, margin: float) -> np.ndarray:
        """Each offset's (T x K x 3, as gaps) summed shortfall below `margin` (T, m): 0 where clear by the margin."""
        return np.maximum(margin - self.gaps(obstacles, offsets, margin), 0.0).sum(axis=(1, 2))


@dataclass
class DetourSetting:
    """What the detours of one trajectory share: which way is across its path, and the part that moves with the
    held object at its interior keyframes."""

    across: np.ndarray  # 3, unit, in W: horizontal, across the held object's straight path
    held_part: HeldPart


class Detours:
    """A held move's detours (DetourConfig), built by HandConstraints.moved and judged by SolutionChecks."""

    def __init__(self, costs: SphereCosts, checks: SolutionChecks, config: DetourConfig, margin: float):
        """margin: m, the collision cost's (CostConfig.margin): the held part counts as clear beyond it."""
        self.costs, self.checks, self.config, self.margin = costs, checks, config, margin

    def detour(self, theta: np.ndarray, problem: StompProblem, cheapest: bool = True) -> Checked:
        """A detour of theta to start from, with its verdict: the held object moved up by each of `heights` and
        sideways (across its straight path) by each of `sideways`, as far as the constraints allow, along the profile
        min(1, ramp sin(pi s)) (s from 0 to 1) of each of `ramps`. Where none of those is a solution, the same up to
        `high_heights` and across to `wide_sideways`.

        Within each stage, the detours the held part would take clear of the scene (moved rigidly) are built and
        checked first (ranked). Where none of those is a solution: the cheapest in STOMP's cost of theta and all
        detours (cheapest_detour), built stage by stage until one is a solution; without `cheapest`, theta itself
        (no solution, no clearances)."""
        setting = self.setting(theta, problem.obstacles)
        stages = self.stages()
        for moves in stages:
            found = self.ranked(theta, problem, moves, setting)
            if found is not None:
                return found
        if not cheapest:
            return Checked(theta, False, None)
        return self.cheapest_detour(theta, problem, stages, setting.across)

    def setting(self, theta: np.ndarray, obstacles: Obstacles) -> DetourSetting:
        """The way across theta's path (the left hand's, start to goal) and the held part at its interior keyframes."""
        costs = self.costs
        poses = costs.kinematics.body_poses(theta)
        travel = costs.end_effectors.from_body_poses(poses[[0, -1]])[0][:, :3, 3]
        along = travel[1] - travel[0]
        across = np.array([-along[1], along[0], 0.0])  # e_z x along
        across /= max(np.linalg.norm(across), 1e-9)
        return DetourSetting(across, self.held_part(poses[1:-1], obstacles))

    def stages(self) -> list[list[tuple[float, float]]]:
        """The detours' (height, sideways) moves (m): the first stage's, then the wider stage's not among them."""
        config = self.config
        first = list(itertools.product(config.heights, config.sideways))
        wider = itertools.product(config.heights + config.high_heights, config.sideways + config.wide_sideways)
        return [first, [move for move in wider if move not in first]]

    def targets(self, moves, across: np.ndarray, n: int) -> np.ndarray:
        """The held object's offsets (m, in W) at the interior keyframes of each detour of the moves, every ramp in
        turn (ramps x moves, less the zero move) x (n - 2) x 3."""
        offsets = np.array([height * np.array([0.0, 0.0, 1.0]) + sideways * across for height, sideways in moves])
        offsets = offsets[np.any(offsets != 0.0, axis=1)]
        s = np.linspace(0.0, 1.0, n)[1:-1]
        profiles = np.array([np.minimum(1.0, ramp * np.sin(np.pi * s)) for ramp in self.config.ramps])
        return (profiles[:, None, :, None] * offsets[None, :, None, :]).reshape(-1, n - 2, 3)

    def held_part(self, poses: np.ndarray, obstacles: Obstacles) -> HeldPart:
        """The spheres that move with the held object with the bodies at `poses` (the keyframes', as
        BatchedKinematics.body_poses): the hands' and a subset of the carried ones."""
        costs = self.costs
        hand = costs.hand_sphere
        centres, radii = costs.spheres.centres_W(poses)[:, hand], costs.spheres.radius[hand]
        cluster_of = costs.spheres.body[hand]  # a hand's spheres: one cluster per body
        if obstacles.carried is not None:
            carried = obstacles.carried
            every = max(1, len(carried.points_B) // self.config.proxy_points)
            points_B = carried.points_B[::every]
            centres = np.concatenate([centres, placed(points_B, poses[:, carried.slot])], axis=1)
            radii = np.concatenate([radii, np.full(len(points_B), carried.radius)])
            cluster_of = np.concatenate([cluster_of, len(costs.kinematics.links) + carried.cluster_of[::every]])
        return HeldPart(centres, radii, cluster_of)

    def ranking(self, shortfall: np.ndarray, size: np.ndarray) -> np.ndarray:
        """The detours in the order they are built: those whose held part stays clear by the margin (no shortfall),
        the smallest (mean offset, m) first; then the rest, the least shortfall first."""
        return np.lexsort((np.where(shortfall > 0, shortfall, size), shortfall > 0))

    def ranked(self, theta, problem: StompProblem, moves, setting: DetourSetting) -> Checked | None:
        """The first solution among the `checks` detours of the moves first in the ranking, or None.

        The held part's clearances along the detours are found smallest detour first, DETOUR_BATCH at a time, until
        one is clear: that one, the first in the ranking, is mostly a solution, and then the rest are not needed."""
        targets = self.targets(moves, setting.across, len(theta))
        if not len(targets):
            return None
        obstacles, held_part, margin = problem.obstacles, setting.held_part, self.margin
        size = np.linalg.norm(targets, axis=-1).mean(axis=1)
        by_size = np.argsort(size, kind="stable")
        shortfall = np.full(len(targets), np.inf)
        done, first = 0, None
        while done < len(targets) and first is None:
            batch = by_size[done : done + DETOUR_BATCH]
            shortfall[batch] = held_part.shortfall(obstacles, targets[batch], margin)
            done += len(batch)
            clear = batch[shortfall[batch] == 0.0]
            first = clear[0] if len(clear) else None
        checked = None
        if first is not None and done < len(targets):  # the smallest clear detour, before the rest are scored
            found = self.through(theta, problem, targets[first], at_once=True)
            if found is not None:
                return found
            shortfall[by_size[done:]] = held_part.shortfall(obstacles, targets[by_size[done:]], margin)
            checked = first  # (the first in the ranking below)
        for rank, i in enumerate(self.ranking(shortfall, size)[: self.config.checks]):
            if i == checked:
                continue
            # The first is mostly a solution: checked at once. The others, keyframes first (they may collide).
            found = self.through(theta, problem, targets[i], at_once=rank == 0)
            if found is not None:
                return found
        return None

    def through(self, theta: np.ndarray, problem: StompProblem, target: np.ndarray, at_once: bool) -> Checked | None:
        """theta with the held object moved by the offsets `target` ((N - 2) x 3, m, in W) at its interior keyframes,
        where that is a solution; else None."""
        candidate = theta.copy()
        candidate[1:-1] = problem.constraints.moved(theta[1:-1], target, self.config.moved_steps)
        checked = self.checks.check(candidate, problem, at_once=at_once)
        return checked if checked.solution else None

    def cheapest_detour(self, theta, problem: StompProblem, stages, across: np.ndarray) -> Checked:
        """The cheapest (in STOMP's cost) of theta and the detours, stage by stage and ramp by ramp until the cheapest
        so far is a solution; with its verdict."""
        n, dof = len(theta), self.costs.dof
        best, best_cost = theta, self.costs.trajectory_costs(theta[None], problem)[0]
        checked = None
        for moves in stages:
            targets = self.targets(moves, across, n)
            if not len(targets):
                continue
            for per_ramp in np.split(targets, len(self.config.ramps)):
                interior = problem.constraints.moved(np.tile(theta[1:-1], (len(per_ramp), 1)), per_ramp.reshape(-1, 3))
                candidates = np.repeat(theta[None], len(per_ramp), axis=0)
                candidates[:, 1:-1] = interior.reshape(len(per_ramp), n - 2, dof)
                costs = self.costs.trajectory_costs(candidates, problem)
                if costs.min() < best_cost:
                    best, best_cost = candidates[np.argmin(costs)], costs.min()
                checked = self.checks.check(best, problem)
                if checked.solution:
                    return checked
        return checked if checked is not None else self.checks.check(best, problem)
