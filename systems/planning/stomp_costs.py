"""STOMP's cost model: the robot's sphere model in a scene, and the cost terms of trajectories (STOMP-New's).

Cost terms per keyframe:
  collision:   sphere-model clearance below the margin, to the scene (boxes, point sets) and between and within the
               arms and the torso (and of a carried object to the scene);
  limits:      q_l, each joint's closeness to its limits within limit_margin;
  torque:      joint torques from inverse dynamics along the keyframes' timing (gravity, velocity, acceleration,
               joint damping and a held payload) against the effort limits;
  duration:    each transition's duration at full joint speed;
  closure:     q_cc of equations (2)-(4) (systems/planning/closure.py) over each transition, when both hands hold an
               object;
  orientation: the hands' world orientation (or tilt), when asked for.
Each term is counted in its unit (TERM_UNITS) times a weight (CostConfig.weights).
"""

from dataclasses import dataclass

import numpy as np

from systems.planning.closure import hand_orientation_deviations, relative_deviations, threshold_cost, transition_costs
from systems.planning.dynamics import Payload, joint_torques
from systems.planning.hand_constraints import HandConstraints
from systems.planning.kinematics import relative_pose
from systems.planning.obstacles import Groups, Obstacles, placed_each
from systems.planning.sphere_model import SphereGroup
from systems.planning.stomp_config import CostConfig
from systems.planning.world import PlanningWorld

TERMS = ("collision", "limits", "torque", "duration", "closure", "orientation")
# Each term's unit, so that 1 means as much in each: the collision margin of shortfall (m, summed over the
# spheres), a joint at its limit, a joint at its effort limit ((tau / tau_max)^2), a second at full joint speed,
# and a transition at the closure's and orientation's thresholds.
TERM_UNITS = np.array([0.02, 1.0, 1.0, 1.0, 1.0, 1.0])
# m: the robot's own sphere pairs nearer each other at a plan's end than the required clearance may come this much
# nearer still along it (the float32 gaps along the plan against the float64 ones at the end)
END_OVERLAP_SLACK = 1e-4


@dataclass(frozen=True)
class StompProblem:
    """What one plan is judged in: the scene and, while the hands hold an object, its constraints and mass."""

    obstacles: Obstacles
    closure: tuple | None = None  # (ClosureConstraint, X_E1E2 to keep: 4 x 4), where both hands hold one object
    orientation: tuple | None = None  # (OrientationConstraint, [R_WE1, R_WE2] to keep), where asked for
    constraints: HandConstraints | None = None  # both as HandConstraints (projection, tangent noise); None: neither
    payload: Payload | None = None  # the held object's masses, for the torque term

    @property
    def held(self) -> bool:
        """Both hands hold one object: the hand-to-hand sphere pairs do not count."""
        return self.closure is not None


