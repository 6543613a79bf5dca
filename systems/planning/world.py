"""The world that planning works in: the robot and the fixed scene, read once from a RobotScene.

The scene (RobotScene) is a built Diagram holding a MultibodyPlant of the robot, its hands and the table, and
optionally an object welded where it stands; diagrams/planning_scene.py builds it from the same files as the
station. A PlanningWorld holds what the IK (systems/planning/ik.py) and STOMP (systems/planning/stomp.py) are
built from: the arms' batched kinematics, their sphere model and grasp frames, the joints' position, velocity
and effort limits, the fixed scene's boxes (table, floor, a box on the table) and a welded object's surface,
and Drake's plant for exact checks. None of it changes after construction. Obstacles that change from plan to
plan (a perceived object) are arguments (planning_obstacles(points_W)), never kept.

Drake's queries (in_collision, clearance, grasp_frame_poses, and the IK's solves) write the arm positions into
the world's one plant context before they read it: scratch, not state. The numpy models (kinematics, boxes) are
read from it once, at construction, with every joint at its default.
"""

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import BodyIndex, ModelInstanceIndex
from pydrake.systems.framework import Diagram

from systems.messages import SIDES
from systems.planning.kinematics import BatchedKinematics, EndEffectors
from systems.planning.obstacles import Obstacles
from systems.planning.sphere_model import SphereGroup, off_the_robot, robot_spheres

# Clearance added around a perceived (reconstructed) object for reach planning, m: a reconstruction is a few
# millimetres off, and a wider margin left reaches without a path to the pre-grasp in STOMP's time.
PERCEIVED_SHAPE_MARGIN = 0.01
# Clearance added around the scene as the camera saw it (measured points and hidden cubes' centres:
# systems/perception/scene_cloud.py), m: an edge seen up to a pixel short (2-3 mm at a metre) and the distance
# field's interpolation between its nodes (up to about 2 mm at a sphere's radius from an edge). Depth noise
# makes the nearest points nearer, not farther.
PERCEIVED_SCENE_MARGIN = 0.005
# The scene's distance field's grid, m (systems/planning/obstacles.py: DistanceField; scene_cloud.SCENE_VOXEL_M, the
# hidden cubes' side).
SCENE_CELL_M = 0.01
# m: a path from where the robot stands in contact with itself (a straight approach ended with a forearm 5.6 mm into
# the torso) may take each such pair this much deeper, no more, as it leaves (float noise of the penetration query).
TOLERATED_DEEPENING_M = 0.001
# rad: a configuration may lie this far beyond a joint limit and still count as within it (IK's answers at a limit).
LIMIT_TOLERANCE_RAD = 1e-9


@dataclass
class RobotScene:
    """The model planning works in (built by diagrams/planning_scene.py)."""

    diagram: Diagram  # holds `plant` and `scene_graph`; the hands' fingers at their planning opening
    plant: MultibodyPlant
    scene_graph: SceneGraph
    robot: ModelInstanceIndex
    hands: dict[str, ModelInstanceIndex]  # "left", "right"
    arm_joints: list[str]  # the planned joints: the left arm's 7, the right arm's 7, then the torso yaw if planned
    # Identifies the model files, placements and seed: the IK seed table is cached under it.
    cache_key: str
    seed: int = 0
    # A welded object's surface points in W (N x 3) and their spacing (m), or None: also an obstacle
    # for the sphere model, since the plant's exact geometry only serves Drake's queries.
    object_surface_W: np.ndarray | None = None
    object_surface_spacing: float = 0.0
    torso_joint: str | None = None  # the torso yaw's name when it is planned (the last of arm_joints)
    objects: tuple[ModelInstanceIndex, ...] = ()  # the welded (or held) objects' model instances


