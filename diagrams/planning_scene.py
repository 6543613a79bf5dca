"""Builds the scene that planning works in: the robot, its hands and the table (optionally an object
welded where it stands), from the same files and placements as the station, and the planning world,
IK and pick motions in it."""

import hashlib
from collections.abc import Sequence

import numpy as np
import trimesh
from pydrake.geometry import Box, CollisionFilterDeclaration, GeometrySet
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, CoulombFriction
from pydrake.systems.framework import DiagramBuilder

from diagrams.generation.centauro_description import TORSO_JOINT, sdf_name
from diagrams.generation.objects.library import ObjectModel, resolve_object
from diagrams.paths import SDF_DIR
from diagrams.scenario import Scenario, initial_positions, planned_joints, torso_free
from diagrams.station import AddBoxObstacle, AddCentauro, AddTable, make_parser, object_pose_on_table
from systems.messages import OPEN_WIDTH
from systems.planning.pick_motions import PickMotions, PlannerConfig
from systems.planning.world import SIDES, PlanningWorld, RobotScene

OBJECT_SURFACE_POINTS = 6000


def MakeRobotScene(
    scenario: Scenario,
    open_width: float = OPEN_WIDTH,
    obstacle: ObjectModel | None = None,
    X_WO: RigidTransform | None = None,
    held_object: ObjectModel | None = None,
    X_GO: RigidTransform | None = None,
    boxes: Sequence[tuple[RigidTransform, Sequence[float]]] = (),
    known_box: bool = True,
) -> RobotScene:
    """The planning model of the scenario's robot and table (and the scenario's box on it, where known_box).

    Args:
        open_width: hand opening (m) of the collision model.
        obstacle, X_WO: an object welded at X_WO in the world, as one more obstacle.
        held_object, X_GO: an object held in the left hand, welded to its grasp frame G at X_GO; it moves with the
            hand and does not collide with either hand or the arm link it is welded to (they hold it).
        boxes: more boxes welded in the world, each (X_WB of its centre, size along x, y, z in m), e.g. the
            obstacles of a planning benchmark's problem.
        known_box: the scenario's box (scenario.obstacle) is in the model; False: the planner learns of it only as
            the camera sees it (the scene cloud), as of everything else on the table.
    """
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
    robot, hands = AddCentauro(plant, scene_graph, scenario)
    AddTable(plant, scenario)
    if known_box:
        AddBoxObstacle(plant, scenario)
    for i, (X_WB, size) in enumerate(boxes):
        plant.RegisterCollisionGeometry(plant.world_body(), X_WB, Box(*size), f"box_{i}", CoulombFriction())
    surface, spacing, objects = None, 0.0, []
    if obstacle is not None:
        (instance,) = make_parser(plant).AddModels(file_name=str(obstacle.model_file))
        objects.append(instance)
        body = plant.get_body(plant.GetBodyIndices(instance)[0])
        plant.WeldFrames(plant.world_frame(), body.body_frame(), X_WO)
        surface, spacing = object_surface_W(obstacle, X_WO, OBJECT_SURFACE_POINTS)
    if held_object is not None:
        (instance,) = make_parser(plant).AddModels(file_name=str(held_object.model_file))
        objects.append(instance)
        held = plant.get_body(plant.GetBodyIndices(instance)[0])
        plant.WeldFrames(plant.GetFrameByName("grasp_frame", hands["left"]), held.body_frame(), X_GO)
    plant.Finalize()
    if held_object is not None:
        # The hands and what is welded to them (each arm's last link): their distances to the held object stay as
        # the grasp made them.
        bodies = {body for hand in hands.values() for body in plant.GetBodyIndices(hand)}
        bodies |= {welded.index() for body in list(bodies) for welded in plant.GetBodiesWeldedTo(plant.get_body(body))}
        bodies.discard(held.index())
        hand_geometries = [
            geometry for body in bodies for geometry in plant.GetCollisionGeometriesForBody(plant.get_body(body))
        ]
        scene_graph.collision_filter_manager().Apply(
            CollisionFilterDeclaration().ExcludeBetween(
                GeometrySet(plant.GetCollisionGeometriesForBody(held)), GeometrySet(hand_geometries)
            )
        )
    for hand in hands.values():
        for name in ("finger_1_joint", "finger_2_joint"):
            plant.GetJointByName(name, hand).set_default_translation(open_width / 2)
    diagram = builder.Build()
    return RobotScene(
        diagram,
        plant,
        scene_graph,
        robot,
        hands,
        planned_joints(scenario),
        _cache_key(scenario, open_width, obstacle, X_WO, boxes, known_box),
        0,  # the IK seed table is a property of the model, not of a run: one seed for all
        surface,
        spacing,
        TORSO_JOINT if torso_free(scenario) else None,
        tuple(objects),
    )


