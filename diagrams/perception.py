"""Perception as one subsystem: camera latch -> segmenter -> pose estimator -> shape registrar, one result;
and the ground-truth source with the same output ports."""

import logging
from pathlib import Path

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource

from diagrams.aim_board import board_placement
from diagrams.generation.objects import catalog
from diagrams.generation.objects.library import resolve_object
from diagrams.planning_scene import clutter_surfaces_W, object_surface_W, true_grasp_poses
from diagrams.pour_container import true_opening
from diagrams.scenario import Scenario
from diagrams.station import TABLE_HEIGHT, drop_zone, object_pose_on_table
from systems import categories
from systems.messages import BoardSeen, ContainerSeen, GraspPoses, PerceptionResult
from systems.perception.board_finder import BoardFinder
from systems.perception.camera_latch import CameraLatch
from systems.perception.container_finder import ContainerFinder
from systems.perception.object_tracker import AIM_MIN_TILT_CHANGE_RAD, MIN_TILT_CHANGE_RAD, ObjectTracker
from systems.perception.part_segmenter import DEFAULT_PART_WEIGHTS, PartSegmenter
from systems.perception.perception_result import PerceptionResultCollector
from systems.perception.pose_estimator import CategoryPrior, PoseEstimator
from systems.perception.pose_noise import PoseYawOffset, draw_yaw_offset
from systems.perception.robot_spheres import RobotSpheres
from systems.perception.scene_cloud import SEEN_SPACING_M, SceneCloud
from systems.perception.scene_memory import SceneMemory
from systems.perception.segmenter import Segmenter
from systems.perception.shape_registrar import ShapeRegistrar

# The training instance whose shape is each category's pose template.
TEMPLATE_INSTANCE = "train_0"
# The ground-truth source's object surface: this many points (the planner thins to its own density).
TRUE_SURFACE_POINTS = 4000


def category_priors() -> dict[str, CategoryPrior]:
    """The pose estimator's prior of every known category: a template mesh and where O sits in the extent.

    A generated category's template is a training instance; a taught one's its canonical model.
    """
    priors = {}
    for category in categories.known_categories():
        if category in catalog.CATEGORIES:
            template = catalog.instance_directory(category, TEMPLATE_INSTANCE) / "visual.obj"
            box_centre = tuple(float(v) for v in catalog.mean_box_centre(category))
            priors[category] = CategoryPrior(template, box_centre)
            continue
        record = categories.load_record(category)
        template = categories.category_directory(category) / "template.obj"
        symmetric_about_yaw = record.presentation_yaw if record.half_turn_symmetric else None
        priors[category] = CategoryPrior(template, tuple(record.box_centre), symmetric_about_yaw)
    return priors


def depth_camera(scenario: Scenario):
    """(intrinsics, X_BC: the depth sensor in the camera body) of the scenario's depth camera."""
    _, depth_camera = scenario.camera.MakeCameras()
    core = depth_camera.core()
    return core.intrinsics(), core.sensor_pose_in_camera_body()


def latch_offset(scenario: Scenario, look: bool = False) -> float:
    """When perception's camera latch reads its trigger within each period, s: half a plant step (a quarter for
    the look latch), where neither the plant nor the other's latch updates (see CameraLatch). A continuous plant
    has no steps: then 5 and 2.5 ms, between the other systems' updates (every 10 ms from 0)."""
    step = scenario.plant_config.time_step or 0.01
    return (0.25 if look else 0.5) * step


