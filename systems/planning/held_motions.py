"""Held moves: both hands hold one object and move it by a rigid motion in W (lift, carry, set down).

Configurations holding it are solved along the motion (each near the one before), the last projected onto the closure
manifold, then STOMP plans from that path with the kinematic-chain closure term q_cc (paper eq. 2-4) and, unless the
motion turns the object, the hands' world orientation constraint. The table (and a box on it) are the obstacles, and
the object itself when its points are given (a carry). Also: the held object for STOMP's torque term and its
collision cost, the segments' shortest durations, and the closure's dense check along the played trajectory.
"""

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.trajectories import PiecewisePolynomial

from systems.planning.closure import ClosureConstraint, OrientationConstraint, deviations, orientation_deviations
from systems.planning.dynamics import Payload
from systems.planning.ik import DualArmIk, IkResult
from systems.planning.obstacles import CarriedPoints, covering_centres
from systems.planning.stomp import Stomp
from systems.planning.straight_motions import MAX_STRAIGHT_STEP, PlanningError
from systems.planning.world import PlanningWorld

HELD_SEGMENT_S = 0.25  # s: a held object is moved gently (the grip is friction only)
# A held object's grasp frames move at most this fast (m/s) and turn at most this fast (rad/s) between keyframes:
# faster, the grip (friction only) lets it swing about its handle grasp.
HELD_SPEED_M_S = 0.1
HELD_TURN_SPEED_RAD_S = 0.3
# The held move's configurations: the left hand within this of its moved pose (m; rad below), the right one
# held at its start pose relative to the left by solve_held's closure tolerances.
HELD_GOAL_POSITION_TOLERANCE = 0.001
# (At most 0.04 rad: a set-down object must stand within 5 degrees of upright.)
HELD_GOAL_ANGLE_TOLERANCES = (0.01, 0.04)
# A tool's precise move (an aim) has its goal solved again onto its hands' targets within this (m, rad; the right
# hand's pose relative to the left within it too): with the tolerances above and a pull towards the configuration
# before, the goal sits at their edge, behind the motion (an aimed bit's tip stopped some 2 mm short of its goal).
HELD_GOAL_EXACT_TOLERANCES = (0.0001, 0.001)
# m: a held move's goal that collides is solved again this far from the robot itself and the table (Drake's geometry)
HELD_GOAL_MIN_DISTANCE = 0.01
HELD_PATH_STEPS = 10  # configurations solved along a held move's motion
PROJECTION_STEPS = 15
# A carried object as spheres of this radius (m) for the collision cost, centred on its points so that every
# point lies in one (farthest point sampling), at most this many.
CARRIED_RADIUS = 0.015
CARRIED_MOST_SPHERES = 600
# The played trajectory's closure is checked at this period, s.
DENSE_CHECK_S = 0.01
# The mass STOMP's torque term assumes for a held object, kg: the heaviest of the familiar categories (the generated
# drills weigh 1.4-2.0 kg), not the object's own mass, which nothing perceives.
HELD_MASS_KG = 2.0


@dataclass
class HeldMove:
    """A held move's keyframes and what the constraints are measured against."""

    keyframes: np.ndarray  # K x n
    X_E1E2: np.ndarray  # 4 x 4: the right grasp frame in the left one's, as at the start


@dataclass
class HeldPath:
    """Configurations holding the object along a held move's motion: STOMP's first trajectory and its goal."""

    configurations: np.ndarray  # K x n, from q_start
    reached: float  # the share of the motion the last one reaches, in (0, 1]
    angle_tolerance: float  # rad: the largest of the hands' angle tolerances used along it