class PlanningWorld:
    """The robot and the fixed scene of a RobotScene, for the IK, STOMP and the collision checks.

    Attributes:
        scene: the RobotScene it was read from.
        plant, plant_context: Drake's model for exact checks and the IK (the context is the queries' scratch).
        q_default: the plant's default positions (the fingers at their planning opening).
        arm_indices: the planned joints' indices in the plant's positions (n: 14 arm joints, 15 with the torso).
        lower, upper, velocity_limits, effort_limits: the planned joints' limits (rad, rad/s, N m).
        torso: the torso yaw's position in a configuration (14), or None when the torso is locked.
        torso_axis_W: where the torso's vertical axis meets the floor plane (x, y in W, m).
        grasp_frames: each hand's grasp frame G, by side.
        kinematics, spheres, end_effectors: the arms' batched kinematics, sphere model and grasp frames (numpy).
        inspector: the SceneGraph's model inspector (its collision filters say which sphere pairs count).
        table_boxes: the fixed scene's boxes for the sphere model, as Obstacles.boxes holds them.
    """

    def __init__(self, scene: RobotScene):
        self.scene = scene
        self.plant, self.scene_graph, self.diagram = scene.plant, scene.scene_graph, scene.diagram
        self.context = self.diagram.CreateDefaultContext()
        self.plant_context = self.plant.GetMyMutableContextFromRoot(self.context)
        self.q_default = self.plant.GetPositions(self.plant_context)
        self.grasp_frames = {side: self.plant.GetFrameByName("grasp_frame", scene.hands[side]) for side in SIDES}
        joints = [self.plant.GetJointByName(n, scene.robot) for n in scene.arm_joints]
        self.arm_indices = np.array([j.position_start() for j in joints])
        self.torso = scene.arm_joints.index(scene.torso_joint) if scene.torso_joint else None
        torso_body = self.plant.GetBodyByName("torso", scene.robot)
        self.torso_axis_W = self.plant.EvalBodyPoseInWorld(self.plant_context, torso_body).translation()[:2]
        self.lower = np.array([j.position_lower_limits()[0] for j in joints])
        self.upper = np.array([j.position_upper_limits()[0] for j in joints])
        self.velocity_limits = np.array([j.velocity_upper_limits()[0] for j in joints])
        actuators = [self.plant.get_joint_actuator(i) for i in self.plant.GetJointActuatorIndices()]
        effort = {actuator.joint().index(): actuator.effort_limit() for actuator in actuators}
        self.effort_limits = np.array([effort[j.index()] for j in joints])
        # Read with the context at q_default: the kinematics keeps the fixed joints (fingers, welds) as they are here.
        self.kinematics, self.spheres = centauro_kinematics(
            self.plant, self.scene_graph, self.plant_context, scene.arm_joints, scene.hands
        )
        self.end_effectors = EndEffectors(self.kinematics, [self.grasp_frames[side] for side in SIDES])
        self.inspector = self.scene_graph.model_inspector()
        self.table_boxes = tuple(self._fixed_boxes().boxes)
        self.object_geometries = set().union(*(self._geometries(instance) for instance in scene.objects))
        self.hand_geometries = {side: self._geometries(scene.hands[side]) for side in SIDES}

    def _geometries(self, instance: ModelInstanceIndex) -> set[int]:
        """The collision geometries' ids (values) of a model instance's bodies."""
        return {
            geometry.get_value()
            for body in self.plant.GetBodyIndices(instance)
            for geometry in self.plant.GetCollisionGeometriesForBody(self.plant.get_body(body))
        }

    def _grasp_contact(self, pair: tuple[int, int]) -> bool:
        """Whether a geometry pair is one a grasp makes: a hand with a welded object, or the two hands (on an
        object whose handles stand close, their fingers meet at the grasps)."""
        left, right = self.hand_geometries["left"], self.hand_geometries["right"]
        a, b = pair
        return bool(set(pair) & self.object_geometries) or (a in left and b in right) or (a in right and b in left)

    def _fixed_boxes(self) -> Obstacles:
        """Every box that is not the robot's (table, floor, a box on the table), welded in the world."""
        obstacles = Obstacles()
        robot = {self.scene.robot, *self.scene.hands.values()}
        for index in range(self.plant.num_bodies()):
            body = self.plant.get_body(BodyIndex(index))
            if body.model_instance() in robot:
                continue
            X_WB = self.plant.EvalBodyPoseInWorld(self.plant_context, body)
            for geometry in self.plant.GetCollisionGeometriesForBody(body):
                shape = self.inspector.GetShape(geometry)
                if isinstance(shape, Box):
                    X_WG = (X_WB @ self.inspector.GetPoseInFrame(geometry)).GetAsMatrix4()
                    obstacles.add_box(X_WG, [shape.width(), shape.depth(), shape.height()])
        return obstacles

    def table_obstacles(self, scene_W: np.ndarray | None = None) -> Obstacles:
        """The fixed scene's boxes for the sphere model, and the scene as seen (scene_W: its occupied points, N x 3 in
        W, or None). A new Obstacles each call: add to it freely."""
        obstacles = Obstacles()
        obstacles.boxes = list(self.table_boxes)
        if scene_W is not None and len(scene_W):
            obstacles.add_scene(scene_W, SCENE_CELL_M, inflation=PERCEIVED_SCENE_MARGIN)
        return obstacles

    def planning_obstacles(self, points_W: np.ndarray | None = None, scene_W: np.ndarray | None = None) -> Obstacles:
        """The scene for a reach: the table's boxes, the object as seen (points_W, N x 3 in W, e.g. a perceived
        cloud: Drake's model has no geometry for it), the rest of the scene as seen (scene_W: centres of occupied
        SCENE_CELL_M cubes in W, N x 3) and a welded object's surface."""
        obstacles = self.table_obstacles(scene_W)
        if points_W is not None:
            # A perceived shape is off by up to a centimetre or two where the camera did not see it.
            obstacles.add_points(points_W, inflation=PERCEIVED_SHAPE_MARGIN)
        if self.scene.object_surface_W is not None:
            # Between surface samples the nearest sample is up to about half their spacing too far.
            obstacles.add_points(self.scene.object_surface_W, inflation=0.5 * self.scene.object_surface_spacing)
        return obstacles

    def where_the_robot_is_not(self, scene_W: np.ndarray | None, q: np.ndarray) -> np.ndarray | None:
        """The perceived scene (its occupied points, N x 3 in W) without the points within the robot's sphere model
        at q grown by the scene's margin and two grid cells: the robot stands there, so nothing else does. (A hand
        beside a neighbour of the object it holds starts clear, whatever the points and their margin say.)"""
        if scene_W is None or not len(scene_W):
            return scene_W
        centres = self.spheres.centres_W(self.kinematics.body_poses(np.asarray(q, float)[None]))[0]
        # The scene's margin, STOMP's required clearance and the field's interpolation.
        return off_the_robot(
            scene_W, np.column_stack([centres, self.spheres.radius]), PERCEIVED_SCENE_MARGIN + 2 * SCENE_CELL_M
        )

    def beyond_limits(self, q_arms: np.ndarray) -> float:
        """How far (rad) the planned joints of q_arms (... x n) lie beyond their limits at most; <= 0 within."""
        return float(np.max(np.maximum(self.lower - q_arms, q_arms - self.upper)))

    def full_positions(self, q_arms: np.ndarray) -> np.ndarray:
        """The plant's positions: q_default with the arm joints at q_arms."""
        q = self.q_default.copy()
        q[self.arm_indices] = q_arms
        return q

    def in_collision(
        self, q_arms: np.ndarray, tolerated: dict[tuple[int, int], float] | None = None, grasp_contacts: bool = True
    ) -> bool:
        """Whether the robot touches itself, the table or a welded object at arm configuration q_arms (Drake's
        exact geometry). tolerated: penetrations that do not count (as penetrations() gives them: where the robot
        stands), unless a pair goes deeper than there by more than TOLERATED_DEEPENING_M. grasp_contacts: False
        leaves out the contacts a grasp makes (_grasp_contact: hands going to their grasps are meant to touch)."""
        if tolerated or not grasp_contacts:
            tolerated = tolerated or {}
            return any(
                depth > tolerated.get(pair, -np.inf) + TOLERATED_DEEPENING_M
                for pair, depth in self.penetrations(q_arms, grasp_contacts).items()
            )
        self.plant.SetPositions(self.plant_context, self.full_positions(q_arms))
        return self.plant.get_geometry_query_input_port().Eval(self.plant_context).HasCollisions()

    def segment_is_free(
        self,
        q_from: np.ndarray,
        q_to: np.ndarray,
        max_step: float = 0.02,
        tolerated: dict | None = None,
        grasp_contacts: bool = True,
    ) -> bool:
        """Whether the straight joint-space segment q_from -> q_to is free by in_collision (`tolerated`,
        `grasp_contacts` as there), checked every max_step rad."""
        return not any(self.in_collision(q, tolerated, grasp_contacts) for q in joint_segment(q_from, q_to, max_step))

    def penetrations(self, q_arms: np.ndarray, grasp_contacts: bool = True) -> dict[tuple[int, int], float]:
        """The geometry pairs (their GeometryIds' values) that penetrate each other at q_arms, and how deep (m),
        by Drake's exact geometry; none where the robot is free. grasp_contacts: False leaves out the pairs a
        grasp makes (_grasp_contact)."""
        self.plant.SetPositions(self.plant_context, self.full_positions(q_arms))
        query = self.plant.get_geometry_query_input_port().Eval(self.plant_context)
        if not query.HasCollisions():
            return {}
        pairs = {
            tuple(sorted((pair.id_A.get_value(), pair.id_B.get_value()))): pair.depth
            for pair in query.ComputePointPairPenetration()
        }
        return {pair: depth for pair, depth in pairs.items() if grasp_contacts or not self._grasp_contact(pair)}

    def clearance(self, q_arms: np.ndarray, max_distance: float = 0.5) -> float:
        """Smallest signed distance (m) between robot, table and object geometries at q_arms (Drake's exact query)."""
        self.plant.SetPositions(self.plant_context, self.full_positions(q_arms))
        query = self.plant.get_geometry_query_input_port().Eval(self.plant_context)
        pairs = query.ComputeSignedDistancePairwiseClosestPoints(max_distance)
        return min((pair.distance for pair in pairs), default=max_distance)

    def grasp_frame_poses(self, q_arms: np.ndarray) -> dict[str, RigidTransform]:
        """X_WG of both hands at arm configuration q_arms."""
        self.plant.SetPositions(self.plant_context, self.full_positions(q_arms))
        return {side: frame.CalcPoseInWorld(self.plant_context) for side, frame in self.grasp_frames.items()}


