"""Reaches: both hands to given poses (the pre-grasps) or the arms to a configuration, around the obstacles. IK goals
(lazily, in the order they are tried), then the straight joint-space move if it is free, else STOMP's path
(shortened to few keyframes)."""

import itertools
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform

from systems.parallel import parallel_calls
from systems.planning.grasp_alternatives import grasp_alternatives, pregrasp_alternatives
from systems.planning.ik import DualArmIk, IkResult
from systems.planning.obstacles import Obstacles
from systems.planning.stomp import Stomp
from systems.planning.straight_motions import PlanningError, StraightMotions
from systems.planning.world import SIDES, PlanningWorld, joint_segment

REACH_LIMIT_MARGIN = 0.15  # rad: a reach's goal keeps its joints this far inside their limits where it can
RISE_M = 0.15  # m: a free move that finds no path from where it starts tries again from this far above it
# Iterations STOMP gets on a reach's goal after the first that IK reached: a goal it cannot reach in as many has its
# full budget only after every later goal had this first look (its first restart comes at 100), so that one goal STOMP
# cannot reach costs its budget once, not once per goal.
SCREENING_ITERATIONS = 100
# Where a pre-grasp is out of reach, pre-grasps this share of the way out from the grasp are tried in turn: the
# approach is then shorter (its straight line still ends at the grasp).
PREGRASP_STANDOFFS = (1.0, 0.5)


class _FirstLookFailed(PlanningError):
    """STOMP found no path to a reach's goal in its first look (SCREENING_ITERATIONS): tried again later in full."""


@dataclass
class Reach:
    """A reach's keyframes (K x n, rad, q_start first) and, per side, which of its targets the last holds (0: as
    given, k: the k-th alternative)."""

    keyframes: np.ndarray
    choice: dict[str, int]