def MakeSegmenter(
    scenario: Scenario, weights: Path | None = None, category: str | None = None, first_near_W=None
) -> Segmenter:
    """A Segmenter with the scenario's depth camera and table top, told the scenario's requested category (or
    `category`); weights None: the one that knows every taught category (categories.active_segmenter). The clear
    task's chooses the object nearest first_near_W (x, y in W, m: the drop zone's centre) of every category."""
    intrinsics, X_BC = depth_camera(scenario)
    clearing = scenario.task == "clear"
    if clearing and first_near_W is None:
        raise ValueError(
            "the clear task's segmenter needs the place it takes the nearest object to first (first_near_W)"
        )
    if category is None:
        category = "" if clearing else scenario.requested_category
    return Segmenter(
        weights or categories.active_segmenter(),
        category=category,
        intrinsics=intrinsics,
        X_BC=X_BC,
        table_top_z=scenario.table_xyz[2] + TABLE_HEIGHT,
        part_segmenter=MakePartSegmenter(scenario),
        first_near_W=tuple(first_near_W) if clearing else None,
    )


def MakePartSegmenter(scenario: Scenario) -> PartSegmenter | None:
    """The part network, where the scenario builds grasps on the seen parts (and its weights are there)."""
    if not scenario.part_grasps:
        return None
    if not DEFAULT_PART_WEIGHTS.is_file():
        logging.warning("no part network (%s): grasps from the shape-space fit alone", DEFAULT_PART_WEIGHTS)
        return None
    return PartSegmenter(DEFAULT_PART_WEIGHTS)


def MakePoseEstimator(scenario: Scenario) -> PoseEstimator:
    """A PoseEstimator with the intrinsics and mounting of the scenario's depth camera and the catalog's priors."""
    intrinsics, X_BC = depth_camera(scenario)
    return PoseEstimator(intrinsics, category_priors(), X_BC)


def MakeObjectTracker(scenario: Scenario) -> ObjectTracker:
    """An ObjectTracker with the intrinsics and mounting of the scenario's depth camera; an aim's takes every tilt
    its looks refine."""
    tilt = AIM_MIN_TILT_CHANGE_RAD if scenario.task == "aim" else MIN_TILT_CHANGE_RAD
    return ObjectTracker(*depth_camera(scenario), min_tilt_change_rad=tilt)