class HeldMotions:
    """Plans held moves in a PlanningWorld.

    Attributes:
        closure, orientation: the constraints a held move keeps (the orientation where the motion allows it).
        held_mass_kg: what STOMP's torque term assumes a held object weighs.
    """

    def __init__(self, world: PlanningWorld, ik: DualArmIk, stomp: Stomp, held_mass_kg: float = HELD_MASS_KG):
        self.world, self.ik, self.stomp, self.held_mass_kg = world, ik, stomp, held_mass_kg
        self.closure = ClosureConstraint()
        self.orientation = OrientationConstraint()

    def held_move(
        self,
        q_start: np.ndarray,
        X_motion_W: RigidTransform,
        min_fraction: float = 1.0,
        carried_points_W: np.ndarray | None = None,
        scene_W: np.ndarray | None = None,
        exact_goal: bool = False,
    ) -> HeldMove:
        """Keyframes moving both hands (and the object they hold) by X_motion_W (X_WG -> X_motion_W X_WG),
        keeping the hands' relative pose (closure constraint) and, where the goal allows it, their world
        orientations (orientation constraint: the object does not tilt).

        Where the arms cannot reach the whole motion, a share of it down to min_fraction will do (a lift near
        the edge of the arms' reach); where they cannot reach it with the hands' orientation kept within
        0.01 rad, the hands may tilt together (the closure still holds) by up to 0.04 rad. With
        carried_points_W (the held object's points in W at q_start), the object is kept clear of the scene
        too (a carry over a box); without, only the robot is. scene_W: the scene as the camera saw it (occupied
        points, N x 3 in W), kept clear of too. exact_goal: the goal solved onto the hands' targets
        (held_path's exact_goal), for a tool's precise move.

        Raises:
            PlanningError: the moved hands are out of reach, or STOMP found no constrained path.
        """
        stomp, end_effectors = self.stomp, self.world.end_effectors
        q_start = np.asarray(q_start, float)
        first = self.held_path(q_start, X_motion_W, min_fraction, exact_goal)
        path = first.configurations
        X_E1E2 = end_effectors.relative(q_start[None])[0]
        R_WE = [X[0, :3, :3] for X in end_effectors.poses(q_start[None])]
        # Project onto the closure manifold alone: the goal keeps its own orientation (a carry may turn the
        # object; a lift at the edge of reach may tilt it).
        q_goal = stomp.project(path[-1], X_E1E2, None, steps=PROJECTION_STEPS)[0]
        scene = self.world.table_obstacles(self.world.where_the_robot_is_not(scene_W, q_start))
        centre_W = None
        if carried_points_W is not None and len(carried_points_W):
            scene = scene.carrying(self.carried(q_start, carried_points_W))
            centre_W = np.mean(carried_points_W, axis=0)
        if not self._stomp_accepts(q_start, q_goal, scene):
            q_goal = self._clear_goal(q_start, q_goal, X_E1E2, scene)
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
        path[-1] = q_goal
        payload = self.payload(q_start, centre_W)
        result = stomp.plan(q_start, q_goal, scene, self.closure, orientation, initial_path=path, payload=payload)
        if not result.success:
            raise PlanningError(f"STOMP: {result.message}")
        kept = "off" if orientation is None else "upright" if orientation.upright_only else "on"
        logging.info(
            "held move: %.0f %% of the motion, hands within %.2f rad (orientation constraint %s); STOMP %d iterations, "
            "%.2f s", 100 * first.reached, first.angle_tolerance, kept, result.iterations, result.seconds
        )  # fmt: skip
        return HeldMove(result.trajectory, X_E1E2)

    def _stomp_accepts(self, q_start: np.ndarray, q_goal: np.ndarray, scene) -> bool:
        """Whether STOMP takes q_goal as a held move's goal from q_start: its sphere model (the held object's among
        them) more than a plan's required clearance from itself and `scene`, as judged from the plan's ends
        (Stomp.standing_at_ends: a goal Drake's exact geometry finds free may keep the coarse spheres' overlaps)."""
        obstacles = self.stomp.standing_at_ends(q_start, q_goal, scene)
        required = self.stomp.config.costs.required_clearance
        return bool(self.stomp.clearance(q_goal[None], obstacles, held=True)[0] > required)

    def _clear_goal(self, q_start: np.ndarray, q_goal: np.ndarray, X_E1E2: np.ndarray, scene) -> np.ndarray:
        """A held move's goal STOMP takes (_stomp_accepts), the hands where they are at q_goal (within the held
        path's tolerances; X_E1E2: 4 x 4): solved from q_goal with Drake's geometry HELD_GOAL_MIN_DISTANCE apart.
        The path's goal, solved along the motion from the start, stays on the arms' branch; where that branch ends
        with an elbow in the pelvis (a carry to the robot's right side), another one may hold the object there.
        q_goal itself where none is taken."""
        X_WG_left = self.world.grasp_frame_poses(q_goal)["left"]
        for tolerance in HELD_GOAL_ANGLE_TOLERANCES:
            result = self.ik.solve_held(
                X_WG_left, RigidTransform(X_E1E2), q_goal, HELD_GOAL_POSITION_TOLERANCE, tolerance,
                min_distance=HELD_GOAL_MIN_DISTANCE,
            )  # fmt: skip
            if result.success and self._stomp_accepts(q_start, result.q, scene):
                logging.info("held move: its goal collides; another holding the object there is clear")
                return result.q
        return q_goal

    def held_path(
        self, q_start: np.ndarray, X_motion_W: RigidTransform, min_fraction: float, exact_goal: bool = False
    ) -> HeldPath:
        """Configurations holding the object along the motion (HELD_PATH_STEPS of it, each solved from the one
        before, so the arms stay on their branch), the share of the motion reached and the hands' angle
        tolerance used. With exact_goal, the last is solved again onto its targets (HELD_GOAL_EXACT_TOLERANCES)
        where it can be.

        Raises:
            PlanningError: not even min_fraction of the motion is reachable.
        """
        start_poses = self.world.grasp_frame_poses(q_start)
        X_E1E2 = start_poses["left"].InvertAndCompose(start_poses["right"])
        angle_axis = X_motion_W.rotation().ToAngleAxis()
        # The motion's share s turns the object about the hands' midpoint c by the share s of the rotation and moves
        # c the share s of the way to where the motion takes it: the hands go straight while the object turns
        # (turned about W's origin instead, a 90 degree turn swings them some 20 cm out of the way midway).
        centre = np.mean([X.translation() for X in start_poses.values()], axis=0)
        moved_centre = X_motion_W.multiply(centre)
        path, q, worst = [np.asarray(q_start, float)], q_start, 0.0
        for step in range(1, HELD_PATH_STEPS + 1):
            s = step / HELD_PATH_STEPS
            turn = RotationMatrix(AngleAxis(s * angle_axis.angle(), angle_axis.axis()))
            partial = RigidTransform(turn, centre + s * (moved_centre - centre)) @ RigidTransform(-centre)
            targets = {side: partial @ X for side, X in start_poses.items()}
            result, tolerance = self._held_configuration(targets, X_E1E2, q)
            if not result.success:
                break
            path.append(result.q)
            q, worst, last_targets = result.q, max(worst, tolerance), targets
        reached = (len(path) - 1) / HELD_PATH_STEPS
        if reached < min_fraction - 1e-9 or len(path) == 1:
            raise PlanningError(f"the moved hands are out of reach ({reached:.0%} of the motion at most)")
        if exact_goal:
            path[-1] = self._on_target(last_targets, X_E1E2, path[-1])
        return HeldPath(np.stack(path), reached, worst)

    def _on_target(self, targets, X_E1E2, q: np.ndarray) -> np.ndarray:
        """q (a held configuration within the path's tolerances of `targets`) solved again onto them, within
        HELD_GOAL_EXACT_TOLERANCES, the right hand as exactly at X_E1E2 from the left; q itself where that finds
        none near it (within MAX_STRAIGHT_STEP: a joint limit in the way, say)."""
        position, angle = HELD_GOAL_EXACT_TOLERANCES
        result = self.ik.solve_held(targets["left"], X_E1E2, q, position, angle, closure_tolerances=(position, angle))
        if result.success and np.abs(result.q - q).max() <= MAX_STRAIGHT_STEP:
            return result.q
        logging.info("held move: no configuration near its goal holds the hands on their targets; the goal kept")
        return q

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
        """The held object for the torque term: held_mass_kg at centre_W (m, in W at q; default midway
        between the hands), half of it in each hand."""
        world = self.world
        body = world.kinematics.body_poses(np.asarray(q)[None])[0]
        if centre_W is None:
            centre_W = np.mean([X[:3, 3] for X in world.end_effectors.from_body_poses(body)], axis=0)
        slots = np.array(world.end_effectors.positions)
        points_B = np.array([(centre_W - body[slot][:3, 3]) @ body[slot][:3, :3] for slot in slots])
        return Payload(slots, points_B, np.full(2, 0.5 * self.held_mass_kg))

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

    def onto_closure(self, keyframes: np.ndarray, held: HeldMove, midpoints: bool = False) -> np.ndarray:
        """A held move's keyframes (K x n) brought onto the closure manifold for playing: every interior one projected
        (PROJECTION_STEPS steps; the ends stay), and with `midpoints` one more midway in each segment first. STOMP's
        threshold cost leaves its keyframes anywhere within t_max, o_max of the manifold, and the cubic played between
        two may then leave it (long carries did, by 0.4-4.5 mm past t_max)."""
        keyframes = np.asarray(keyframes, float)
        if midpoints:
            middle = 0.5 * (keyframes[:-1] + keyframes[1:])
            keyframes = np.insert(keyframes, np.arange(1, len(keyframes)), middle, axis=0)
        projected = keyframes.copy()
        projected[1:-1] = self.stomp.project(keyframes[1:-1], held.X_E1E2, None, steps=PROJECTION_STEPS)
        return projected

    def closure_deviations(self, trajectory: PiecewisePolynomial, held: HeldMove) -> tuple[float, float]:
        """Largest (translation m, orientation rad) deviation of the hands' relative pose from the held
        one along the played trajectory, checked every DENSE_CHECK_S."""
        times = np.arange(trajectory.start_time(), trajectory.end_time() + 1e-9, DENSE_CHECK_S)
        q = np.array([trajectory.value(t).ravel() for t in times])
        t_dev, o_dev = deviations(self.world.end_effectors, q, held.X_E1E2)
        return float(t_dev.max()), float(o_dev.max())