def joint_segment(q_from: np.ndarray, q_to: np.ndarray, max_step: float) -> list[np.ndarray]:
    """The states of the straight joint-space segment q_from -> q_to, both ends included, no joint turning more
    than max_step (rad) between two."""
    q_from, q_to = np.asarray(q_from, float), np.asarray(q_to, float)
    steps = max(1, int(np.ceil(np.max(np.abs(q_to - q_from)) / max_step)))
    return [q_from + s * (q_to - q_from) for s in np.linspace(0, 1, steps + 1)]


def centauro_kinematics(plant: MultibodyPlant, scene_graph, plant_context, arm_joints: list[str], hands: dict):
    """Batched kinematics of both arms with the hands, and their sphere model.

    Args:
        arm_joints: the planned joints' names: the left arm (arm1_*), the right (arm2_*), and the torso yaw if
            it is planned.
        hands: {"left": model instance, "right": model instance} of the hands.

    Sphere groups (SphereGroup): the pelvis, torso and head; the left arm and hand; the right arm and hand.
    """
    joints = [plant.GetJointByName(name) for name in arm_joints]
    bodies = [joint.child_body() for joint in joints]
    for hand in hands.values():
        bodies += [plant.get_body(b) for b in plant.GetBodyIndices(hand)]
    bodies += [plant.GetBodyByName("torso"), plant.GetBodyByName("pelvis")]
    kinematics = BatchedKinematics(plant, plant_context, joints, bodies)

    def group(name, model_instance) -> SphereGroup:
        if model_instance == hands["left"] or name.startswith("arm1_"):
            return SphereGroup.LEFT
        if model_instance == hands["right"] or name.startswith("arm2_"):
            return SphereGroup.RIGHT
        return SphereGroup.TORSO

    return kinematics, robot_spheres(plant, scene_graph, kinematics, group)