def MakePerception(
    scenario: Scenario,
    weights: Path | None = None,
    robot_spheres: RobotSpheres | None = None,
    torso_axis_W=(0.0, 0.0),
) -> Diagram:
    """Perception as one subsystem ("perception"): camera_latch -> segmenter -> pose_estimator ->
    [registration_yaw_noise] -> shape_registrar, gathered by perception_result; with robot_spheres, also
    scene_cloud: the rest of the scene as seen (systems/perception/scene_cloud.py), and scene_memory: with what the
    robot hides in the frame remembered from the frame before (systems/perception/scene_memory.py).

    Input ports: color_image, depth_image, camera_pose (the camera's), trigger (1: the frame wanted), image_health
    (optional LinkHealth: the latch waits for fresh images), and with
    robot_spheres robot_position (the planned joints, rad: latched with the frame); for the clear task, left_out
    (LeftOut: the segmenter's).
    Output ports: frame_id (1: the frame latched), result (PerceptionResult), and the registrar's
    grasp_poses (GraspPoses), reconstructed_cloud_W (N x 3, m) and X_WO (RigidTransform); with robot_spheres,
    scene_cloud_W (N x 3 in W, m: its occupied points); for the aim task, board (BoardSeen: board_finder's); for the
    pour task, container (ContainerSeen: container_finder's).

    Args:
        weights: the segmenter's; None: the one that knows every taught category (categories.active_segmenter).
        robot_spheres: the robot's sphere model (a RobotSpheres of its own): what the camera sees of the robot is
            not the scene.
        torso_axis_W: where the torso's axis meets the floor plane (x, y in W, m): the scene is kept within reach.
    """
    builder = DiagramBuilder()
    dof = robot_spheres.kinematics.dof if robot_spheres is not None else 14
    latch = builder.AddNamedSystem("camera_latch", CameraLatch(robot_positions=dof, offset_s=latch_offset(scenario)))
    zone_centre = drop_zone(scenario).centre_W if scenario.task == "clear" else None
    segmenter = builder.AddNamedSystem("segmenter", MakeSegmenter(scenario, weights, first_near_W=zone_centre))
    pose_estimator = builder.AddNamedSystem("pose_estimator", MakePoseEstimator(scenario))
    registrar = builder.AddNamedSystem("shape_registrar", ShapeRegistrar(part_grasps=scenario.part_grasps))
    collector = builder.AddNamedSystem("perception_result", PerceptionResultCollector())
    for port in ("color_image", "depth_image", "camera_pose", "trigger", "image_health"):
        builder.ExportInput(latch.GetInputPort(port), port)
    if scenario.task == "clear":  # what the segmenter leaves out: the drop zone, the objects given up
        builder.ExportInput(segmenter.GetInputPort("left_out"), "left_out")
    builder.Connect(latch.GetOutputPort("color_image"), segmenter.GetInputPort("color_image"))
    builder.Connect(latch.GetOutputPort("depth_image"), segmenter.GetInputPort("depth_image"))
    builder.Connect(latch.GetOutputPort("camera_pose"), segmenter.GetInputPort("camera_pose"))
    builder.Connect(segmenter.GetOutputPort("segmentation"), pose_estimator.GetInputPort("segmentation"))
    builder.Connect(latch.GetOutputPort("depth_image"), pose_estimator.GetInputPort("depth_image"))
    builder.Connect(latch.GetOutputPort("camera_pose"), pose_estimator.GetInputPort("camera_pose"))
    estimate = pose_estimator.GetOutputPort("estimate")
    if scenario.registration_yaw_noise > 0:  # the paper's experiment: a perturbed pose for the registration
        offset = draw_yaw_offset(scenario.registration_yaw_noise, scenario.random_seed)
        noise = builder.AddNamedSystem("registration_yaw_noise", PoseYawOffset(offset))
        builder.Connect(estimate, noise.get_input_port())
        estimate = noise.get_output_port()
    builder.Connect(estimate, registrar.GetInputPort("estimate"))
    for port, source in (
        ("segmentation", segmenter.GetOutputPort("segmentation")),
        ("estimate", pose_estimator.GetOutputPort("estimate")),
        ("grasp_poses", registrar.GetOutputPort("grasp_poses")),
        ("reconstructed_cloud_W", registrar.GetOutputPort("reconstructed_cloud_W")),
        ("X_WO", registrar.GetOutputPort("X_WO")),
    ):
        builder.Connect(source, collector.GetInputPort(port))
    builder.Connect(latch.GetOutputPort("latched_wall_s"), collector.GetInputPort("latched_wall_s"))
    builder.ExportOutput(latch.GetOutputPort("frame_id"), "frame_id")
    builder.ExportOutput(collector.GetOutputPort("result"), "result")
    for port in ("grasp_poses", "reconstructed_cloud_W", "X_WO"):
        builder.ExportOutput(registrar.GetOutputPort(port), port)
    if robot_spheres is not None:
        builder.ExportInput(latch.GetInputPort("robot_position"), "robot_position")
        robot = builder.AddNamedSystem("robot_spheres", robot_spheres)
        builder.Connect(latch.GetOutputPort("robot_position"), robot.GetInputPort("position"))
        intrinsics, X_BC = depth_camera(scenario)
        table_top_z = scenario.table_xyz[2] + TABLE_HEIGHT
        scene = builder.AddNamedSystem("scene_cloud", SceneCloud(intrinsics, X_BC, table_top_z, torso_axis_W))
        for port, source in (
            ("depth_image", latch.GetOutputPort("depth_image")),
            ("camera_pose", latch.GetOutputPort("camera_pose")),
            ("segmentation", segmenter.GetOutputPort("segmentation")),
            ("robot_spheres_W", robot.GetOutputPort("spheres_W")),
            ("object_cloud_W", registrar.GetOutputPort("reconstructed_cloud_W")),
        ):
            builder.Connect(source, scene.GetInputPort(port))
        memory = builder.AddNamedSystem("scene_memory", SceneMemory(intrinsics, X_BC, offset_s=latch_offset(scenario)))
        for port, source in (
            ("scene_cloud_W", scene.GetOutputPort("scene_cloud_W")),
            ("depth_image", latch.GetOutputPort("depth_image")),
            ("camera_pose", latch.GetOutputPort("camera_pose")),
            ("robot_spheres_W", robot.GetOutputPort("spheres_W")),
            ("object_cloud_W", registrar.GetOutputPort("reconstructed_cloud_W")),
            ("frame_id", latch.GetOutputPort("frame_id")),
        ):
            builder.Connect(source, memory.GetInputPort(port))
        builder.ConnectInput("trigger", memory.GetInputPort("trigger"))
        builder.ExportOutput(memory.GetOutputPort("scene_cloud_W"), "scene_cloud_W")
    if scenario.task == "aim":  # the board and its target, in the same frame
        board = builder.AddNamedSystem("board_finder", BoardFinder(*depth_camera(scenario)))
        for port in ("color_image", "depth_image", "camera_pose"):
            builder.Connect(latch.GetOutputPort(port), board.GetInputPort(port))
        builder.ExportOutput(board.GetOutputPort("board"), "board")
    if scenario.task == "pour":  # the container's opening, in the same frame
        table_top_z = scenario.table_xyz[2] + TABLE_HEIGHT
        container = builder.AddNamedSystem("container_finder", ContainerFinder(*depth_camera(scenario), table_top_z))
        for port in ("depth_image", "camera_pose"):
            builder.Connect(latch.GetOutputPort(port), container.GetInputPort(port))
        builder.Connect(segmenter.GetOutputPort("segmentation"), container.GetInputPort("segmentation"))
        builder.ExportOutput(container.GetOutputPort("container"), "container")
    diagram = builder.Build()
    diagram.set_name("perception")
    return diagram


