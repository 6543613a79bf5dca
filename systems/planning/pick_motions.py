"""The motions of a pick, planned from Cartesian goals of both hands' grasp frames G.

  reach:     to given hand poses (the pre-grasps), around the obstacles: IK, then the straight
             joint-space move if it is free, else STOMP (shortened to few keyframes).
  straight:  each hand along a straight line to its goal, keeping its orientation (approach, retreat).
  held move: both hands hold one object and move it by a rigid motion in W (lift, carry, set down):
             configurations holding it solved along the motion (each near the one before), the last
             projected onto the closure manifold, then STOMP from that path with the kinematic-chain
             closure term q_cc (paper eq. 2-4) and, unless the motion turns the object, the hands' world
             orientation constraint. The table (and a box on it) are the obstacles, and the object itself
             when its points are given (a carry).

Each returns joint-space keyframes (K x n, the start first); time parameterisation and the dense
check of the played trajectory are time_parameterise() and closure_deviations() below.

PickMotions is built once from a PlanningWorld (systems/planning/world.py) and a PlannerConfig; it keeps
nothing between motions. What changes from one motion to the next (the object as seen, the points of a
carried object) is each motion's argument.
"""

import dataclasses
import itertools
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.trajectories import PiecewisePolynomial

from systems.parallel import parallel_calls
from systems.planning.closure import ClosureConstraint, OrientationConstraint, deviations, orientation_deviations
from systems.planning.hand_constraints import MAX_STEP, bounded_step, rotation_error
from systems.planning.ik import DualArmIk, IkResult
from systems.planning.kinematics import Payload, off_the_robot
from systems.planning.obstacles import CarriedPoints, Obstacles, covering_centres
from systems.planning.stomp import Stomp, StompConfig
from systems.planning.world import PERCEIVED_SCENE_MARGIN, SCENE_CELL_M, SIDES, PlanningWorld
from systems.robot_io.joint_plan import move_duration

APPROACH_STEPS = 3
REACH_LIMIT_MARGIN = 0.15  # rad: a reach's goal keeps its joints this far inside their limits where it can
MAX_STRAIGHT_STEP = 0.6  # rad: the most a joint may turn between two keyframes of a straight motion
RISE_M = 0.15  # m: a free move that finds no path from where it starts tries again from this far above it
# Iterations STOMP gets on a reach's goal after the first that IK reached: a goal it cannot reach in as many has
# its full budget only after every later goal had this first look (its first restart comes at 100). Without it, a
# large drill's pick (wide_204, yaw 0) spent 95 s on 10 goals of 600 iterations each before the 11th.
SCREENING_ITERATIONS = 100
# Tracking a straight motion's next keyframe: at most this many Gauss-Newton steps, to within these position (m)
# and orientation (rad, about sin of the angle) errors per hand.
TRACK_ITERATIONS = 40
TRACK_TOLERANCES = (0.001, 0.005)
# Shortest duration of one move between sparse (IK) keyframes, and between STOMP's dense ones, s.
SPARSE_SEGMENT_S = 0.8
STOMP_SEGMENT_S = 0.1
HELD_SEGMENT_S = 0.25  # s: a held object is moved gently (the grip is friction only)
# A held object's grasp frames move at most this fast (m/s) and turn at most this fast (rad/s) between keyframes.
# Faster, the grip (friction only) lets it swing: carried 30 cm sideways in 1.2 s (up to 0.4 m/s), a can swung
# 18 deg about its handle grasp.
HELD_SPEED_M_S = 0.1
HELD_TURN_SPEED_RAD_S = 0.3
# The held move's configurations: the left hand within this of its moved pose (m; rad below), the right one
# held at its start pose relative to the left by solve_held's closure tolerances.
HELD_GOAL_POSITION_TOLERANCE = 0.001
# (At most 0.04 rad: a set-down object must stand within 5 degrees of upright.)
HELD_GOAL_ANGLE_TOLERANCES = (0.01, 0.04)
HELD_PATH_STEPS = 10  # configurations solved along a held move's motion
PROJECTION_STEPS = 15
# A carried object as spheres of this radius (m) for the collision cost, centred on its points so that every
# point lies in one (farthest point sampling; 3000 points of a can take 380-510, of a drill 290-330), at most this many.
CARRIED_RADIUS = 0.015
CARRIED_MOST_SPHERES = 600
# The played trajectory's closure is checked at this period, s.
DENSE_CHECK_S = 0.01
# The mass STOMP's torque term assumes for a held object, kg: the heaviest of the familiar categories (the generated
# drills weigh 1.4-2.0 kg), not the object's own mass, which nothing perceives.
HELD_MASS_KG = 2.0