def clutter_surfaces_W(scenario: Scenario, spacing: float = 0.01) -> np.ndarray:
    """Ground truth: points about `spacing` apart (m) on the surfaces of the scenario's other objects where they
    stand (N x 3 in W), for the ground-truth pick and tests."""
    from diagrams.generation.objects.bowl import bowl_mesh
    from diagrams.pour_container import table_clutter
    from diagrams.station import clutter_object_config, clutter_pose_on_table

    points = [np.zeros((0, 3))]
    for other in table_clutter(scenario):
        if other.instance:
            model_file = resolve_object(clutter_object_config(other)).model_file
            mesh = trimesh.load(model_file.parent / "visual.obj", force="mesh")
        elif other.kind == "box":
            mesh = trimesh.creation.box(other.size)
            mesh.apply_translation([0, 0, other.size[2] / 2])
        elif other.kind == "cylinder":
            mesh = trimesh.creation.cylinder(other.size[0] / 2, other.size[2])
            mesh.apply_translation([0, 0, other.size[2] / 2])
        else:
            mesh = bowl_mesh(other.size[0], other.size[2], pot=other.kind == "pot")
        surface, _ = trimesh.sample.sample_surface_even(mesh, int(np.ceil(mesh.area / spacing**2)), seed=0)
        points.append(clutter_pose_on_table(scenario, other).multiply(surface.T).T)
    return np.vstack(points)


def object_surface_W(model: ObjectModel, X_WO: RigidTransform, count: int) -> tuple[np.ndarray, float]:
    """Ground truth: an even sample of about `count` points of the object's surface where it stands at X_WO
    (N x 3 in W), and their spacing (m)."""
    mesh = trimesh.load(model.model_file.parent / "visual.obj", force="mesh")
    points, _ = trimesh.sample.sample_surface_even(mesh, count, seed=0)
    return X_WO.multiply(points.T).T, float(np.sqrt(mesh.area / len(points)))


def object_collision_surface_W(model: ObjectModel, X_WO: RigidTransform, count: int) -> np.ndarray:
    """Ground truth: an even sample of about `count` points of the surfaces of the object's convex collision
    pieces (what the simulator and the exact checks collide; they reach up to about 4 cm past the visual mesh,
    where a piece's hull spans a bend), where it stands at X_WO (N x 3 in W).

    Raises:
        FileNotFoundError: the model has no collision_*.obj pieces beside its file.
    """
    files = sorted(model.model_file.parent.glob("collision_*.obj"))
    if not files:
        raise FileNotFoundError(f"no collision_*.obj pieces beside {model.model_file}")
    mesh = trimesh.util.concatenate([trimesh.load(file, force="mesh") for file in files])
    points, _ = trimesh.sample.sample_surface_even(mesh, count, seed=0)
    return X_WO.multiply(points.T).T


def make_planning_world(scenario: Scenario, **scene_options) -> PlanningWorld:
    """The PlanningWorld of MakeRobotScene(scenario, **scene_options)."""
    return PlanningWorld(MakeRobotScene(scenario, **scene_options))


def make_pick_motions(scenario: Scenario, config: PlannerConfig | None = None, **scene_options) -> PickMotions:
    """The pick's planning core (world, IK, STOMP) in make_planning_world(scenario, **scene_options), built with
    `config` (default PlannerConfig())."""
    return PickMotions(make_planning_world(scenario, **scene_options), config)


def _cache_key(scenario, open_width, obstacle, X_WO, boxes=(), known_box=True) -> str:
    """A hash of everything the IK seed table depends on: the model files, placements and object."""
    digest = hashlib.sha256()
    robot = f"centauro/{sdf_name(torso_free(scenario))}"
    for path in (robot, "centauro/hand.sdf", "scene/table.sdf", "scene/floor.sdf"):
        digest.update((SDF_DIR / path).read_bytes())
    box = scenario.obstacle
    placement = (scenario.pelvis_height, list(scenario.table_xyz), open_width)
    digest.update(repr(placement + ((list(box.xy), list(box.size)) if box.present and known_box else ())).encode())
    if obstacle is not None:
        for piece in sorted(obstacle.model_file.parent.glob("*")):
            if piece.suffix in (".sdf", ".obj", ".urdf"):
                digest.update(piece.read_bytes())
        digest.update(np.round(X_WO.GetAsMatrix4(), 9).tobytes())
    for X_WB, size in boxes:
        digest.update(np.round(np.append(X_WB.GetAsMatrix4().ravel(), size), 9).tobytes())
    return digest.hexdigest()[:24]


def true_grasp_poses(scenario: Scenario) -> dict[str, RigidTransform]:
    """Ground truth: X_WG of each control pose (left/right pregrasp/grasp) of the scenario's object where
    the station places it. For the ground-truth pick, tests and benchmarks only.

    Raises:
        ValueError: the object's model has no grasp frames.
    """
    model = resolve_object(scenario.object)
    if model.info is None:
        raise ValueError(f"{model.model_file} has no grasp frames (info.yaml beside it): ground truth needs them")
    X_WO = object_pose_on_table(scenario, model)
    return {name: X_WO @ X_OG for name, X_OG in model.info.control_poses().items()}


def grasp_configuration(scenario: Scenario, motions: PickMotions) -> np.ndarray:
    """Ground truth: the planned joints holding the scenario's object at its true grasps, reached as the
    pick reaches them (pre-grasp, then straight in) with `motions` (e.g. make_pick_motions(scenario, obstacle=...,
    X_WO=...): the object welded where it stands). For tests and benchmarks.

    Raises:
        PlanningError: no such configuration.
    """
    poses = true_grasp_poses(scenario)
    q = initial_positions(scenario)
    pregrasp = motions.reach(q, {side: poses[f"{side}_pregrasp"] for side in SIDES}).keyframes[-1]
    return motions.straight(pregrasp, {side: poses[f"{side}_grasp"] for side in SIDES})[-1]