def true_board(scenario: Scenario) -> BoardSeen:
    """The aim task's board and target where the station puts them."""
    placement = board_placement(scenario)
    return BoardSeen(True, placement.normal_W, placement.target_W, "ground truth")


def true_container(scenario: Scenario) -> ContainerSeen:
    """The pour task's container's opening where the station puts it."""
    opening = true_opening(scenario)
    return ContainerSeen(True, opening.centre_W, opening.radius, "ground truth")


def MakeGroundTruthPerception(scenario: Scenario, surface_points: int = TRUE_SURFACE_POINTS) -> Diagram:
    """The ground-truth source ("ground_truth") with perception's output ports: the object's true grasp
    frames, surface and pose where the station puts it, and the other objects' surfaces as the scene cloud (the
    oracle pick; no camera, frame_id 0).

    Raises:
        ValueError: the object's model has no grasp frames.
    """
    poses = true_grasp_poses(scenario)
    model = resolve_object(scenario.object)
    X_WO = object_pose_on_table(scenario, model)
    surface, _ = object_surface_W(model, X_WO, surface_points)
    tool_O = model.info.tool_frame()
    grasps = GraspPoses(True, poses, "ground truth", tool_W=None if tool_O is None else tool_O.moved(X_WO))
    result = PerceptionResult(True, None, "ground truth", scenario.object.category, X_WO, grasps, None, surface)
    builder = DiagramBuilder()
    for name, value in (
        ("result", result),
        ("grasp_poses", grasps),
        ("reconstructed_cloud_W", surface),
        ("X_WO", X_WO),
        ("scene_cloud_W", clutter_surfaces_W(scenario, SEEN_SPACING_M)),
        *((("board", true_board(scenario)),) if scenario.task == "aim" else ()),
        *((("container", true_container(scenario)),) if scenario.task == "pour" else ()),
    ):
        source = builder.AddNamedSystem(name, ConstantValueSource(AbstractValue.Make(value)))
        builder.ExportOutput(source.get_output_port(), name)
    frame = builder.AddNamedSystem("frame_id", ConstantVectorSource([0.0]))
    builder.ExportOutput(frame.get_output_port(), "frame_id")
    diagram = builder.Build()
    diagram.set_name("ground_truth")
    return diagram
