"""STOMP (Kalakrishnan et al. 2011) for both arms and the torso: joint-space keyframes of the
planned joints (14, or 15 with the torso yaw), start and goal fixed.

Each iteration draws noisy rollouts around the current trajectory (noise shaped by the
inverse of the finite-difference acceleration metric R, so it is smooth), evaluates each
cost term per rollout and keyframe, turns the costs into per-keyframe probabilities and
averages the noise with them, smooths the update with M (R^-1 with columns scaled) and
keeps the best rollouts for the next iteration. It stops as soon as the trajectory is
collision-free (and within the constraints), or at the iteration or time limit.

Cost terms per keyframe (STOMP-New's):
  collision:   sphere-model clearance below the margin, to the scene (boxes, point sets) and
               between and within the arms and the torso (and of a carried object to the scene);
  limits:      q_l, each joint's closeness to its limits within limit_margin (rollouts are also
               clipped to the limits: the robot is never commanded beyond them);
  torque:      joint torques from inverse dynamics along the keyframes' timing (gravity, velocity,
               acceleration, joint damping and a held payload) against the effort limits;
  duration:    each transition's duration at full joint speed;
  closure:     q_cc of equations (2)-(4) (systems/planning/closure.py) over each transition, when
               both hands hold an object;
  orientation: the hands' world orientation (or tilt), when asked for.
Each term is counted in its unit (TERM_UNITS: 2 cm of clearance shortfall, a joint at its
limit, a joint at its effort limit, a second, a transition at the threshold) times a weight.
Unconstrained plans (reaches) whose straight line is not a solution start from the least colliding of it
and paths through random joint-space via points; when stuck they restart first from a path RRT-Connect samples
in the sphere model (returned at once where it is a solution), then from paths that move both hands through
Cartesian via points (back towards the robot and up above the goal, across, down to it: out from under the
table and over what stands at its edge), least colliding first, then from the other joint-space ones.

With hand constraints (systems/planning/hand_constraints.py), the sampling respects them:
the noise of each rollout lies in the constraints' tangent space at the current trajectory,
and each rollout is projected back onto them (rollout_projection_steps Gauss-Newton steps)
before it is scored; the update is projected too (projection_steps), which STOMP-New did not
do. With both set to 0, only the tangent-space noise and the cost terms keep the constraints.
"""

import itertools
import time
from dataclasses import dataclass, replace

import numpy as np

from systems.planning.closure import (
    ClosureConstraint,
    OrientationConstraint,
    hand_orientation_deviations,
    relative_deviations,
    threshold_cost,
    transition_costs,
)
from systems.planning.hand_constraints import HandConstraints, bounded_step
from systems.planning.heap import keep_freed_heap
from systems.planning.kinematics import Payload, joint_torques, relative_pose
from systems.planning.obstacles import Groups, Obstacles, placed, placed_each
from systems.planning.rrt_connect import RrtConfig, rrt_connect
from systems.planning.world import LIMIT_TOLERANCE_RAD, PlanningWorld

TERMS = ("collision", "limits", "torque", "duration", "closure", "orientation")
# Each term's unit, so that 1 means as much in each: the collision margin of shortfall (m, summed over the
# spheres), a joint at its limit, a joint at its effort limit ((tau / tau_max)^2), a second at full joint speed,
# and a transition at the closure's and orientation's thresholds.
TERM_UNITS = np.array([0.02, 1.0, 1.0, 1.0, 1.0, 1.0])
HAND_VIA_STEP_RAD = 0.3  # the largest joint change of one Gauss-Newton step towards a hand via point
# m: the robot's own sphere pairs nearer each other at a plan's start than the required clearance may come this much
# nearer still along it (the float32 gaps along the plan against the float64 ones at the start)
START_OVERLAP_SLACK = 1e-4
DETOUR_BATCH = 8  # detours whose held part's clearances are found at once, smallest first (_ranked_detour)