class ReachMotions:
    """Plans reaches in a PlanningWorld (robot and table; the object as points when given)."""

    def __init__(self, world: PlanningWorld, ik: DualArmIk, stomp: Stomp, straights: StraightMotions):
        self.world, self.ik, self.stomp, self.straights = world, ik, stomp, straights

    def reach(
        self,
        q_start: np.ndarray,
        targets_W: dict[str, RigidTransform],
        obstacle_points_W: np.ndarray | None = None,
        alternatives: dict[str, list[RigidTransform]] | None = None,
        approach_to: dict[str, list[RigidTransform]] | None = None,
        scene_W: np.ndarray | None = None,
    ) -> Reach:
        """Keyframes from q_start to both hands at targets_W, collision-free: Drake's geometry, and the sphere model
        against the world's fixed scene and obstacle_points_W (the object as seen, N x 3 in W, e.g. a perceived
        cloud: Drake's model has no geometry for it). alternatives: per side, the targets to try in turn as
        transforms of targets_W[side] on the right (the first the identity), the next only where the ones before
        are out of that hand's reach (DualArmIk.solve). approach_to: per side, where the hand goes straight on from
        each of its targets (the grasps, from pre-grasps; one per alternative, or one without alternatives): a
        goal from which that straight motion fails is passed over for the next, and where every goal is, goals are
        found backwards from the grasps (_goals_from_the_grasps). scene_W: the rest of the scene as the camera saw
        it (its occupied points, N x 3 in W; world.planning_obstacles), avoided too.

        Raises:
            PlanningError: no collision-free IK solution, or no collision-free path to it. A path that fails from a
                goal found backwards does not hide why the goals solved forwards failed (a caller may try targets
                nearer the grasps on an IK failure, never on a path failure).
            ValueError: approach_to does not give one grasp per alternative.
        """
        if approach_to is not None:
            counts = {side: len((alternatives or {}).get(side, [RigidTransform()])) for side in SIDES}
            if any(len(approach_to[side]) != counts[side] for side in SIDES):
                raise ValueError(f"approach_to needs one grasp per alternative per side ({counts})")
        specs = self._goal_specs(q_start, targets_W, alternatives)
        first_spec = next(specs)
        # The sphere model's scene (its distance fields) and the first IK goal need nothing of each other: side by side.
        obstacles, first = parallel_calls(
            lambda: self.world.planning_obstacles(
                obstacle_points_W, self.world.where_the_robot_is_not(scene_W, q_start)
            ),
            lambda: self._goal(q_start, targets_W, first_spec),
        )
        # Straight segments are checked with Drake's geometry, and with the sphere model where anything is points.
        checked = obstacles if obstacle_points_W is not None or scene_W is not None else None
        # Goals in what the camera saw (an elbow through an object set down beside the next) are passed over for the
        # other ways the IK finds: the first goal solved again where it is one.
        clear = self._clear_of(obstacles) if checked is not None else None
        if clear is not None and first.success and not clear(first.q):
            first = self._goal(q_start, targets_W, first_spec, clear)
        forwards = itertools.chain([first], (self._goal(q_start, targets_W, spec, clear) for spec in specs))
        backwards = self._goals_from_the_grasps(q_start, targets_W, alternatives, approach_to) if approach_to else ()
        failure, at_the_grasps = None, ""  # at_the_grasps: why the goals found backwards failed, if they did
        screened = []  # (goal, choice, whether found backwards): STOMP's first look at them found no path
        full_look_given = False  # the first goal STOMP plans to gets all its iterations, as if it were the only one
        for goals in (forwards, backwards):
            for goal in goals:
                if not goal.success:
                    failure = failure or PlanningError(f"no collision-free IK solution at the goal ({goal.message})")
                    at_the_grasps = goal.message if goals is backwards else at_the_grasps
                    continue
                choice = {side: goal.choice.get(side, 0) for side in SIDES}
                try:
                    if approach_to is not None:
                        self._check_approach(goal.q, {side: approach_to[side][choice[side]] for side in SIDES})
                    budget, full_look_given = (SCREENING_ITERATIONS if full_look_given else None), True
                    return Reach(self._reach_path(q_start, goal.q, obstacles, checked, budget), choice)
                except PlanningError as error:
                    if isinstance(error, _FirstLookFailed):
                        screened.append((goal, choice, goals is backwards))
                    failure = error if goals is forwards or failure is None else failure
        for goal, choice, found_backwards in screened:  # now with all their iterations
            try:
                return Reach(self._reach_path(q_start, goal.q, obstacles, checked), choice)
            except PlanningError as error:
                failure = error if not found_backwards or failure is None else failure
        raise PlanningError(f"{failure}; {at_the_grasps}") if at_the_grasps and failure else failure

    def reach_pregrasps(
        self,
        q_start: np.ndarray,
        pregrasps_W: dict[str, RigidTransform],
        grasps_W: dict[str, RigidTransform],
        cloud_W: np.ndarray | None = None,
        obstacle_points_W: np.ndarray | None = None,
        scene_W: np.ndarray | None = None,
        deeper: RigidTransform | None = None,
    ) -> tuple[np.ndarray, dict[str, RigidTransform]]:
        """A pick's reach: keyframes from q_start to both hands at pre-grasps from which the straight approach
        reaches the grasps (each grasp_W moved by `deeper` on the right, if given), and per side the grasp of its
        family it leads to (X_GG'). Where a hand cannot reach its pre-grasp so, the other grasps of its family
        (grasp_alternatives: rolled about the handle, slid along it, judged on the object's points cloud_W, N x 3
        in W), and where none does, pre-grasps nearer the grasps (PREGRASP_STANDOFFS). Where the approach reaches
        none of them `deeper`, it ends at the grasps themselves: the X_GG' returned then take `deeper` back off (an
        approach to grasp @ X_GG' @ deeper ends at grasp @ X_GG of the family). obstacle_points_W, scene_W: as
        reach()'s.

        Raises:
            PlanningError: as reach(), for the first standoff (or the last, where a nearer one was tried).
        """
        families = {side: grasp_alternatives(grasps_W[side], cloud_W) for side in SIDES}
        depths = [RigidTransform()] if deeper is None else [deeper, RigidTransform()]
        failure = None
        for depth in depths:
            try:
                keyframes, chosen = self._reach_to_depth(
                    q_start, pregrasps_W, grasps_W, families, depth, obstacle_points_W, scene_W
                )
            except PlanningError as error:
                failure = failure or error
                if not _out_of_reach(error):
                    break  # reachable but not by a free path: a shallower approach will not help
                continue
            if depth is not depths[0]:
                logging.info("reach: the approach goes no deeper than the grasps (deeper, they are out of reach)")
                chosen = {side: X_GG @ deeper.inverse() for side, X_GG in chosen.items()}
            return keyframes, chosen
        raise failure

    def _reach_to_depth(self, q_start, pregrasps_W, grasps_W, families, depth, obstacle_points_W, scene_W):
        """reach_pregrasps' reach with each approach ending at grasp @ X_GG @ depth (X_GG: each of the hand's
        family): its keyframes and the X_GG chosen per side."""
        # Where each hand's approach ends, for each grasp of its family.
        approach_to = {side: [grasps_W[side] @ X_GG @ depth for X_GG in families[side]] for side in SIDES}
        failure = None
        for standoff in PREGRASP_STANDOFFS:
            nearer = {
                side: RigidTransform(
                    X.rotation(), standoff * X.translation() + (1 - standoff) * grasps_W[side].translation()
                )
                for side, X in pregrasps_W.items()
            }
            alternatives = {
                side: pregrasp_alternatives(grasps_W[side].inverse() @ nearer[side], families[side]) for side in SIDES
            }
            try:
                reach = self.reach(q_start, nearer, obstacle_points_W, alternatives, approach_to, scene_W)
                return reach.keyframes, {side: families[side][reach.choice[side]] for side in SIDES}
            except PlanningError as error:
                failure = failure or error
                if not _out_of_reach(error):
                    break  # reachable but not by a free path: nearer the object will not help
        raise failure

    def _goal_specs(self, q_start, targets_W, alternatives) -> Iterator[tuple]:
        """The reach's IK goals as (alternatives, torso yaw, limit margin), lazily in the order they are tried: the
        targets as given before their alternatives; the torso where it stands first, turned only where the arms
        cannot reach from there; at each torso yaw, joints well inside their limits first (a pre-grasp at a limit
        leaves no room for the approach), then without the margin."""
        for choices in (None, alternatives) if alternatives else (None,):
            for torso in self.ik.torso_candidates(targets_W, q_start):  # lazily: later ones cost solves of their own
                for margin in (REACH_LIMIT_MARGIN, 0.0):
                    yield choices, torso, margin

    def _goal(self, q_start, targets_W, spec: tuple, accept: Callable[[np.ndarray], bool] | None = None) -> IkResult:
        """The IK goal of one of _goal_specs (accept: as DualArmIk.solve's)."""
        choices, torso, margin = spec
        return self.ik.solve(
            targets_W, q_start, restarts=12, limit_margin=margin, torso_yaws=[torso], alternatives=choices,
            accept=accept,
        )  # fmt: skip

    def _clear_of(self, obstacles: Obstacles) -> Callable[[np.ndarray], bool]:
        """Whether a goal (n joints) keeps the sphere model more than a plan's required clearance from `obstacles`
        (STOMP refuses a goal any nearer)."""
        required = self.stomp.config.costs.required_clearance
        return lambda q: bool(self.stomp.clearance(q[None], obstacles, robot_pairs=False)[0] > required)

    def _goals_from_the_grasps(self, q_start, targets_W, alternatives, approach_to) -> Iterator[IkResult]:
        """Pre-grasp goals found backwards: both hands at their grasps (IK, the torso and the alternatives tried as
        _goal_specs orders them), then backed off along the approach to the pre-grasps (straight()). For an arm
        that reaches its grasp only near full stretch: from a pre-grasp solved first, the approach may not reach."""
        grasps = {side: approach_to[side][0] for side in SIDES}
        others = {side: [grasps[side].inverse() @ X for X in approach_to[side]] for side in SIDES}
        for goal in (self._goal(q_start, grasps, spec) for spec in self._goal_specs(q_start, grasps, others)):
            if not goal.success:
                yield IkResult(False, goal.q, f"at the grasps: {goal.message}")
                continue
            choice = {side: goal.choice.get(side, 0) for side in SIDES}
            pregrasps = {
                side: targets_W[side] @ (alternatives[side][choice[side]] if alternatives else RigidTransform())
                for side in SIDES
            }
            try:
                yield IkResult(
                    True, self.straights.straight(goal.q, pregrasps)[-1], "backed off from the grasps", choice
                )
            except PlanningError as error:
                yield IkResult(False, goal.q, f"at the grasps: backing off to the pre-grasps fails ({error})")

    def _check_approach(self, q: np.ndarray, approach_to: dict[str, RigidTransform]):
        """Raises PlanningError where the straight approach from q to approach_to fails."""
        try:
            self.straights.straight(q, approach_to)
        except PlanningError as error:
            raise PlanningError(f"the approach from the goal fails ({error})") from None

    def reach_configuration(
        self,
        q_start: np.ndarray,
        q_goal: np.ndarray,
        obstacle_points_W: np.ndarray | None = None,
        scene_W: np.ndarray | None = None,
    ) -> np.ndarray:
        """Keyframes from q_start to the arm configuration q_goal (the planned joints, rad), collision-free as reach's.
        Where there is no such path from q_start (from beside an object, e.g. backed off an empty grasp), both
        hands rise RISE_M straight up first and the path starts there.

        Raises:
            PlanningError: no collision-free path, from q_start or from above it.
        """
        obstacles = self.world.planning_obstacles(
            obstacle_points_W, self.world.where_the_robot_is_not(scene_W, q_start)
        )
        checked = obstacles if obstacle_points_W is not None or scene_W is not None else None
        q_goal = np.asarray(q_goal, float)
        try:
            return self._reach_path(q_start, q_goal, obstacles, checked)
        except PlanningError as error:
            up = RigidTransform([0.0, 0.0, RISE_M])
            above = {side: up @ X for side, X in self.world.grasp_frame_poses(q_start).items()}
            try:
                rise = self.straights.straight(q_start, above)
                standing = self.world.penetrations(q_start)  # (the rise leaves where the robot stands, as a path does)
                if not all(
                    self.segment_is_free(a, b, checked, tolerated=standing) for a, b in itertools.pairwise(rise)
                ):
                    raise PlanningError("the rise collides")
                onwards = self._reach_path(rise[-1], q_goal, obstacles, checked)
            except PlanningError as after:
                raise PlanningError(f"{error}; from {RISE_M:.2f} m higher: {after}") from None
            logging.info("free move: up %.2f m first", RISE_M)
            return np.concatenate([rise, onwards[1:]])

    def _reach_path(
        self,
        q_start: np.ndarray,
        q_goal: np.ndarray,
        obstacles: Obstacles,
        checked: Obstacles | None,
        max_iterations: int | None = None,
    ) -> np.ndarray:
        """Keyframes from q_start to q_goal: the straight move if it is free, else STOMP's (in `obstacles`; at most
        max_iterations, default its config's), shortened; the straight segments are checked against `checked` too
        (segment_is_free).

        Raises:
            PlanningError: no path (_FirstLookFailed where STOMP found none in max_iterations).
        """
        standing = self.world.penetrations(q_start)  # the robot stands there: leaving it, no deeper
        if self.segment_is_free(q_start, q_goal, checked, tolerated=standing):
            return np.stack([q_start, q_goal])
        result = self.stomp.plan(q_start, q_goal, obstacles, max_iterations=max_iterations)
        if not result.success:
            raise (PlanningError if max_iterations is None else _FirstLookFailed)(result.message)
        logging.info("reach: STOMP, %d iterations, %.2f s", result.iterations, result.seconds)
        keyframes = shortcut(
            lambda a, b: self.segment_is_free(a, b, checked, tolerated=standing), list(result.trajectory)
        )
        if keyframes is None:
            raise PlanningError("the STOMP trajectory collides under Drake's exact check")
        return np.stack(keyframes)

    def segment_is_free(
        self,
        q_from: np.ndarray,
        q_to: np.ndarray,
        obstacles: Obstacles | None = None,
        max_step: float = 0.02,
        tolerated: dict | None = None,
    ) -> bool:
        """Whether the straight joint-space segment q_from -> q_to is collision-free (checked every max_step rad).

        Drake's exact geometry (but for `tolerated` penetrations: PlanningWorld.in_collision), and the sphere model
        against the scene in `obstacles` if given (e.g. an object known by its points); the robot against itself by
        Drake's geometry alone (its spheres are coarser).
        """
        if obstacles is not None:
            states = np.array(joint_segment(q_from, q_to, max_step))
            if self.stomp.clearance(states, obstacles, robot_pairs=False).min() <= 0:
                return False
        return self.world.segment_is_free(q_from, q_to, max_step, tolerated)


def _out_of_reach(error: PlanningError) -> bool:
    """Whether a reach failed for want of an IK goal or of its straight approach (targets nearer the grasps, or less
    deep, may do), not of a free path to a goal."""
    return "no collision-free IK solution" in str(error) or "approach" in str(error)


def shortcut(is_free: Callable[[np.ndarray, np.ndarray], bool], keyframes: list[np.ndarray]) -> list[np.ndarray] | None:
    """Greedily drops keyframes while each remaining segment is free (is_free(q_from, q_to); None if some segment
    is not)."""
    kept, i = [keyframes[0]], 0
    while i < len(keyframes) - 1:
        j = next((j for j in range(len(keyframes) - 1, i, -1) if is_free(keyframes[i], keyframes[j])), None)
        if j is None:
            return None
        kept.append(keyframes[j])
        i = j
    return kept