@dataclass(frozen=True)
class PlannerConfig:
    """The planning core's settings, given once when it is built."""

    stomp: StompConfig = field(default_factory=StompConfig)
    held_mass_kg: float = HELD_MASS_KG  # what STOMP's torque term assumes a held object weighs (HELD_MASS_KG)
    # Each arm's IK by batched Gauss-Newton first (SNOPT as the last resort); False: SNOPT alone, as the planning
    # benchmark's problems were drawn (diagrams/generation/planning_problems.py).
    batched_ik: bool = True


class PlanningError(RuntimeError):
    """No motion: names the phase that failed and why."""


class _FirstLookFailed(PlanningError):
    """STOMP found no path to a reach's goal in its first look (SCREENING_ITERATIONS): tried again later in full."""


@dataclass
class HeldMove:
    """A held move's keyframes and what the constraints are measured against."""

    keyframes: np.ndarray  # K x n
    X_E1E2: np.ndarray  # 4 x 4: the right grasp frame in the left one's, as at the start


@dataclass
class Reach:
    """A reach's keyframes (K x n, rad, q_start first) and, per side, which of its targets the last holds (0: as
    given, k: the k-th alternative)."""

    keyframes: np.ndarray
    choice: dict[str, int]


class PickMotions:
    """Plans the motions of a pick in a PlanningWorld (robot and table; the object as points when given).

    Attributes:
        world: the robot and the fixed scene. ik, stomp: the IK and STOMP built from it.
        config: the PlannerConfig it was built with.
    """

    def __init__(self, world: PlanningWorld, config: PlannerConfig | None = None):
        self.world, self.config = world, config or PlannerConfig()
        self.ik = DualArmIk(world, self.config.batched_ik)
        self.stomp = Stomp(world, self.config.stomp)
        self.closure = ClosureConstraint()
        self.orientation = OrientationConstraint()

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
        forwards = self._reach_goals(q_start, targets_W, alternatives)
        # The sphere model's scene (its distance fields) and the first IK goal need nothing of each other: side by side.
        obstacles, first = parallel_calls(
            lambda: self.world.planning_obstacles(obstacle_points_W, self.where_the_robot_is_not(scene_W, q_start)),
            lambda: next(forwards, None),
        )
        forwards = itertools.chain([first] if first is not None else [], forwards)
        # Straight segments are checked with Drake's geometry, and with the sphere model where anything is points.
        checked = obstacles if obstacle_points_W is not None or scene_W is not None else None
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

    def _reach_goals(self, q_start, targets_W, alternatives) -> Iterator[IkResult]:
        """The reach's IK goals, solved lazily in the order they are tried: the targets as given before their
        alternatives; the torso where it stands first, turned only where the arms cannot reach from there; at each
        torso yaw, joints well inside their limits first (a pre-grasp at a limit leaves no room for the
        approach), then without the margin."""
        for choices in (None, alternatives) if alternatives else (None,):
            for torso in self.ik.torso_candidates(targets_W, q_start):  # lazily: later ones cost solves of their own
                for margin in (REACH_LIMIT_MARGIN, 0.0):
                    yield self.ik.solve(
                        targets_W, q_start, restarts=12, limit_margin=margin, torso_yaws=[torso], alternatives=choices
                    )

    def _goals_from_the_grasps(self, q_start, targets_W, alternatives, approach_to) -> Iterator[IkResult]:
        """Pre-grasp goals found backwards: both hands at their grasps (IK, the torso and the alternatives tried as
        _reach_goals tries them), then backed off along the approach to the pre-grasps (straight()). For an arm
        that reaches its grasp only near full stretch: from a pre-grasp solved first, the approach may not reach."""
        grasps = {side: approach_to[side][0] for side in SIDES}
        others = {side: [grasps[side].inverse() @ X for X in approach_to[side]] for side in SIDES}
        for goal in self._reach_goals(q_start, grasps, others):
            if not goal.success:
                yield IkResult(False, goal.q, f"at the grasps: {goal.message}")
                continue
            choice = {side: goal.choice.get(side, 0) for side in SIDES}
            pregrasps = {
                side: targets_W[side] @ (alternatives[side][choice[side]] if alternatives else RigidTransform())
                for side in SIDES
            }
            try:
                yield IkResult(True, self.straight(goal.q, pregrasps)[-1], "backed off from the grasps", choice)
            except PlanningError as error:
                yield IkResult(False, goal.q, f"at the grasps: backing off to the pre-grasps fails ({error})")

    def _check_approach(self, q: np.ndarray, approach_to: dict[str, RigidTransform]):
        """Raises PlanningError where the straight approach from q to approach_to fails."""
        try:
            self.straight(q, approach_to)
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
        obstacles = self.world.planning_obstacles(obstacle_points_W, self.where_the_robot_is_not(scene_W, q_start))
        checked = obstacles if obstacle_points_W is not None or scene_W is not None else None
        q_goal = np.asarray(q_goal, float)
        try:
            return self._reach_path(q_start, q_goal, obstacles, checked)
        except PlanningError as error:
            up = RigidTransform([0.0, 0.0, RISE_M])
            above = {side: up @ X for side, X in self.world.grasp_frame_poses(q_start).items()}
            try:
                rise = self.straight(q_start, above)
                if not all(self.segment_is_free(a, b, checked) for a, b in itertools.pairwise(rise)):
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
        if self.segment_is_free(q_start, q_goal, checked):
            return np.stack([q_start, q_goal])
        result = self.stomp.plan(q_start, q_goal, obstacles, max_iterations=max_iterations)
        if not result.success:
            raise (PlanningError if max_iterations is None else _FirstLookFailed)(result.message)
        logging.info("reach: STOMP, %d iterations, %.2f s", result.iterations, result.seconds)
        keyframes = shortcut(lambda a, b: self.segment_is_free(a, b, checked), list(result.trajectory))
        if keyframes is None:
            raise PlanningError("the STOMP trajectory collides under Drake's exact check")
        return np.stack(keyframes)

    def segment_is_free(
        self, q_from: np.ndarray, q_to: np.ndarray, obstacles: Obstacles | None = None, max_step: float = 0.02
    ) -> bool:
        """Whether the straight joint-space segment q_from -> q_to is collision-free (checked every max_step rad).

        Drake's exact geometry, and the sphere model in `obstacles` if given (e.g. an object known by its points).
        """
        steps = max(1, int(np.ceil(np.max(np.abs(np.asarray(q_to) - q_from)) / max_step)))
        states = [q_from + s * (q_to - q_from) for s in np.linspace(0, 1, steps + 1)]
        if obstacles is not None:
            clearance = self.stomp.clearance(np.array(states), obstacles)
            if clearance.min() <= 0:
                return False
        return not any(self.world.in_collision(q) for q in states)

    def straight(
        self,
        q_start: np.ndarray,
        targets_W: dict[str, RigidTransform],
        steps: int = APPROACH_STEPS,
        min_steps: int | None = None,
    ):
        """Keyframes moving each hand's origin along a straight line to its target, its orientation kept as
        at q_start (the IK branch kept: no half turns, no restarts).

        The whole line is tracked with the arms alone first, the torso held (a turning torso sweeps both hands
        along arcs between keyframes). Where that stalls, each keyframe is tracked from the one before with the
        torso too, and where that stalls, SNOPT solves it from there (then from the nearest seeds), as long as the
        arms stay on their branch (a jump would leave the line between keyframes).

        min_steps: where a later step fails, the keyframes of the steps before it are the move, as long as there
        are at least this many (a back-off goes as far as the arms reach); None: the whole line or nothing.

        Raises:
            PlanningError: naming the step whose IK failed.
        """
        start_poses = self.world.grasp_frame_poses(q_start)
        line = [
            {
                side: RigidTransform(
                    start_poses[side].rotation(),
                    (1 - step / steps) * start_poses[side].translation() + step / steps * targets_W[side].translation(),
                )
                for side in SIDES
            }
            for step in range(1, steps + 1)
        ]
        keyframes, q = [np.asarray(q_start, float)], np.asarray(q_start, float)
        if self.world.torso is not None:
            for targets in line:
                if (q := self.track(q, targets, with_torso=False)) is None:
                    break
                keyframes.append(q)
            else:
                return np.stack(keyframes)
            keyframes, q = [np.asarray(q_start, float)], np.asarray(q_start, float)
        for step, targets in enumerate(line, start=1):
            if (tracked := self.track(q, targets)) is not None:
                keyframes.append(tracked)
                q = tracked
                continue
            torso = [q[self.world.torso]] if self.world.torso is not None else None  # where it stands: no jump
            result = self.ik.solve(targets, q, min_distance=None, allow_half_turn=False, restarts=4, torso_yaws=torso)
            failure = None
            if not result.success:
                failure = f"step {step} of {steps}: IK failed ({result.message})"
            elif np.abs(result.q - q).max() > MAX_STRAIGHT_STEP:
                failure = f"step {step} of {steps}: the arms would change their IK branch"
            if failure is not None:
                if min_steps is None or step - 1 < min_steps:
                    raise PlanningError(failure)
                logging.warning("straight move: %s; ending after step %d", failure, step - 1)
                break
            keyframes.append(result.q)
            q = result.q
        return np.stack(keyframes)

    def track(self, q: np.ndarray, targets_W: dict[str, RigidTransform], with_torso: bool = True) -> np.ndarray | None:
        """The planned joints moved from q until both grasp frames are at targets_W (within TRACK_TOLERANCES), by
        damped Gauss-Newton steps of every joint at once (the torso held unless with_torso) within the limits,
        each joint at most MAX_STEP a step: a nearby target is reached on q's branch. None where the steps stall
        (a limit, a singularity, too far)."""
        world = self.world
        q = np.atleast_2d(np.asarray(q, float)).copy()
        for _ in range(TRACK_ITERATIONS):
            poses, jacobians = world.end_effectors.jacobians(q)
            errors, rows = [], []
            for X, J, side in zip(poses, jacobians, SIDES, strict=True):
                R = targets_W[side].rotation().matrix()
                errors += [X[:, :3, 3] - targets_W[side].translation(), rotation_error(R, X[:, :3, :3])]
                rows += [J[:, 3:], R.T @ J[:, :3]]
            error = np.concatenate(errors, axis=1)[0]
            if all(np.abs(error[i : i + 3]).max() < TRACK_TOLERANCES[(i // 3) % 2] for i in range(0, 12, 3)):
                return q[0]
            jacobian = np.concatenate(rows, axis=1)
            if world.torso is not None and not with_torso:
                jacobian[:, :, world.torso] = 0.0  # a joint without effect on the error is not moved
            q = bounded_step(q, error[None], jacobian, world.lower, world.upper, MAX_STEP)
        return None

    def held_move(
        self,
        q_start: np.ndarray,
        X_motion_W: RigidTransform,
        min_fraction: float = 1.0,
        carried_points_W: np.ndarray | None = None,
        scene_W: np.ndarray | None = None,
    ) -> HeldMove:
        """Keyframes moving both hands (and the object they hold) by X_motion_W (X_WG -> X_motion_W X_WG),
        keeping the hands' relative pose (closure constraint) and, where the goal allows it, their world
        orientations (orientation constraint: the object does not tilt).

        Where the arms cannot reach the whole motion, a share of it down to min_fraction will do (a lift near
        the edge of the arms' reach); where they cannot reach it with the hands' orientation kept within
        0.01 rad, the hands may tilt together (the closure still holds) by up to 0.04 rad. With
        carried_points_W (the held object's points in W at q_start), the object is kept clear of the scene
        too (a carry over a box); without, only the robot is. scene_W: the scene as the camera saw it (occupied
        points, N x 3 in W), kept clear of too.

        Raises:
            PlanningError: the moved hands are out of reach, or STOMP found no constrained path.
        """
        stomp, end_effectors = self.stomp, self.world.end_effectors
        q_start = np.asarray(q_start, float)
        path, fraction, tolerance = self.held_path(q_start, X_motion_W, min_fraction)
        X_E1E2 = end_effectors.relative(q_start[None])[0]
        R_WE = [X[0, :3, :3] for X in end_effectors.poses(q_start[None])]
        # Project onto the closure manifold alone: the goal keeps its own orientation (a carry may turn the
        # object; a lift at the edge of reach may tilt it).
        q_goal = stomp.project(path[-1], X_E1E2, None, steps=PROJECTION_STEPS)[0]
        # The hands keep their world orientation along a translation, and their tilt along a motion that turns
        # the object about the vertical (a carry, a set-down that corrects its yaw): it does not tip on the way.
        R_motion = X_motion_W.rotation().matrix()
        orientation = None
        if np.allclose(R_motion, np.eye(3)):
            orientation = self.orientation
        elif R_motion[2, 2] > 1.0 - 1e-9:
            orientation = dataclasses.replace(self.orientation, upright_only=True)
        if orientation is not None:
            R_goal = [R_motion @ R for R in R_WE]
            tilt = orientation_deviations(end_effectors, q_goal[None], R_goal, orientation.upright_only)
            if tilt.max() >= 0.5 * orientation.o_max:  # the goal itself tilts (the edge of reach): no constraint
                orientation = None
        scene = self.world.table_obstacles(self.where_the_robot_is_not(scene_W, q_start))
        centre_W = None
        if carried_points_W is not None and len(carried_points_W):
            scene = scene.carrying(self.carried(q_start, carried_points_W))
            centre_W = np.mean(carried_points_W, axis=0)
        path[-1] = q_goal
        payload = self.payload(q_start, centre_W)
        result = stomp.plan(q_start, q_goal, scene, self.closure, orientation, initial_path=path, payload=payload)
        if not result.success:
            raise PlanningError(f"STOMP: {result.message}")
        kept = "off" if orientation is None else "upright" if orientation.upright_only else "on"
        logging.info(
            "held move: %.0f %% of the motion, hands within %.2f rad (orientation constraint %s); STOMP %d iterations, "
            "%.2f s", 100 * fraction, tolerance, kept, result.iterations, result.seconds
        )  # fmt: skip
        return HeldMove(result.trajectory, X_E1E2)

    def where_the_robot_is_not(self, scene_W: np.ndarray | None, q: np.ndarray) -> np.ndarray | None:
        """The perceived scene (its occupied points, N x 3 in W) without the points within the robot's sphere model
        at q grown by the scene's margin and two grid cells: the robot stands there, so nothing else does. (A hand
        beside a neighbour of the object it holds starts clear, whatever the points and their margin say.)"""
        if scene_W is None or not len(scene_W):
            return scene_W
        world = self.world
        centres = world.spheres.centres_W(world.kinematics.body_poses(np.asarray(q, float)[None]))[0]
        # The scene's margin, STOMP's required clearance and the field's interpolation.
        return off_the_robot(
            scene_W, np.column_stack([centres, world.spheres.radius]), PERCEIVED_SCENE_MARGIN + 2 * SCENE_CELL_M
        )

    def held_path(self, q_start: np.ndarray, X_motion_W: RigidTransform, min_fraction: float):
        """Configurations holding the object along the motion (HELD_PATH_STEPS of it, each solved from the one
        before, so the arms stay on their branch), the share of the motion reached and the hands' angle
        tolerance used: STOMP's first trajectory and its goal.

        Raises:
            PlanningError: not even min_fraction of the motion is reachable.
        """
        start_poses = self.world.grasp_frame_poses(q_start)
        X_E1E2 = start_poses["left"].InvertAndCompose(start_poses["right"])
        angle_axis = X_motion_W.rotation().ToAngleAxis()
        path, q, worst = [np.asarray(q_start, float)], q_start, 0.0
        for step in range(1, HELD_PATH_STEPS + 1):
            s = step / HELD_PATH_STEPS
            # The object's motion so far: the share s of the translation and of the rotation (about the same axis).
            partial = RigidTransform(
                RotationMatrix(AngleAxis(s * angle_axis.angle(), angle_axis.axis())), s * X_motion_W.translation()
            )
            targets = {side: partial @ X for side, X in start_poses.items()}
            result, tolerance = self._held_configuration(targets, X_E1E2, q)
            if not result.success:
                break
            path.append(result.q)
            q, worst = result.q, max(worst, tolerance)
        reached = (len(path) - 1) / HELD_PATH_STEPS
        if reached < min_fraction - 1e-9 or len(path) == 1:
            raise PlanningError(f"the moved hands are out of reach ({reached:.0%} of the motion at most)")
        return np.stack(path), reached, worst

    def _held_configuration(self, targets, X_E1E2, q_near):
        """Both hands at `targets` (the right one exactly at X_E1E2 from the left), near q_near (no joint more
        than MAX_STRAIGHT_STEP away: a jump, e.g. a wrist turned over, breaks the path between the two), with the
        smallest of HELD_GOAL_ANGLE_TOLERANCES that works, from q_near or else from each arm solved alone."""
        ik = self.ik
        for tolerance in HELD_GOAL_ANGLE_TOLERANCES:
            result = ik.solve_held(targets["left"], X_E1E2, q_near, HELD_GOAL_POSITION_TOLERANCE, tolerance)
            if result.success and np.abs(result.q - q_near).max() <= MAX_STRAIGHT_STEP:
                return result, tolerance
            alone = ik.solve(targets, q_near, HELD_GOAL_POSITION_TOLERANCE, tolerance, None,
                             allow_half_turn=False, restarts=4)  # fmt: skip
            if alone.success:
                result = ik.solve_held(
                    targets["left"], X_E1E2, q_near, HELD_GOAL_POSITION_TOLERANCE, tolerance, start=alone.q
                )
                if result.success and np.abs(result.q - q_near).max() <= MAX_STRAIGHT_STEP:
                    return result, tolerance
        return IkResult(False, q_near, "no configuration near the last one holds the object there"), tolerance

    def payload(self, q: np.ndarray, centre_W: np.ndarray | None = None) -> Payload:
        """The held object for the torque term: config.held_mass_kg at centre_W (m, in W at q; default midway
        between the hands), half of it in each hand."""
        world = self.world
        body = world.kinematics.body_poses(np.asarray(q)[None])[0]
        if centre_W is None:
            centre_W = np.mean([X[:3, 3] for X in world.end_effectors.from_body_poses(body)], axis=0)
        slots = np.array(world.end_effectors.positions)
        points_B = np.array([(centre_W - body[slot][:3, 3]) @ body[slot][:3, :3] for slot in slots])
        return Payload(slots, points_B, np.full(2, 0.5 * self.config.held_mass_kg))

    def carried(self, q: np.ndarray, points_W: np.ndarray) -> CarriedPoints:
        """The held object's points (N x 3 in W) as spheres fixed to the left hand's body (as at q), every point
        within a sphere (at most CARRIED_MOST_SPHERES)."""
        world = self.world
        slot = world.end_effectors.positions[0]
        X_WB = world.kinematics.body_poses(np.asarray(q)[None])[0, slot]
        points = covering_centres(points_W, CARRIED_RADIUS, CARRIED_MOST_SPHERES)
        points_B = (points - X_WB[:3, 3]) @ X_WB[:3, :3]
        return CarriedPoints(slot, points_B, CARRIED_RADIUS)

    def held_segment_durations(self, keyframes: np.ndarray) -> np.ndarray:
        """Shortest duration of each segment of a held move (K - 1 values, s): HELD_SEGMENT_S, or longer where
        a grasp frame moves more than HELD_SPEED_M_S or turns more than HELD_TURN_SPEED_RAD_S would allow."""
        durations = np.full(len(keyframes) - 1, HELD_SEGMENT_S)
        for X in self.world.end_effectors.poses(np.asarray(keyframes)):
            moved = np.linalg.norm(np.diff(X[:, :3, 3], axis=0), axis=1)
            trace = np.einsum("kij,kij->k", X[:-1, :3, :3], X[1:, :3, :3])  # trace(R_k^T R_k+1)
            turned = np.arccos(np.clip(0.5 * (trace - 1.0), -1.0, 1.0))
            durations = np.maximum(durations, np.maximum(moved / HELD_SPEED_M_S, turned / HELD_TURN_SPEED_RAD_S))
        return durations

    def closure_deviations(self, trajectory: PiecewisePolynomial, held: HeldMove) -> tuple[float, float]:
        """Largest (translation m, orientation rad) deviation of the hands' relative pose from the held
        one along the played trajectory, checked every DENSE_CHECK_S."""
        times = np.arange(trajectory.start_time(), trajectory.end_time() + 1e-9, DENSE_CHECK_S)
        q = np.array([trajectory.value(t).ravel() for t in times])
        t_dev, o_dev = deviations(self.world.end_effectors, q, held.X_E1E2)
        return float(t_dev.max()), float(o_dev.max())


def time_parameterise(
    keyframes: np.ndarray, velocity_limits: np.ndarray, start_time: float, min_segment_s: float | np.ndarray
) -> PiecewisePolynomial:
    """A shape-preserving cubic through the keyframes (no overshoot: it stays within their range),
    each segment long enough to move at SPEED_FRACTION of the velocity limits (at least min_segment_s: one
    value, or one per segment), at rest at both ends."""
    shortest = np.broadcast_to(np.asarray(min_segment_s, float), (len(keyframes) - 1,))
    durations = [
        move_duration(a, b, velocity_limits, m)
        for (a, b), m in zip(itertools.pairwise(keyframes), shortest, strict=True)
    ]
    times = start_time + np.concatenate([[0.0], np.cumsum(durations)])
    return PiecewisePolynomial.CubicShapePreserving(times, np.asarray(keyframes).T, zero_end_point_derivatives=True)


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