@dataclass(frozen=True)
class StompConfig:
    keyframes: int = 16
    rollouts: int = 16
    reused_rollouts: int = 4
    max_iterations: int = 600  # 0: the first trajectory (straight line, detours, via points) alone
    time_limit_s: float = 2.0
    noise_std: float = 0.8  # rad, initial; shrinks by noise_decay per iteration
    noise_decay: float = 0.97
    # rad, initial, with hand constraints: the noise lies in their tangent space and a held move is short
    # (carry over a box, 3 seeds: 0.8 took 47-52 iterations, 0.4 took 25-53, 0.2 failed one in 300).
    constrained_noise_std: float = 0.4
    margin: float = 0.02  # m: clearance below which the collision cost starts
    required_clearance: float = 0.005  # m: a plan counts as collision-free above this (covers model errors)
    # rad: between keyframes the sphere model is checked at states no joint turns more than this apart (at least 4
    # per segment). With 4 per segment (0.06 rad apart in a reach), a finger pad or the palm passed through a box
    # corner or the table's edge between two checked states in 4 of 200 tuning reaches (0.4-2.7 mm deep).
    segment_step_rad: float = 0.02
    sensitivity: float = 10.0  # h in exp(-h * normalised cost)
    seed: int = 0
    torque_limit_penalty: float = 100.0  # per unit of |tau| / tau_max beyond 1, besides (tau / tau_max)^2
    limit_margin: float = 0.1  # rad: q_l grows from 0 to 1 over the last limit_margin before a joint's limit
    segment_s: float = 0.25  # s: the shortest time between keyframes, for the torque term's velocities
    # Weights of the terms in their units (TERM_UNITS), in TERMS' order.
    weights: tuple = (1.0, 0.05, 0.01, 0.05, 1.0, 1.0)
    # m: an unconstrained plan's Cartesian via paths, its restarts after the first trajectory: both hands pulled
    # back towards the robot (along -x_W) by each of hand_via_backs and raised to each of hand_via_heights above
    # the higher goal hand, then carried across at that height above their goals. On the tuning reaches, 8 of 200
    # stayed stuck in collision from the joint-space vias alone (from under the table, past boxes at its edge);
    # 7 of them are solved from these.
    hand_via_heights: tuple = (0.05, 0.15, 0.25, 0.35)
    hand_via_backs: tuple = (0.0, 0.12, 0.25)
    via_candidates: int = 128  # random via points tried for the first trajectory of an unconstrained plan
    via_std: float = 1.0  # rad
    restart_after: int = 100  # iterations without a solution before an unconstrained plan starts again from the next
    # rad: a held move (no first trajectories to start again from) without a solution after restart_after
    # iterations (and every restart_after after) samples again about its trajectory with this noise (its own has
    # shrunk away), and from then on its collision cost also watches each transition where the dense check finds
    # it least clear (a turn stalled with every keyframe and middle clear and a segment 1-4 cm deep at 0.4 of its
    # way); 0: neither. Tuning range, the 15 turns of the first 200 that STOMP left unsolved at 300 iterations, now
    # 600 at most: 0.2 / 0.4 / 0.6 / 0.8 / 1.2 / 1.6 / 2.4 rad solved 5 / 6 / 8 / 8 / 9 / 7 / 5; the noise alone
    # (0.4, nothing watched) 6, the noise with every transition's quarter points 6; restarting at 50 iterations
    # solved no more, no sooner (docs/planning.md). A plan solved within restart_after iterations is unchanged.
    held_restart_noise_std: float = 1.2
    # An unconstrained plan stuck at its first restart first tries a path RRT-Connect samples in the sphere model
    # (systems/planning/rrt_connect.py), this many random draws at most (0: none).
    sampled_restart_draws: int = 1000
    projection_steps: int = 3  # Gauss-Newton steps projecting each update onto the hand constraints
    rollout_projection_steps: int = 2  # ... and each rollout, before it is scored
    # m: with hand constraints, first trajectories with the held object moved this much up and sideways along the
    # way (over or around a box in its path) are tried beside the given one.
    detour_heights: tuple = (0.0, 0.06, 0.12, 0.18)
    detour_sideways: tuple = (-0.12, -0.06, 0.0, 0.06, 0.12)
    detour_ramps: tuple = (1.0, 2.0)  # the detours' profiles along the way, tried in turn (see _detour_trajectory)
    # m: where no detour above is collision-free, these heights too (turns of a held object among tall boxes)
    high_detour_heights: tuple = (0.24, 0.30)
    wide_detour_sideways: tuple = (-0.24, -0.18, 0.18, 0.24)  # m: ... and these farther sideways
    # The detours are first ranked by how clear of the scene the part of the robot that moves with the held object
    # (the hands' spheres and every len // detour_proxy_points-th carried sphere) would be, moved rigidly by each
    # detour's offsets; the best detour_checks of each stage are then built (detour_moved_steps Gauss-Newton steps)
    # and checked one at a time. Only where none of them is a solution are all of them built and scored. Tuning
    # range (the first 100 problems, STOMP alone): lift median 0.127 -> 0.020 s, carry 0.207 -> 0.025 s, the same
    # problems solved (6 Gauss-Newton steps against 10: 0.027 against 0.030 s, carry 0.039 against 0.049 s). Then
    # 3 steps (and 1 projecting) against 6 (and 3): a detour problem's first trajectory 0.86-0.89 of the time (the
    # first 60 tuning indices of carry and set-down, each problem both ways in turn), the same problems solved at 0
    # iterations, and on the turn's first 200 tuning indices the same 132 solved, each with the same iterations but
    # one (solved at 0 instead of 1). With 2 steps, a set-down's first trajectory no longer solved it.
    detour_checks: int = 4
    detour_proxy_points: int = 64
    detour_moved_steps: int = 3
    # A held move's first trajectories (the projected straight line, then the detours) are drawn first with this
    # many keyframes: every check is per keyframe or per segment, and a held move's first trajectory is mostly
    # already a solution. Where one is, the plan is that path, given `keyframes` keyframes along it (each coarse
    # keyframe one of them); where none is, the plan starts again with `keyframes` (the same plan as without). Not
    # for a plan from an initial_path (the pick's held moves, from their Cartesian paths): drawn with 10 keyframes
    # too, two test cans of the place campaign were set down 5.1 and 5.3 deg turned (7/9 against 9/9).
    # Tuning range (turn and carry 60, set-down, lift and reach 40; 300 iterations at most), 10 against 0 (off): the
    # same problems solved with the same iterations, medians carry 6.2 -> 5.1 ms, set-down 6.6 -> 5.6, lift 6.2 ->
    # 5.6; a problem the coarse drawing does not solve pays it (up to 20 ms). The first trajectory alone with 10, 8
    # keyframes solved 52, 51 of the first 60 carries against 54 with 16. The pick's played cubic (60 carries,
    # set-downs, lifts) left the closure no more often (2, 0, 2 plans against 3, 1, 4).
    first_keyframes: int = 10
    # Gauss-Newton steps projecting that coarse straight line (the full plan's: projection_steps). After 2 its
    # keyframes are within 3e-6 of the constraints (m, rad; median 3e-7, two tuning turns' first trajectories), far
    # inside the dense check's t_max and o_max that every plan passes; the third step reaches 1e-12 and costs about
    # 5 % of a set-down's first trajectory.
    first_projection_steps: int = 2


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
class StompResult:
    success: bool
    trajectory: np.ndarray  # keyframes x n
    iterations: int
    seconds: float
    min_clearance_m: float  # smallest sphere-model clearance along the keyframes
    message: str = ""


def interpolate_segments(keyframes: np.ndarray, steps: int) -> np.ndarray:
    """States along each segment between consecutive keyframes, `steps` per segment (both ends included), S x n."""
    s = np.linspace(0, 1, steps + 1)[:, None, None]
    return ((1 - s) * keyframes[None, :-1] + s * keyframes[None, 1:]).reshape(-1, keyframes.shape[1])


def _resample(path: np.ndarray, n: int) -> np.ndarray:
    """n configurations evenly spaced by joint-space length along the piecewise-linear `path` (K x n)."""
    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    if length[-1] <= 0:
        return np.repeat(path[:1], n, axis=0)
    targets = np.linspace(0.0, length[-1], n)
    return np.column_stack([np.interp(targets, length, path[:, j]) for j in range(path.shape[1])])


def _keyframes_through(path: np.ndarray, n: int) -> np.ndarray:
    """n configurations along the piecewise-linear path (K x n, K <= n: each of its corners one of them; the
    segments given keyframes by their joint-space length, at least one each). With more corners than n, evenly
    spaced by length (_resample)."""
    if len(path) > n:
        return _resample(path, n)
    lengths = np.linalg.norm(np.diff(path, axis=0), axis=1)
    intervals = np.ones(len(lengths), int)
    for _ in range(n - 1 - len(lengths)):  # the next interval to the segment whose intervals are longest
        intervals[np.argmax(lengths / intervals)] += 1
    pieces = [
        a + np.linspace(0.0, 1.0, k + 1)[:-1, None] * (b - a)
        for a, b, k in zip(path[:-1], path[1:], intervals, strict=True)
    ]
    return np.concatenate([*pieces, path[-1:]])


