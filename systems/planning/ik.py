"""Dual-arm inverse kinematics for the hands' grasp frames (Drake InverseKinematics), and the
robot scene that planning works in.

The scene (RobotScene) is a built Diagram holding a MultibodyPlant of the robot, its hands and
the table, and optionally an object welded where it stands; diagrams/planning_scene.py builds it
from the same files as the station.
"""

import functools
import itertools
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box, SceneGraph
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import BodyIndex, ModelInstanceIndex
from pydrake.solvers import Solve
from pydrake.systems.framework import Diagram

from systems.paths import cache_dir, save_npz_atomically
from systems.planning.kinematics import EndEffectors, centauro_kinematics
from systems.planning.stomp import Obstacles, Stomp

SIDES = ("left", "right")
SEED_SAMPLES = 3000
# Clearance added around a perceived (reconstructed) object for reach planning, m. The reconstructions
# are 2.8-4.1 mm off (Chamfer, single views); 1.5 cm around the accurate drills left STOMP's reach without a
# path to the pre-grasp in its 2 s (unseen drills 17/24 picks; 1 cm: see the README's evaluation).
PERCEIVED_SHAPE_MARGIN = 0.01
# A hand is symmetric under a half turn about its approach axis z_G.
HALF_TURN = RigidTransform(RotationMatrix.MakeZRotation(np.pi))


@dataclass
class RobotScene:
    """The model planning works in (built by diagrams/planning_scene.py)."""

    diagram: Diagram  # holds `plant` and `scene_graph`; the hands' fingers at their planning opening
    plant: MultibodyPlant
    scene_graph: SceneGraph
    robot: ModelInstanceIndex
    hands: dict[str, ModelInstanceIndex]  # "left", "right"
    arm_joints: list[str]  # the 14 arm joints, left arm then right
    # Identifies the model files, placements and seed: the IK seed table is cached under it.
    cache_key: str
    seed: int = 0
    # A welded object's surface points in W (N x 3) and their spacing (m), or None: also an obstacle
    # for the sphere model, since the plant's exact geometry only serves Drake's queries.
    object_surface_W: np.ndarray | None = None
    object_surface_spacing: float = 0.0


@dataclass
class IkResult:
    success: bool
    q: np.ndarray  # 14 arm joint positions, rad (arm 1 then arm 2)
    message: str = ""