class SphereCosts:
    """The sphere model's clearances and the cost terms of trajectories, in a PlanningWorld.

    Attributes:
        pair_a, pair_b: the sphere pairs that must not meet (unless their geometries are filtered): the arms with
            each other, with the torso, and within each arm.
        hand_to_hand: per pair, whether one sphere is fixed to each hand (not counted in held moves).
        hand_sphere: per sphere, whether it moves with a held object.
    """

    def __init__(self, world: PlanningWorld, config: CostConfig):
        self.config = config
        self.end_effectors = world.end_effectors
        self.velocity_limits, self.effort_limits = world.velocity_limits, world.effort_limits
        self.kinematics, self.spheres = world.kinematics, world.spheres
        self.lower, self.upper = np.asarray(world.lower), np.asarray(world.upper)
        self.dof = world.kinematics.dof  # the planned joints: 14 arm joints, and the torso yaw when it is free
        left, right, torso = SphereGroup.LEFT, SphereGroup.RIGHT, SphereGroup.TORSO
        groups = ((left, right), (left, torso), (right, torso), (left, left), (right, right))
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
        # While both hands hold an object (the closure constraint) the gap between their spheres stays as the grasp
        # made it (the sphere model can find two hands on one handle overlapping where Drake's geometry does not).
        moved_by = np.array([world.kinematics.driving_dof(position) for position in spheres.body])
        hands = {world.kinematics.driving_dof(position) for position in world.end_effectors.positions}
        self.hand_to_hand = np.array(
            [{moved_by[a], moved_by[b]} == hands for a, b in zip(self.pair_a, self.pair_b, strict=True)], bool
        )
        self.hand_sphere = np.isin(moved_by, list(hands))

    def standing_ends(self, ends: np.ndarray, obstacles: Obstacles) -> Obstacles:
        """The scene a plan between its ends (E x n: the start where the robot stands, and the goal where Drake's
        exact geometry finds it free) is judged in: where the robot's own spheres come nearer each other at an end
        than a plan's required clearance, or overlap (the sphere model is coarser than the robot: a pelvis sphere
        reaches 4.6 cm above the box it covers), each such pair may come as near along the plan as it does at its
        nearer end, no nearer. Else `obstacles` itself."""
        centres = self.spheres.centres_W(self.kinematics.body_poses(np.asarray(ends, float).reshape(-1, self.dof)))
        a, b = self.pair_a, self.pair_b
        gap = np.linalg.norm(centres[:, a] - centres[:, b], axis=-1) - self.spheres.radius[a] - self.spheres.radius[b]
        short = (self.config.required_clearance + END_OVERLAP_SLACK - gap).max(axis=0)
        if short.max() <= 0.0:
            return obstacles
        return obstacles.allowing_self_overlap(np.maximum(short, 0.0))

    def clearance(
        self, q: np.ndarray, obstacles: Obstacles, held: bool = False, poses=None, robot_pairs: bool = True
    ) -> np.ndarray:
        """Smallest clearance (m) of the sphere model at each configuration (... x n); with `held` (both hands
        hold one object), without the hand-to-hand pairs; without `robot_pairs`, the robot against the scene
        alone (where Drake's exact geometry judges the robot against itself). `poses`: the tracked bodies' poses at
        q if known ((B x L x 4 x 4), as BatchedKinematics.body_poses)."""
        return self.clearances(q, obstacles, poses, held, robot_pairs)[0]

    def clearances(
        self, q: np.ndarray, obstacles: Obstacles, poses=None, held: bool = False, robot_pairs: bool = True
    ) -> tuple[np.ndarray, np.ndarray]:
        """(smallest clearance, summed shortfall below the margin over all spheres and pairs) per configuration;
        with `held`, the hand-to-hand pairs left out; without `robot_pairs`, every pair of the robot's own spheres.
        Exact below the margin; a sphere whose body's bounding sphere is farther than the margin from the scene
        counts at that bound (at least the margin: most sphere-states of noisy trajectories are placed only as their
        body's bound)."""
        shape = q.shape[:-1]
        if poses is None:
            poses = self.kinematics.body_poses(q.reshape(-1, self.dof))
        gaps, _ = self._gaps(poses, obstacles, held, robot_pairs)
        shortfall = np.maximum(self.config.margin - gaps, 0.0).sum(axis=1)
        return gaps.min(axis=1).reshape(shape), shortfall.reshape(shape)

    def _gaps(
        self, poses: np.ndarray, obstacles: Obstacles, held: bool, robot_pairs: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """Every gap (m) at each configuration's body poses (B x G): each sphere's to the scene, each carried
        sphere's to the scene, then each near pair of the robot's own spheres' (clearances()); and those pairs'
        indices (into pair_a, pair_b)."""
        centres = self.spheres.centres_W(poses)
        radius = self.spheres.radius
        margin = self.config.margin
        bounds = self.body_bounds(poses)
        to_scene = (obstacles.distance(bounds) - self.bound_radius[:, None]).T  # B x bodies
        scene_gaps = to_scene[:, self.sphere_bound]  # B x S: lower bounds
        b, k = self.bound_spheres.expand(*np.nonzero(to_scene < margin))  # the spheres of the bodies near the scene
        scene_gaps[b, k] = obstacles.distance(centres[b, k]) - radius[k]
        gaps = [scene_gaps]
        if obstacles.carried is not None:
            gaps.append(obstacles.carried_clearances(poses[:, obstacles.carried.slot], margin))
        near = self.near_sphere_pairs(bounds) if robot_pairs else np.zeros(0, int)
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
        return np.concatenate(gaps, axis=1, dtype=np.float64), near

    def deepest_contact(self, q: np.ndarray, obstacles: Obstacles, held: bool = False) -> str:
        """What comes nearest at the configuration q (n,) as clearances() judges it, said for a message: "<body> in
        the scene", "the held object in the scene" or "<body> and <body>" (the robot's own spheres; with `held`, not
        hand against hand), and how deep (mm; a gap where nothing overlaps)."""
        gaps, near = self._gaps(self.kinematics.body_poses(np.asarray(q, float)[None]), obstacles, held, True)
        k, name, body = int(np.argmin(gaps[0])), self.kinematics.body_name, self.spheres.body
        carried = 0 if obstacles.carried is None else gaps.shape[1] - len(body) - len(near)
        if k < len(body):
            what = f"{name(body[k])} in the scene"
        elif k < len(body) + carried:
            what = "the held object in the scene"
        else:
            pair = near[k - len(body) - carried]
            what = f"{name(body[self.pair_a[pair]])} and {name(body[self.pair_b[pair]])}"
        mm = abs(1000 * gaps[0, k])
        return f"{what}, {mm:.{1 if mm < 10 else 0}f} mm {'deep' if gaps[0, k] < 0 else 'apart'}"

    def body_bounds(self, body_poses: np.ndarray) -> np.ndarray:
        """The centres (bodies x B x 3, m, in W) of the bodies' bounding spheres (radii bound_radius)."""
        X_WB = body_poses[:, self.bound_body, :3].swapaxes(0, 1)  # bodies x B x 3 x 4 (body_poses' own layout)
        return placed_each(self.bound_centre[:, None], X_WB)

    def near_sphere_pairs(self, bounds: np.ndarray) -> np.ndarray:
        """Indices of the sphere pairs whose bodies' bounding spheres (centres bodies x B x 3, body_bounds) come
        within the margin in any configuration."""
        i, j = self.body_pairs[:, 0], self.body_pairs[:, 1]
        difference = bounds[i] - bounds[j]
        difference *= difference
        squared = difference[..., 0] + difference[..., 1] + difference[..., 2]
        reach = self.bound_radius[i] + self.bound_radius[j] + self.config.margin
        close = (squared < (reach**2)[:, None]).any(axis=1)
        return np.nonzero(close[self.pair_group])[0]

    def cost_terms(
        self, trajectories: np.ndarray, problem: StompProblem, watched: np.ndarray | None = None
    ) -> np.ndarray:
        """Every term's cost at every keyframe of every trajectory (K x N x len(TERMS)); a transition's terms
        (duration, closure, orientation and, in held moves, its middle's collision, and the collision at its `watched`
        share of the way where given: N - 1 shares) count at the keyframe it leads to."""
        K, N = trajectories.shape[:2]
        config = self.config
        obstacles, closure, orientation, held = problem.obstacles, problem.closure, problem.orientation, problem.held
        terms = np.zeros((K, N, len(TERMS)))
        poses = self.kinematics.body_poses(trajectories.reshape(-1, self.dof))
        terms[..., 0] = self.clearances(trajectories, obstacles, poses, held)[1]
        if closure is not None or orientation is not None:
            # Held moves: between keyframes too (a carry stalled with its keyframes clear and a segment just short
            # of clear). Not for reaches: there it solved fewer problems.
            middles = 0.5 * (trajectories[:, :-1] + trajectories[:, 1:])
            middle_poses = self.kinematics.body_poses(middles.reshape(-1, self.dof))
            terms[:, 1:, 0] += self.clearances(middles, obstacles, middle_poses, held)[1]
            if watched is not None:
                share = watched[None, :, None]
                between = (1 - share) * trajectories[:, :-1] + share * trajectories[:, 1:]
                terms[:, 1:, 0] += self.clearances(between, obstacles, held=held)[1]
        to_limit = np.minimum(trajectories - self.lower, self.upper - trajectories)
        terms[..., 1] = (np.maximum(1.0 - to_limit / config.limit_margin, 0.0) ** 2).sum(axis=-1)
        if self.effort_limits is not None:
            qd, qdd = self.rates(trajectories)
            torques = joint_torques(
                self.kinematics, poses, qd.reshape(-1, self.dof), qdd.reshape(-1, self.dof), problem.payload
            )
            load = np.abs(torques.reshape(trajectories.shape)) / self.effort_limits
            terms[..., 2] = (load**2).sum(axis=-1) + config.torque_limit_penalty * np.maximum(load - 1.0, 0.0).sum(-1)
        if self.velocity_limits is not None:
            terms[:, 1:, 3] = (np.abs(np.diff(trajectories, axis=1)) / self.velocity_limits).max(axis=-1)
        if closure is not None or orientation is not None:
            hands = self.transition_hand_poses(trajectories, poses, middle_poses)  # each (K x N-1 x 3) x 4 x 4
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

    def rates(self, trajectories: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint velocities and accelerations (each K x N x n) at the keyframes, each transition taking
        segment_s or longer at full joint speed, the ends at rest."""
        steps = np.diff(trajectories, axis=1)
        seconds = np.maximum(self.config.segment_s, (np.abs(steps) / self.velocity_limits).max(axis=-1))[..., None]
        velocity = np.zeros_like(trajectories)
        velocity[:, 1:-1] = 0.5 * (steps[:, :-1] / seconds[:, :-1] + steps[:, 1:] / seconds[:, 1:])
        acceleration = np.zeros_like(trajectories)
        acceleration[:, 1:] = np.diff(velocity, axis=1) / seconds
        return velocity, acceleration

    def total(self, terms: np.ndarray) -> np.ndarray:
        """The weighted sum of the terms in their units (... x len(TERMS) -> ...)."""
        return terms @ (np.asarray(self.config.weights) / TERM_UNITS)

    def trajectory_costs(self, trajectories: np.ndarray, problem: StompProblem) -> np.ndarray:
        """Each trajectory's (K x N x n) total cost over its keyframes (K)."""
        return self.total(self.cost_terms(trajectories, problem)).sum(axis=1)

    def transition_hand_poses(self, trajectories: np.ndarray, poses: np.ndarray, middle: np.ndarray):
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