def _through(start: np.ndarray, vias: np.ndarray, goal: np.ndarray, n: int) -> np.ndarray:
    """For each via point (V x n), n configurations evenly spaced by joint-space length along start -> via -> goal
    (V x n x n)."""
    first, second = vias - start, goal - vias
    length_1 = np.linalg.norm(first, axis=1, keepdims=True)
    length_2 = np.linalg.norm(second, axis=1, keepdims=True)
    t = np.linspace(0.0, 1.0, n)[None] * (length_1 + length_2)  # V x n, length travelled
    before = np.clip(t / np.maximum(length_1, 1e-12), 0.0, 1.0)[..., None]
    after = np.clip((t - length_1) / np.maximum(length_2, 1e-12), 0.0, 1.0)[..., None]
    return start + before * first[:, None] + after * second[:, None]


def _smoothing_matrices(free: int) -> tuple[np.ndarray, np.ndarray]:
    """R^-1 (noise covariance) and M (update smoothing) for `free` interior keyframes."""
    A = np.zeros((free + 2, free))
    for i in range(free):
        A[i, i], A[i + 1, i], A[i + 2, i] = 1.0, -2.0, 1.0
    R = A.T @ A
    R_inv = np.linalg.inv(R)
    M = R_inv / (free * R_inv.max(axis=0))
    return R_inv / R_inv.max(), M