class DualArmIk:
    """Solves for the 14 arm joints that put both grasp frames at given world poses."""

    def __init__(self, scene: RobotScene, obstacle_points_W: np.ndarray | None = None):
        """Args:
        scene: the robot, table (and welded object) to plan in.
        obstacle_points_W: the object as seen (e.g. a reconstructed cloud, N x 3): checked with the
            sphere model (collision checks and STOMP), since Drake's model has no geometry for it.
        """
        self.scene = scene
        self.obstacle_points_W = obstacle_points_W
        self.plant, self.scene_graph, self.diagram = scene.plant, scene.scene_graph, scene.diagram
        self.context = self.diagram.CreateDefaultContext()
        self.plant_context = self.plant.GetMyMutableContextFromRoot(self.context)
        self.q_default = self.plant.GetPositions(self.plant_context)
        self.grasp_frames = {side: self.plant.GetFrameByName("grasp_frame", scene.hands[side]) for side in SIDES}
        joints = [self.plant.GetJointByName(n, scene.robot) for n in scene.arm_joints]
        self.arm_indices = np.array([j.position_start() for j in joints])
        self.lower = np.array([j.position_lower_limits()[0] for j in joints])
        self.upper = np.array([j.position_upper_limits()[0] for j in joints])
        self.velocity_limits = np.array([j.velocity_upper_limits()[0] for j in joints])
        actuators = [self.plant.get_joint_actuator(i) for i in self.plant.GetJointActuatorIndices()]
        effort = {actuator.joint().index(): actuator.effort_limit() for actuator in actuators}
        self.effort_limits = np.array([effort[j.index()] for j in joints])
        self._load_or_build_seed_table()

    def _load_or_build_seed_table(self):
        """The seed table from the cache when this scene (robot, table, object, seed) was seen before."""
        path = cache_dir() / "ik_seeds" / f"{self.scene.cache_key}_{SEED_SAMPLES}.npz"
        if path.is_file():
            with np.load(path) as data:
                self._seed_q = data["q"]
                self._seed_poses = {side: data[side] for side in SIDES}
            return
        self._build_seed_table(self.scene.seed, SEED_SAMPLES)
        save_npz_atomically(path, q=self._seed_q, **self._seed_poses)
        # Building left the last sample in the context: back to where a cached table leaves it, so that a
        # pick on a cold cache plans exactly as one on a warm cache (it lifted 1.3e-12 m lower).
        self.plant.SetPositions(self.plant_context, self.q_default)

    def _build_seed_table(self, seed: int, samples: int = SEED_SAMPLES):
        """Random collision-free arm configurations and the grasp frame poses they reach.

        They are IK starting points: SNOPT from a nearby, feasible start converges far more
        often than from the current configuration.
        """
        rng = np.random.default_rng(seed)
        candidates = rng.uniform(self.lower, self.upper, size=(3 * samples, len(self.lower)))
        free = [q for q in candidates if not self.in_collision(q)]
        self._seed_q = np.array(free[:samples])
        samples = len(self._seed_q)
        self._seed_poses = {side: np.empty((samples, 3, 4)) for side in SIDES}
        for i, q in enumerate(self._seed_q):
            for side, X in self.grasp_frame_poses(q).items():
                self._seed_poses[side][i] = X.GetAsMatrix34()

    def _seeds(self, targets: dict[str, RigidTransform], count: int) -> list[np.ndarray]:
        """Seed-table configurations whose hands lie nearest the targets, per arm."""
        best = {}
        for side, X in targets.items():
            poses = self._seed_poses[side]
            position_error = np.linalg.norm(poses[:, :, 3] - X.translation(), axis=1)
            # Approach axes must agree; the handle axis only up to sign (the hand is symmetric).
            R = X.rotation().matrix()
            approach_error = 1.0 - poses[:, :, 2] @ R[:, 2]
            handle_error = 1.0 - np.abs(poses[:, :, 0] @ R[:, 0])
            best[side] = np.argsort(position_error + 0.3 * approach_error + 0.1 * handle_error)[:count]
        seeds = []
        for left, right in zip(best["left"], best["right"], strict=True):
            q = self._seed_q[left].copy()
            q[7:] = self._seed_q[right][7:]
            seeds.append(q)
        return seeds

    def set_obstacle_points(self, points_W: np.ndarray | None):
        """The object as seen (N x 3 in W, or None) for the plans that follow: the robot model and
        its seed table are kept, only the obstacles change."""
        self.obstacle_points_W = points_W
        self.__dict__.pop("planning_obstacles", None)  # (a cached_property: rebuilt on next use)

    def full_positions(self, q_arms: np.ndarray) -> np.ndarray:
        q = self.q_default.copy()
        q[self.arm_indices] = q_arms
        return q

    def in_collision(self, q_arms: np.ndarray) -> bool:
        """Whether the robot touches itself or the table at arm configuration q_arms."""
        self.plant.SetPositions(self.plant_context, self.full_positions(q_arms))
        return self.plant.get_geometry_query_input_port().Eval(self.plant_context).HasCollisions()

    def clearance(self, q_arms: np.ndarray, max_distance: float = 0.5) -> float:
        """Smallest signed distance (m) between robot, table and object geometries at q_arms (Drake's exact query)."""
        self.plant.SetPositions(self.plant_context, self.full_positions(q_arms))
        query = self.plant.get_geometry_query_input_port().Eval(self.plant_context)
        pairs = query.ComputeSignedDistancePairwiseClosestPoints(max_distance)
        return min((pair.distance for pair in pairs), default=max_distance)

    @functools.cached_property
    def stomp(self) -> Stomp:
        """A STOMP planner over this model's robot (sphere model) and its limits."""
        kinematics, spheres = centauro_kinematics(
            self.plant, self.scene_graph, self.plant_context, self.scene.arm_joints, self.scene.hands
        )
        end_effectors = EndEffectors(kinematics, [self.grasp_frames[side] for side in SIDES])
        inspector = self.scene_graph.model_inspector()
        return Stomp(
            kinematics,
            spheres,
            inspector,
            self.lower,
            self.upper,
            end_effectors=end_effectors,
            velocity_limits=self.velocity_limits,
            effort_limits=self.effort_limits,
        )

    @functools.cached_property
    def table_obstacles(self) -> Obstacles:
        """The fixed scene for STOMP: every box that is not the robot's (table, floor)."""
        obstacles = Obstacles()
        inspector = self.scene_graph.model_inspector()
        robot = {self.scene.robot, *self.scene.hands.values()}
        for index in range(self.plant.num_bodies()):
            body = self.plant.get_body(BodyIndex(index))
            if body.model_instance() in robot:
                continue
            X_WB = self.plant.EvalBodyPoseInWorld(self.plant_context, body)
            for geometry in self.plant.GetCollisionGeometriesForBody(body):
                shape = inspector.GetShape(geometry)
                if isinstance(shape, Box):
                    X_WG = (X_WB @ inspector.GetPoseInFrame(geometry)).GetAsMatrix4()
                    obstacles.add_box(X_WG, [shape.width(), shape.depth(), shape.height()])
        return obstacles

    @functools.cached_property
    def planning_obstacles(self) -> Obstacles:
        """The scene for STOMP: the table's boxes, and the object's points (as seen, or a welded object's surface)."""
        obstacles = Obstacles()
        obstacles.boxes = list(self.table_obstacles.boxes)
        if self.obstacle_points_W is not None:
            # A perceived shape is off by up to a centimetre or two where the camera did not see it.
            obstacles.add_points(self.obstacle_points_W, inflation=PERCEIVED_SHAPE_MARGIN)
        if self.scene.object_surface_W is not None:
            # Between surface samples the nearest sample is up to about half their spacing too far.
            obstacles.add_points(self.scene.object_surface_W, inflation=0.5 * self.scene.object_surface_spacing)
        return obstacles

    def segment_is_free(self, q_from: np.ndarray, q_to: np.ndarray, max_step: float = 0.02) -> bool:
        """Whether the straight joint-space segment q_from -> q_to is collision-free (checked every max_step rad).

        Drake's exact geometry, and the sphere model against obstacle points if there are any.
        """
        steps = max(1, int(np.ceil(np.max(np.abs(np.asarray(q_to) - q_from)) / max_step)))
        states = [q_from + s * (q_to - q_from) for s in np.linspace(0, 1, steps + 1)]
        if self.obstacle_points_W is not None:
            clearance = self.stomp.clearance(np.array(states), self.planning_obstacles)
            if clearance.min() <= 0:
                return False
        return not any(self.in_collision(q) for q in states)

    def grasp_frame_poses(self, q_arms: np.ndarray) -> dict[str, RigidTransform]:
        """X_WG of both hands at arm configuration q_arms."""
        self.plant.SetPositions(self.plant_context, self.full_positions(q_arms))
        return {side: frame.CalcPoseInWorld(self.plant_context) for side, frame in self.grasp_frames.items()}

    def solve(
        self,
        X_WG: dict[str, RigidTransform],
        q_guess: np.ndarray,
        position_tolerance: float = 0.002,
        angle_tolerance: float = 0.03,
        min_distance: float | None = 0.005,
        allow_half_turn: bool = True,
        restarts: int = 4,
        limit_margin: float = 0.0,
    ) -> IkResult:
        """Arm joints putting each side's grasp frame at X_WG[side], nearest to q_guess.

        Args:
            X_WG: target pose per side ("left", "right") in the world.
            q_guess: 14 arm joints, the initial guess and the configuration to stay near.
            position_tolerance: metres. angle_tolerance: radians.
            min_distance: if not None, every robot/table geometry pair stays this far apart (m).
            allow_half_turn: also try each target turned by pi about z_G (the hands are symmetric).
            restarts: extra initial guesses from the seed table. With min_distance, all of them are
                solved (the collision stage needs alternatives); without, only when q_guess fails.
            limit_margin: keep every joint this far inside its limits (rad), e.g. to leave room for a
                motion that follows.
        """
        q_guess = np.asarray(q_guess, dtype=float)
        flips = (False, True) if allow_half_turn else (False,)
        seeds = self._seeds(X_WG, restarts) if restarts else []
        # The arms are kinematically independent: solve each alone (7 joints, many starts),
        # then both together with the collision constraint, from the per-arm answers.
        per_arm = {}
        for side in SIDES:
            per_arm[side] = []
            for start, flip in itertools.product([q_guess, *seeds], flips):
                if min_distance is None and per_arm[side] and start is not q_guess:
                    break  # solved from q_guess: the seeds would only add answers farther from it
                target = {side: X_WG[side] @ HALF_TURN if flip else X_WG[side]}
                result = self._solve_once(
                    target, start, q_guess, position_tolerance, angle_tolerance, None, limit_margin
                )
                if result.success:
                    per_arm[side].append((flip, result.q))
            if not per_arm[side]:
                return IkResult(False, q_guess, f"{side} hand: target out of reach")
            per_arm[side].sort(key=lambda item: np.sum((item[1] - q_guess) ** 2))
        for (left_flip, left_q), (right_flip, right_q) in itertools.islice(
            itertools.product(per_arm["left"][:4], per_arm["right"][:4]), 8
        ):
            start = np.concatenate([left_q[:7], right_q[7:]])
            targets = {
                "left": X_WG["left"] @ HALF_TURN if left_flip else X_WG["left"],
                "right": X_WG["right"] @ HALF_TURN if right_flip else X_WG["right"],
            }
            if min_distance is None:
                return IkResult(True, start, "solved per arm")
            result = self._solve_once(
                targets, start, start, position_tolerance, angle_tolerance, min_distance, limit_margin
            )
            if result.success:
                return result
        return IkResult(False, q_guess, "each hand reaches its target, but not without a collision")

    def solve_held(
        self,
        X_WG_left: RigidTransform,
        X_E1E2: RigidTransform,
        q_near: np.ndarray,
        position_tolerance: float,
        angle_tolerance: float,
        start: np.ndarray | None = None,
        closure_tolerances: tuple[float, float] = (0.0005, 0.005),
    ) -> IkResult:
        """Both arms holding one object: the left grasp frame at X_WG_left (within the tolerances, m and
        rad) and the right one at X_E1E2 from it (within closure_tolerances, m and rad), nearest to q_near,
        solved from `start` (default q_near)."""
        left, right = self.grasp_frames["left"], self.grasp_frames["right"]
        ik = InverseKinematics(self.plant, self.plant_context, with_joint_limits=True)
        q, prog = ik.q(), ik.prog()
        tol = np.full(3, position_tolerance)
        p = X_WG_left.translation()
        ik.AddPositionConstraint(left, [0, 0, 0], self.plant.world_frame(), p - tol, p + tol)
        ik.AddOrientationConstraint(
            left, RotationMatrix(), self.plant.world_frame(), X_WG_left.rotation(), angle_tolerance
        )
        closure = np.full(3, closure_tolerances[0])
        p_E1E2 = X_E1E2.translation()
        ik.AddPositionConstraint(right, [0, 0, 0], left, p_E1E2 - closure, p_E1E2 + closure)
        ik.AddOrientationConstraint(right, RotationMatrix(), left, X_E1E2.rotation(), closure_tolerances[1])
        initial = self.full_positions(q_near if start is None else start)
        fixed = np.setdiff1d(np.arange(self.plant.num_positions()), self.arm_indices)
        prog.AddBoundingBoxConstraint(initial[fixed], initial[fixed], q[fixed])
        prog.AddQuadraticErrorCost(np.eye(len(self.arm_indices)), q_near, q[self.arm_indices])
        prog.SetInitialGuess(q, initial)
        result = Solve(prog)
        if result.is_success():
            return IkResult(True, result.GetSolution(q)[self.arm_indices], "solved")
        return IkResult(False, q_near, f"both hands cannot hold the object there ({result.get_solution_result()})")

    def _solve_once(
        self, targets, start, q_nominal, position_tolerance, angle_tolerance, min_distance, limit_margin=0.0
    ) -> IkResult:
        """One SNOPT solve; the joints of an arm without a target stay at `start`."""
        ik = InverseKinematics(self.plant, self.plant_context, with_joint_limits=True)
        q = ik.q()
        prog = ik.prog()
        for side, X in targets.items():
            frame = self.grasp_frames[side]
            tol = np.full(3, position_tolerance)
            ik.AddPositionConstraint(
                frame, [0, 0, 0], self.plant.world_frame(), X.translation() - tol, X.translation() + tol
            )
            ik.AddOrientationConstraint(
                frame, RotationMatrix(), self.plant.world_frame(), X.rotation(), angle_tolerance
            )
        if min_distance is not None:
            ik.AddMinimumDistanceLowerBoundConstraint(min_distance)
        fixed_q = self.full_positions(start)
        free = np.concatenate(
            [self.arm_indices[:7] if "left" in targets else [], self.arm_indices[7:] if "right" in targets else []]
        )
        fixed = np.setdiff1d(np.arange(self.plant.num_positions()), free.astype(int))
        prog.AddBoundingBoxConstraint(fixed_q[fixed], fixed_q[fixed], q[fixed])
        if limit_margin > 0:
            prog.AddBoundingBoxConstraint(self.lower + limit_margin, self.upper - limit_margin, q[self.arm_indices])
        prog.AddQuadraticErrorCost(np.eye(len(self.arm_indices)), q_nominal, q[self.arm_indices])
        prog.SetInitialGuess(q, self.full_positions(start))
        result = Solve(prog)
        q_arms = result.GetSolution(q)[self.arm_indices]
        return IkResult(result.is_success(), q_arms, str(result.get_solution_result()))