class Stomp:
    """Plans joint-space trajectories for both arms with STOMP."""

    def __init__(self, world: PlanningWorld, config: StompConfig | None = None):
        """Args:
        world: the robot (batched kinematics, sphere model, grasp frames, joint limits) and the collision filters
            that decide which sphere pairs count. The scene to plan in is each plan's argument.
        config: fixed for this planner's life (default StompConfig()).
        """
        keep_freed_heap()
        self.world = world
        self.end_effectors = world.end_effectors
        self.velocity_limits, self.effort_limits = world.velocity_limits, world.effort_limits
        self.kinematics, self.spheres = world.kinematics, world.spheres
        self.lower, self.upper = np.asarray(world.lower), np.asarray(world.upper)
        self.dof = world.kinematics.dof  # the planned joints: 14 arm joints, and the torso yaw when it is free
        self.config = config or StompConfig()
        self.noise_covariance, self.smoothing = _smoothing_matrices(self.config.keyframes - 2)
        self.noise_factor = np.linalg.cholesky(self.noise_covariance + 1e-12 * np.eye(len(self.noise_covariance)))
        # Sphere pairs that must not meet (unless their geometries are filtered): the arms with each other,
        # with the torso, and within each arm.
        groups = ((1, 2), (1, 0), (2, 0), (1, 1), (2, 2))
        spheres = world.spheres
        pairs = [spheres.pairs(world.inspector, a, b) for a, b in groups]
        self.pair_a = np.concatenate([a for a, _ in pairs])
        self.pair_b = np.concatenate([b for _, b in pairs])
        # Broad phase: a bounding sphere per body; sphere pairs are grouped by their bodies' pair.
        bodies = np.unique(spheres.body)
        self.bound_centre = np.array([spheres.centre_B[spheres.body == b].mean(axis=0) for b in bodies])
        self.bound_radius = np.array(
            [
                np.max(
                    np.linalg.norm(spheres.centre_B[spheres.body == b] - c, axis=1) + spheres.radius[spheres.body == b]
                )
                for b, c in zip(bodies, self.bound_centre, strict=True)
            ]
        )
        self.bound_body = bodies
        self.sphere_bound = np.searchsorted(bodies, spheres.body)  # each sphere's body's bounding sphere
        self.bound_spheres = Groups(self.sphere_bound, len(bodies))
        slot = {b: i for i, b in enumerate(bodies)}
        body_pairs = np.array(
            [(slot[spheres.body[a]], slot[spheres.body[b]]) for a, b in zip(self.pair_a, self.pair_b, strict=True)]
        )
        self.body_pairs, pair_group = np.unique(body_pairs, axis=0, return_inverse=True)
        self.pair_group = pair_group.ravel()
        # Pairs of a sphere fixed to one hand and one fixed to the other: while both hands hold an object (the
        # closure constraint) their gap stays as the grasp made it, so a held move does not count them (the
        # sphere model can find two hands on one handle overlapping where Drake's geometry does not).
        moved_by = np.array([world.kinematics.driving_dof(position) for position in spheres.body])
        hands = {world.kinematics.driving_dof(position) for position in world.end_effectors.positions}
        self.hand_to_hand = np.array(
            [{moved_by[a], moved_by[b]} == hands for a, b in zip(self.pair_a, self.pair_b, strict=True)], bool
        )
        self.hand_sphere = np.isin(moved_by, list(hands))  # the spheres that move with a held object

    def _standing_start(self, q_start: np.ndarray, obstacles: Obstacles) -> Obstacles:
        """The scene a plan from q_start is judged in: where the robot's own spheres come nearer each other at
        q_start than a plan's required clearance, or overlap (the sphere model is coarser than the robot, and the
        robot stands there: a path to there was free by Drake's geometry), each such pair may come as near along
        the plan as it is there, no nearer. Else `obstacles` itself."""
        centres = self.spheres.centres_W(self.kinematics.body_poses(np.asarray(q_start, float)[None]))[0]
        a, b = self.pair_a, self.pair_b
        gap = np.linalg.norm(centres[a] - centres[b], axis=1) - self.spheres.radius[a] - self.spheres.radius[b]
        short = self.config.required_clearance + START_OVERLAP_SLACK - gap
        if short.max() <= 0.0:
            return obstacles
        return obstacles.allowing_self_overlap(np.maximum(short, 0.0))

    def clearance(self, q: np.ndarray, obstacles: Obstacles, held: bool = False, poses=None) -> np.ndarray:
        """Smallest clearance (m) of the sphere model at each configuration (... x n); with `held` (both hands
        hold one object), without the hand-to-hand pairs. `poses`: the tracked bodies' poses at q if known
        ((B x L x 4 x 4), as BatchedKinematics.body_poses)."""
        return self._clearances(q, obstacles, poses, held)[0]

    def _clearances(
        self, q: np.ndarray, obstacles: Obstacles, poses=None, held: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """(smallest clearance, summed shortfall below the margin over all spheres and pairs) per configuration;
        with `held`, the hand-to-hand pairs left out. Exact below the margin; a sphere whose body's bounding sphere
        is farther than the margin from the scene counts at that bound (at least the margin; 9 in 10 of the
        sphere-states of noisy trajectories about a report turn's straight line)."""
        shape = q.shape[:-1]
        if poses is None:
            poses = self.kinematics.body_poses(q.reshape(-1, self.dof))
        centres = self.spheres.centres_W(poses)
        radius = self.spheres.radius
        margin = self.config.margin
        bounds = self._body_bounds(poses)
        to_scene = (obstacles.distance(bounds) - self.bound_radius[:, None]).T  # B x bodies
        scene_gaps = to_scene[:, self.sphere_bound]  # B x S: lower bounds
        b, k = self.bound_spheres.expand(*np.nonzero(to_scene < margin))  # the spheres of the bodies near the scene
        scene_gaps[b, k] = obstacles.distance(centres[b, k]) - radius[k]
        gaps = [scene_gaps]
        if obstacles.carried is not None:
            gaps.append(obstacles.carried_clearances(poses[:, obstacles.carried.slot], margin))
        near = self._near_sphere_pairs(bounds)
        if held:
            near = near[~self.hand_to_hand[near]]
        if len(near):
            a, b = self.pair_a[near], self.pair_b[near]
            centres32 = centres.astype(np.float32)
            difference = centres32[:, a] - centres32[:, b]
            difference *= difference
            distance = np.sqrt(difference[..., 0] + difference[..., 1] + difference[..., 2])
            gap = distance - (radius[a] + radius[b]).astype(np.float32)
            if obstacles.self_overlap is not None:
                gap += obstacles.self_overlap[near]
            gaps.append(gap)
        gaps = np.concatenate(gaps, axis=1, dtype=np.float64)
        shortfall = np.maximum(margin - gaps, 0.0).sum(axis=1)
        return gaps.min(axis=1).reshape(shape), shortfall.reshape(shape)

    def _body_bounds(self, body_poses: np.ndarray) -> np.ndarray:
        """The centres (bodies x B x 3, m, in W) of the bodies' bounding spheres (radii bound_radius)."""
        X_WB = body_poses[:, self.bound_body, :3].swapaxes(0, 1)  # bodies x B x 3 x 4 (body_poses' own layout)
        return placed_each(self.bound_centre[:, None], X_WB)

    def _near_sphere_pairs(self, bounds: np.ndarray) -> np.ndarray:
        """Indices of the sphere pairs whose bodies' bounding spheres (centres bodies x B x 3, _body_bounds) come
        within the margin in any configuration."""
        i, j = self.body_pairs[:, 0], self.body_pairs[:, 1]
        difference = bounds[i] - bounds[j]
        difference *= difference
        squared = difference[..., 0] + difference[..., 1] + difference[..., 2]
        reach = self.bound_radius[i] + self.bound_radius[j] + self.config.margin
        close = (squared < (reach**2)[:, None]).any(axis=1)
        return np.nonzero(close[self.pair_group])[0]

    def _cost_terms(
        self,
        trajectories: np.ndarray,
        obstacles: Obstacles,
        closure=None,
        orientation=None,
        payload=None,
        watched: np.ndarray | None = None,
    ) -> np.ndarray:
        """Every term's cost at every keyframe of every rollout (K x N x len(TERMS)); a transition's terms (duration,
        closure, orientation and, in held moves, its middle's collision, and the collision at its `watched` share of
        the way where given: N - 1 shares) count at the keyframe it leads to."""
        K, N = trajectories.shape[:2]
        config = self.config
        terms = np.zeros((K, N, len(TERMS)))
        poses = self.kinematics.body_poses(trajectories.reshape(-1, self.dof))
        held = closure is not None
        terms[..., 0] = self._clearances(trajectories, obstacles, poses, held)[1]
        if closure is not None or orientation is not None:
            # Held moves: between keyframes too (a carry stalled with its keyframes clear and a segment just short
            # of clear). Not for reaches: there it solved fewer unseen problems (42/47 against 46/47).
            middles = 0.5 * (trajectories[:, :-1] + trajectories[:, 1:])
            middle_poses = self.kinematics.body_poses(middles.reshape(-1, self.dof))
            terms[:, 1:, 0] += self._clearances(middles, obstacles, middle_poses, held)[1]
            if watched is not None:
                share = watched[None, :, None]
                between = (1 - share) * trajectories[:, :-1] + share * trajectories[:, 1:]
                terms[:, 1:, 0] += self._clearances(between, obstacles, held=held)[1]
        to_limit = np.minimum(trajectories - self.lower, self.upper - trajectories)
        terms[..., 1] = (np.maximum(1.0 - to_limit / config.limit_margin, 0.0) ** 2).sum(axis=-1)
        if self.effort_limits is not None:
            qd, qdd = self._rates(trajectories)
            torques = joint_torques(
                self.kinematics, poses, qd.reshape(-1, self.dof), qdd.reshape(-1, self.dof), payload
            )
            load = np.abs(torques.reshape(trajectories.shape)) / self.effort_limits
            terms[..., 2] = (load**2).sum(axis=-1) + config.torque_limit_penalty * np.maximum(load - 1.0, 0.0).sum(-1)
        if self.velocity_limits is not None:
            terms[:, 1:, 3] = (np.abs(np.diff(trajectories, axis=1)) / self.velocity_limits).max(axis=-1)
        if closure is not None or orientation is not None:
            hands = self._transition_hand_poses(trajectories, poses, middle_poses)  # each (K x N-1 x 3) x 4 x 4
            along = (K, N - 1, 3)
        if closure is not None:
            constraint, X_desired = closure
            t_dev, o_dev = relative_deviations(relative_pose(*hands), X_desired)
            terms[:, 1:, 4] = transition_costs(t_dev.reshape(along), o_dev.reshape(along), constraint)
        if orientation is not None:
            constraint, R_desired = orientation
            o_dev = hand_orientation_deviations(hands, R_desired, constraint.upright_only).reshape(along)
            terms[:, 1:, 5] = threshold_cost(o_dev, constraint.o_max, constraint.C).max(axis=-1)
        return terms

    def _rates(self, trajectories: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint velocities and accelerations (each K x N x n) at the keyframes, each transition taking
        segment_s or longer at full joint speed, the ends at rest."""
        steps = np.diff(trajectories, axis=1)
        seconds = np.maximum(self.config.segment_s, (np.abs(steps) / self.velocity_limits).max(axis=-1))[..., None]
        velocity = np.zeros_like(trajectories)
        velocity[:, 1:-1] = 0.5 * (steps[:, :-1] / seconds[:, :-1] + steps[:, 1:] / seconds[:, 1:])
        acceleration = np.zeros_like(trajectories)
        acceleration[:, 1:] = np.diff(velocity, axis=1) / seconds
        return velocity, acceleration

    def _total(self, terms: np.ndarray) -> np.ndarray:
        """The weighted sum of the terms in their units (... x len(TERMS) -> ...)."""
        return terms @ (np.asarray(self.config.weights) / TERM_UNITS)

    def _weights(self, terms: np.ndarray) -> np.ndarray:
        """Per-keyframe probabilities of the rollouts (K x N) from their total cost-to-go (STOMP's)."""
        total = np.cumsum(self._total(terms)[:, ::-1], axis=1)[:, ::-1]
        low, high = total.min(axis=0), total.max(axis=0)
        weights = np.exp(-self.config.sensitivity * (total - low) / np.maximum(high - low, 1e-12))
        return weights / weights.sum(axis=0)

    def _transition_hand_poses(self, trajectories: np.ndarray, poses: np.ndarray, middle: np.ndarray):
        """Both hands' poses at the states along every transition (its start, middle and end), each
        (K * (N-1) * 3) x 4 x 4; `poses` and `middle` are the bodies' poses at the keyframes ((K * N) x L x 4 x 4)
        and the transitions' middles ((K * (N-1)) x L x 4 x 4)."""
        K, N = trajectories.shape[:2]
        at_keyframes = self.end_effectors.from_body_poses(poses.reshape(K, N, *poses.shape[1:]))
        at_middles = self.end_effectors.from_body_poses(middle.reshape(K, N - 1, *middle.shape[1:]))
        return tuple(
            np.stack([X[:, :-1], X_middle, X[:, 1:]], axis=2).reshape(-1, 4, 4)
            for X, X_middle in zip(at_keyframes, at_middles, strict=True)
        )

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
        (default config.projection_steps) damped Gauss-Newton steps, each the smallest joint change."""
        steps = self.config.projection_steps if steps is None else steps
        return self.constraints(X_desired, R_desired, upright_only).project(q, steps)

    def dense_hand_poses(self, theta: np.ndarray, steps: int = 10) -> tuple[np.ndarray, np.ndarray]:
        """Both hands' poses (X_WE1, X_WE2, each S x 4 x 4) at `steps` states per segment of the trajectory."""
        return self.end_effectors.poses(interpolate_segments(theta, steps))

    def orientation_within_limits(self, theta: np.ndarray, orientation, steps: int = 10, hands=None):
        """Whether both hands stay within o_max of their desired orientations densely; also the largest deviation.
        `hands`: dense_hand_poses(theta, steps) if already computed."""
        constraint, R_desired = orientation
        hands = self.dense_hand_poses(theta, steps) if hands is None else hands
        worst = float(hand_orientation_deviations(hands, R_desired, constraint.upright_only).max())
        return worst < constraint.o_max, worst

    def closure_within_limits(self, theta: np.ndarray, closure, steps: int = 10, hands=None):
        """Whether the deviations stay below t_max and o_max densely along the trajectory; also the largest ones.
        `hands`: dense_hand_poses(theta, steps) if already computed."""
        constraint, X_desired = closure
        hands = self.dense_hand_poses(theta, steps) if hands is None else hands
        t_dev, o_dev = relative_deviations(relative_pose(*hands), X_desired)
        ok = t_dev.max() < constraint.t_max and o_dev.max() < constraint.o_max
        return bool(ok), float(t_dev.max()), float(o_dev.max())

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
        n, free = config.keyframes, config.keyframes - 2
        s = np.linspace(0.0, 1.0, n)[:, None]
        theta = (1 - s) * q_start + s * q_goal  # N x n
        if initial_path is not None:
            theta = _resample(np.asarray(initial_path, float), n)
        for q, name in ((q_start, "start"), (q_goal, "goal")):
            if self.world.beyond_limits(q) > LIMIT_TOLERANCE_RAD:
                return StompResult(
                    False, theta, 0, 0.0, np.nan, f"the {name} configuration is outside the joint limits"
                )
        obstacles = self._standing_start(q_start, obstacles)
        closure = orientation = constraints = None
        if closure_constraint is not None or orientation_constraint is not None:
            hands_start = self.end_effectors.poses(q_start[None])
        if closure_constraint is not None:
            closure = (closure_constraint, relative_pose(*hands_start)[0])
        if orientation_constraint is not None:
            orientation = (orientation_constraint, [X[0, :3, :3] for X in hands_start])
        if closure or orientation:
            upright_only = orientation_constraint is not None and orientation_constraint.upright_only
            constraints = self.constraints(
                closure[1] if closure else None, orientation[1] if orientation else None, upright_only
            )
            if initial_path is None and 2 < config.first_keyframes < n:
                coarse = self._coarse_first_trajectory(
                    q_start, q_goal, obstacles, closure, orientation, constraints, payload
                )
                if coarse is not None:  # (a solution at 0 iterations)
                    path, clearance = coarse
                    elapsed = time.perf_counter() - start
                    return StompResult(
                        True,
                        _keyframes_through(path, n),
                        0,
                        elapsed,
                        float(clearance.min()),
                        "collision-free as first drawn",
                    )
            theta[1:-1] = constraints.project(theta[1:-1], config.projection_steps)
        keyframe_clearance = self.clearance(theta, obstacles, held=closure is not None)  # the ends' among them
        if keyframe_clearance[0] < 0 or keyframe_clearance[-1] < 0:
            which = "start" if keyframe_clearance[0] < 0 else "goal"
            end_clearance = float(keyframe_clearance[[0, -1]].min())
            return StompResult(False, theta, 0, 0.0, end_clearance, f"the {which} configuration collides")
        feasible, clearance = self._feasible(theta, obstacles, closure, orientation, keyframe_clearance)
        starts = []  # first trajectories to restart from, best first (unconstrained plans)
        if not feasible and initial_path is None and constraints is None:
            starts = self._initial_trajectories(theta, obstacles, rng)
            theta = starts.pop(0)
            feasible, clearance = self._feasible(theta, obstacles, closure, orientation)
        if not feasible and constraints is not None and config.detour_heights:
            theta, feasible, clearance = self._detour_trajectory(
                theta, obstacles, closure, orientation, constraints, payload
            )
        if feasible:  # the first trajectory is already a solution: nothing to optimise (0 iterations)
            elapsed = time.perf_counter() - start
            return StompResult(True, theta, 0, elapsed, float(clearance.min()), "collision-free as first drawn")
        if config.max_iterations == 0:  # the first trajectory alone was asked for
            elapsed = time.perf_counter() - start
            return StompResult(False, theta, 0, elapsed, float(clearance.min()), "the first trajectory collides")
        std = config.noise_std if constraints is None else config.constrained_noise_std
        kept = np.empty((0, n, self.dof))
        kept_terms = np.empty((0, n, len(TERMS)))
        watching = False  # each transition's least clear share of the way (from a held move's restart on)
        iteration = 0
        while True:
            iteration += 1
            noise = (
                np.einsum("ij,kjd->kid", self.noise_factor, rng.standard_normal((config.rollouts, free, self.dof)))
                * std
            )
            rollouts = np.repeat(theta[None], config.rollouts, axis=0)
            if constraints is not None:
                noise = constraints.tangent(theta[1:-1], noise)
            rollouts[:, 1:-1] += noise
            np.clip(rollouts, self.lower, self.upper, out=rollouts)
            if constraints is not None and config.rollout_projection_steps:
                interior = constraints.project(rollouts[:, 1:-1].reshape(-1, self.dof), config.rollout_projection_steps)
                rollouts[:, 1:-1] = interior.reshape(config.rollouts, free, self.dof)
            watched = self._least_clear_along(theta, obstacles) if watching else None
            terms = self._cost_terms(rollouts, obstacles, closure, orientation, payload, watched)
            all_rollouts = np.concatenate([rollouts, kept])
            all_terms = np.concatenate([terms, kept_terms])
            weights = self._weights(all_terms)
            delta = np.einsum("kn,knd->nd", weights, all_rollouts - theta[None])[1:-1]
            theta[1:-1] += self.smoothing @ delta
            np.clip(theta, self.lower, self.upper, out=theta)
            if constraints is not None and config.projection_steps:
                theta[1:-1] = constraints.project(theta[1:-1], config.projection_steps)
            best = np.argsort(self._total(all_terms).sum(axis=1))[: config.reused_rollouts]
            kept, kept_terms = all_rollouts[best], all_terms[best]
            std *= config.noise_decay
            elapsed = time.perf_counter() - start
            feasible, clearance = self._feasible(theta, obstacles, closure, orientation)
            if feasible:
                return StompResult(True, theta, iteration, elapsed, float(clearance.min()), "collision-free")
            if starts and iteration % config.restart_after == 0:  # stuck: start again from the next first trajectory
                if iteration == config.restart_after:  # (made only when needed: about 15 ms)
                    starts[:0] = self._hand_via_trajectories(theta, obstacles)
                    sampled = self._sampled_trajectory(theta, obstacles, rng, config, iteration, start)
                    if sampled is not None:
                        feasible, clearance = self._feasible(sampled, obstacles, closure, orientation)
                        if feasible:
                            elapsed, clearance = time.perf_counter() - start, float(clearance.min())
                            return StompResult(True, sampled, iteration, elapsed, clearance, "collision-free (sampled)")
                        starts.insert(0, sampled)
                theta, std = starts.pop(0), config.noise_std
                kept, kept_terms = kept[:0], kept_terms[:0]
            if constraints is not None and config.held_restart_noise_std and iteration % config.restart_after == 0:
                std, watching = config.held_restart_noise_std, True
                kept, kept_terms = kept[:0], kept_terms[:0]
            if iteration >= config.max_iterations or elapsed > config.time_limit_s:
                return StompResult(
                    False,
                    theta,
                    iteration,
                    elapsed,
                    float(clearance.min()),
                    f"no collision-free trajectory after {iteration} iterations ({elapsed:.2f} s)",
                )

    def _sampled_trajectory(self, theta, obstacles: Obstacles, rng, config, iteration: int, start: float):
        """A trajectory (N x n, theta[0] to theta[-1]) along a path RRT-Connect found clear in the sphere model
        (by required_clearance), its corners kept as keyframes where there are few enough; None where it found
        none (within its draws or the plan's time), or where the plan has no iterations left to use it (a first
        look) or asked for none (sampled_restart_draws 0). `start`: the plan's start (time.perf_counter())."""
        if iteration >= config.max_iterations or not config.sampled_restart_draws:
            return None
        required = config.required_clearance
        deadline = start + config.time_limit_s
        path = rrt_connect(
            theta[0],
            theta[-1],
            lambda q: self.clearance(q, obstacles) > required,
            self.lower,
            self.upper,
            rng,
            RrtConfig(max_draws=config.sampled_restart_draws),
            deadline,
        )
        return None if path is None else _keyframes_through(path, len(theta))

    def _hand_via_trajectories(self, theta: np.ndarray, obstacles: Obstacles) -> list[np.ndarray]:
        """Trajectories to restart from (each N x n, from theta[0] to theta[-1]), least in collision first, that
        move both hands through two Cartesian via points: from the start pulled back along -x_W by each of
        hand_via_backs and raised to each of hand_via_heights above the higher goal hand, then above the goals at
        that height. STOMP is local: from under the table, past a box at its edge, neither the straight line nor
        random joint-space vias lead it out."""
        config = self.config
        if not (config.hand_via_heights and config.hand_via_backs):
            return []
        start, goal = theta[0], theta[-1]
        X1, X2 = self.end_effectors.poses(np.stack([start, goal]))
        hands_start, hands_goal = np.stack([X1[0], X2[0]])[:, :3, 3], np.stack([X1[1], X2[1]])[:, :3, 3]
        raised, above = [], []
        for height, back in itertools.product(config.hand_via_heights, config.hand_via_backs):
            level = hands_goal[:, 2].max() + height
            raised.append(np.column_stack([hands_start[:, 0] - back, hands_start[:, 1], [level, level]]))
            above.append(np.column_stack([hands_goal[:, :2], [level, level]]))
        q_raised = self._hands_moved_to(np.repeat(start[None], len(raised), 0), np.array(raised))
        q_above = self._hands_moved_to(np.repeat(goal[None], len(above), 0), np.array(above))
        paths = np.stack(
            [_resample(np.stack([start, a, b, goal]), len(theta)) for a, b in zip(q_raised, q_above, strict=True)]
        )
        shortfall = np.concatenate(
            [
                self._clearances(group, obstacles)[1].sum(axis=1)
                for group in np.array_split(paths, max(1, len(paths) // 4))
            ]
        )
        return [paths[i] for i in np.argsort(shortfall, kind="stable")]

    def _hands_moved_to(self, q: np.ndarray, targets_W: np.ndarray, steps: int = 12) -> np.ndarray:
        """Configurations (B x n) from q (B x n) with both grasp frames' origins as near targets_W (B x 2 x 3, m,
        left then right) as the joints' limits allow: damped Gauss-Newton steps on the hands' positions alone, each
        joint change at most HAND_VIA_STEP_RAD."""
        for _ in range(steps):
            (X1, X2), (J1, J2) = self.end_effectors.jacobians(q)
            error = np.concatenate([X1[:, :3, 3] - targets_W[:, 0], X2[:, :3, 3] - targets_W[:, 1]], axis=1)
            jacobian = np.concatenate([J1[:, 3:], J2[:, 3:]], axis=1)
            q = bounded_step(q, error, jacobian, self.lower, self.upper, HAND_VIA_STEP_RAD)
        return q

    def _initial_trajectories(self, straight: np.ndarray, obstacles: Obstacles, rng) -> list[np.ndarray]:
        """First trajectories (each N x n), least in collision first: the straight joint-space line and paths
        through via_candidates random configurations around its middle (joint-space std via_std). STOMP is local:
        from under the table the straight line can lead it into a minimum it does not leave."""
        config = self.config
        start, goal = straight[0], straight[-1]
        middle = 0.5 * (start + goal)
        vias = np.clip(
            middle + config.via_std * rng.standard_normal((config.via_candidates, self.dof)), self.lower, self.upper
        )
        candidates = np.concatenate([straight[None], _through(start, vias, goal, len(straight))])
        # Scored in small groups: a sphere pair counts where it comes near in any path of the group.
        shortfall = np.concatenate(
            [
                self._clearances(group, obstacles)[1].sum(axis=1)
                for group in np.array_split(candidates, max(1, len(candidates) // 4))
            ]
        )
        return [candidates[i] for i in np.argsort(shortfall, kind="stable")]

    def _coarse_first_trajectory(
        self, q_start, q_goal, obstacles, closure, orientation, constraints, payload
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """A held move's first trajectory with config.first_keyframes keyframes (the projected straight line, else
        one of the ranked detours: not the costlier search among all of them) and its keyframes' clearances, where
        it is a solution; else None."""
        theta = np.linspace(q_start, q_goal, self.config.first_keyframes)
        theta[1:-1] = constraints.project(theta[1:-1], self.config.first_projection_steps)
        clearance = self.clearance(theta, obstacles, held=closure is not None)
        if min(clearance[0], clearance[-1]) < 0:
            return None  # (the plan with every keyframe says which end collides)
        feasible, clearance = self._feasible(theta, obstacles, closure, orientation, clearance)
        if not feasible and self.config.detour_heights:
            theta, feasible, clearance = self._detour_trajectory(
                theta, obstacles, closure, orientation, constraints, payload, cheapest=False
            )
        return (theta, clearance) if feasible else None

    def _detour_trajectory(
        self, theta, obstacles, closure, orientation, constraints, payload, cheapest: bool = True
    ) -> tuple[np.ndarray, bool, np.ndarray]:
        """A detour of theta to start from, whether it is a solution, and its keyframes' clearances: the held object
        moved up by each of detour_heights and sideways (across its straight path) by each of detour_sideways, as
        far as the constraints allow, along the profile min(1, ramp sin(pi s)) (s from 0 to 1) of each of
        detour_ramps: a held object carried over or around what stands in its straight path. Where none of those
        is a solution, the same up to high_detour_heights and across to wide_detour_sideways.

        Within each stage, the detours the held part would take clear of the scene (moved rigidly) are built and
        checked first, the smallest first (_ranked_detour). Where none of those is a solution, the cheapest in
        STOMP's cost of theta and all detours (_cheapest_detour), built stage by stage until one is a solution; without
        `cheapest`, theta itself."""
        poses = self.kinematics.body_poses(theta)
        travel = self.end_effectors.from_body_poses(poses[[0, -1]])[0][:, :3, 3]
        along = travel[1] - travel[0]
        across = np.array([-along[1], along[0], 0.0])  # e_z x along
        across /= max(np.linalg.norm(across), 1e-9)
        stages = self._detour_stages()
        held_part = self._held_part(poses[1:-1], obstacles)
        for moves in stages:
            found = self._ranked_detour(theta, obstacles, closure, orientation, constraints, moves, across, held_part)
            if found is not None:
                return found
        if not cheapest:
            return theta, False, None
        return self._cheapest_detour(theta, obstacles, closure, orientation, constraints, payload, stages, across)

    def _detour_stages(self) -> list[list[tuple[float, float]]]:
        """The detours' (height, sideways) moves (m): the first stage's, then the wider stage's not among them."""
        config = self.config
        first = list(itertools.product(config.detour_heights, config.detour_sideways))
        wider = itertools.product(
            config.detour_heights + config.high_detour_heights, config.detour_sideways + config.wide_detour_sideways
        )
        return [first, [move for move in wider if move not in first]]

    def _detour_targets(self, moves, across: np.ndarray, n: int) -> np.ndarray:
        """The held object's offsets (m, in W) at the interior keyframes of each detour of the moves, every ramp in
        turn (ramps x moves, less the zero move) x (n - 2) x 3."""
        offsets = np.array([height * np.array([0.0, 0.0, 1.0]) + sideways * across for height, sideways in moves])
        offsets = offsets[np.any(offsets != 0.0, axis=1)]
        s = np.linspace(0.0, 1.0, n)[1:-1]
        profiles = np.array([np.minimum(1.0, ramp * np.sin(np.pi * s)) for ramp in self.config.detour_ramps])
        return (profiles[:, None, :, None] * offsets[None, :, None, :]).reshape(-1, n - 2, 3)

    def _held_part(self, poses: np.ndarray, obstacles: Obstacles) -> HeldPart:
        """The spheres that move with the held object with the bodies at `poses` (the keyframes', as
        BatchedKinematics.body_poses): the hands' and a subset of the carried ones."""
        centres, radii = self.spheres.centres_W(poses)[:, self.hand_sphere], self.spheres.radius[self.hand_sphere]
        cluster_of = self.spheres.body[self.hand_sphere]  # a hand's spheres: one cluster per body
        if obstacles.carried is not None:
            carried = obstacles.carried
            every = max(1, len(carried.points_B) // self.config.detour_proxy_points)
            points_B = carried.points_B[::every]
            centres = np.concatenate([centres, placed(points_B, poses[:, carried.slot])], axis=1)
            radii = np.concatenate([radii, np.full(len(points_B), carried.radius)])
            cluster_of = np.concatenate([cluster_of, len(self.kinematics.links) + carried.cluster_of[::every]])
        return HeldPart(centres, radii, cluster_of)

    def _ranked_detour(self, theta, obstacles, closure, orientation, constraints, moves, across, held_part):
        """The first solution (theta, True, clearances) among the detour_checks detours of the moves that the held
        part, moved rigidly along each, takes clearest of the scene (all above the margin, the smallest detour
        first; then the least shortfall), or None.

        The held part's clearances along the detours are found smallest detour first, DETOUR_BATCH at a time, until
        one is clear: that one, the first in the ranking, is mostly a solution, and then the rest are not needed."""
        targets = self._detour_targets(moves, across, len(theta))
        if not len(targets):
            return None
        margin = self.config.margin
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
            found = self._detour_through(theta, obstacles, closure, orientation, constraints, targets[first], True)
            if found is not None:
                return found
            shortfall[by_size[done:]] = held_part.shortfall(obstacles, targets[by_size[done:]], margin)
            checked = first  # (the first in the ranking below)
        order = np.lexsort((np.where(shortfall > 0, shortfall, size), shortfall > 0))
        for rank, i in enumerate(order[: self.config.detour_checks]):
            if i == checked:
                continue
            # The first is mostly a solution: checked at once. The others, keyframes first (they may collide).
            found = self._detour_through(theta, obstacles, closure, orientation, constraints, targets[i], rank == 0)
            if found is not None:
                return found
        return None

    def _detour_through(self, theta, obstacles, closure, orientation, constraints, target, at_once: bool):
        """theta with the held object moved by the offsets `target` ((N - 2) x 3, m, in W) at its interior keyframes,
        with True and its keyframes' clearances where it is a solution; else None."""
        candidate = theta.copy()
        candidate[1:-1] = constraints.moved(theta[1:-1], target, self.config.detour_moved_steps)
        feasible, clearance = self._feasible(candidate, obstacles, closure, orientation, at_once=at_once)
        return (candidate, True, clearance) if feasible else None

    def _cheapest_detour(self, theta, obstacles, closure, orientation, constraints, payload, stages, across):
        """The cheapest (in STOMP's cost) of theta and the detours, stage by stage and ramp by ramp until the cheapest
        so far is a solution; with whether it is, and its keyframes' clearances."""
        n = len(theta)

        def cost(trajectories):  # STOMP's total cost of each trajectory (K x N x n)
            return self._total(self._cost_terms(trajectories, obstacles, closure, orientation, payload)).sum(axis=1)

        best, best_cost = theta, cost(theta[None])[0]
        feasible, clearance = False, None
        for moves in stages:
            targets = self._detour_targets(moves, across, n)
            if not len(targets):
                continue
            for per_ramp in np.split(targets, len(self.config.detour_ramps)):
                interior = constraints.moved(np.tile(theta[1:-1], (len(per_ramp), 1)), per_ramp.reshape(-1, 3))
                candidates = np.repeat(theta[None], len(per_ramp), axis=0)
                candidates[:, 1:-1] = interior.reshape(len(per_ramp), n - 2, self.dof)
                costs = cost(candidates)
                if costs.min() < best_cost:
                    best, best_cost = candidates[np.argmin(costs)], costs.min()
                feasible, clearance = self._feasible(best, obstacles, closure, orientation)
                if feasible:
                    return best, True, clearance
        if clearance is None:
            feasible, clearance = self._feasible(best, obstacles, closure, orientation)
        return best, feasible, clearance

    def _feasible(
        self, theta, obstacles, closure, orientation, clearance=None, at_once: bool = False
    ) -> tuple[bool, np.ndarray]:
        """Whether the trajectory is a solution (clear of collision at and between its keyframes, within the
        hand constraints densely), and its keyframes' clearances (`clearance` if already computed). With
        `at_once`, the keyframes and the states between them are checked in one batch (a likely solution: one
        sphere-model call instead of three)."""
        held = closure is not None
        between = None
        if clearance is None and at_once:
            both = self.clearance(np.concatenate([theta, self._segment_states(theta)[0]]), obstacles, held)
            clearance, between = both[: len(theta)], both[len(theta) :]
        elif clearance is None:
            clearance = self.clearance(theta, obstacles, held)
        ok = clearance.min() > self.config.required_clearance
        if ok and (closure is not None or orientation is not None):  # both from one batch of hand poses
            hands = self.dense_hand_poses(theta)
            ok = closure is None or self.closure_within_limits(theta, closure, hands=hands)[0]
            ok = ok and (orientation is None or self.orientation_within_limits(theta, orientation, hands=hands)[0])
        if between is not None:
            return bool(ok and between.min() > self.config.required_clearance), clearance
        return bool(ok and self._segments_clear(theta, obstacles, held)), clearance

    def _least_clear_along(self, theta: np.ndarray, obstacles: Obstacles) -> np.ndarray:
        """Where along each transition of a held move (its share of the way, N - 1) the sphere model is least clear,
        checked as densely as _segments_clear checks it."""
        states, segment, share, _ = self._segment_states(theta)
        clearance = self.clearance(states, obstacles, held=True)
        order = np.lexsort((clearance, segment))  # by segment, then clearance: each segment's least clear first
        first = np.searchsorted(segment[order], np.arange(len(theta) - 1))
        return share[order[first]]

    def _segment_states(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The states strictly between keyframes that _segments_clear checks (S x n), their segments (S), their
        share of the way along it (S) and which of them is its segment's middle one (S)."""
        steps = np.maximum(4, np.ceil(np.abs(np.diff(theta, axis=0)).max(axis=1) / self.config.segment_step_rad))
        steps = steps.astype(int)
        segment = np.repeat(np.arange(len(steps)), steps - 1)
        along = np.concatenate([np.arange(1, k) for k in steps])
        share = along / steps[segment]
        states = (1 - share)[:, None] * theta[segment] + share[:, None] * theta[segment + 1]
        return states, segment, share, along == steps[segment] // 2

    def _segments_clear(self, theta: np.ndarray, obstacles: Obstacles, held: bool) -> bool:
        """The sphere model stays clear between keyframes too (the keyframes themselves checked by the caller): at
        states no joint turns more than segment_step_rad apart (at least 4 steps per segment, each segment as many
        as its largest joint change needs). The states at each segment's middle are checked first: a trajectory
        that collides is mostly found there."""
        states, _, _, middle = self._segment_states(theta)
        return all(
            self.clearance(subset, obstacles, held).min() > self.config.required_clearance
            for subset in (states[middle], states[~middle])
        )
