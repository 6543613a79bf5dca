"""The simulated Centauro station: plant, controllers and the chest RGB-D camera.

MakeStation(scenario) returns a Diagram with these exported ports (the hardware
station of the LCM backend exposes the same names):

  inputs:  centauro.position (n, rad), left_hand.position, right_hand.position
           (1 each: opening width, m)
  outputs: centauro.position_commanded, centauro.position_measured,
           centauro.velocity_estimated (n each), centauro.state_estimated (2n),
           centauro.torque_commanded (n, N m),
           left_hand.state_measured, right_hand.state_measured (2 each: width m, m/s),
           camera0.rgb_image, camera0.depth_image (32F, m), camera0.pose (X_WB of the camera body),
           centauro.status_health, camera0.image_health (LinkHealth: here always fresh)

The plant is named "plant" inside the diagram, the camera "camera0.sensor"; the
simulator's ground truth (poses, contacts, the label image) is read from them, never
through an exported port. n is the number of planned joints (diagrams/scenario.py:
planned_joints): 15, the left arm, the right arm and the torso yaw, or 14 with the torso
locked. The camera rides on the torso: its pose follows the torso's yaw.
"""

import dataclasses
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import (
    AddRigidHydroelasticProperties,
    Box,
    CollisionFilterDeclaration,
    Convex,
    Cylinder,
    MakeRenderEngineVtk,
    Mesh,
    Meshcat,
    MeshcatVisualizer,
    MeshcatVisualizerParams,
    ProximityProperties,
    RenderEngineVtkParams,
    Role,
    RoleAssign,
    SceneGraph,
)
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlant, CoulombFriction, MultibodyPlant
from pydrake.multibody.tree import PdControllerGains, SpatialInertia
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import Demultiplexer, MatrixGain, PassThrough, StateInterpolatorWithDiscreteDerivative
from pydrake.systems.sensors import RgbdSensor

from diagrams.aim_board import AddBoard
from diagrams.generation.centauro_description import TORSO_JOINT, joint_names, sdf_name
from diagrams.generation.objects import catalog
from diagrams.generation.objects.bowl import bowl_file
from diagrams.generation.objects.library import ObjectModel, resolve_object
from diagrams.paths import PACKAGE_XML
from diagrams.pour_container import table_clutter
from diagrams.scenario import (
    TABLE_HALF_SIZE,
    TABLE_HEIGHT,
    ClutterObjectConfig,
    ObjectConfig,
    Scenario,
    initial_positions,
    planned_joints,
    torso_free,
)
from systems.perception.rgbd_noise import RgbdNoise, sensor_model
from systems.planning.drop_zone import DropZone
from systems.robot_io.gravity_compensation import GravityCompensation
from systems.robot_io.simulated_links import FreshLink

ARM_INSTANCE = "centauro"
HAND_INSTANCES = {"left": "left_hand", "right": "right_hand"}
OBJECT_INSTANCE = "object"
CLUTTER_INSTANCE = "clutter_{}"  # the scenario's other objects, by their index in scenario.clutter
# Lift the object this far above the table at t = 0 so that it settles without penetration.
OBJECT_DROP_HEIGHT = 0.002


def make_parser(plant: MultibodyPlant) -> Parser:
    """A parser that resolves package://dualarm/... to this repository's sdf/ folder."""
    parser = Parser(plant)
    parser.package_map().AddPackageXml(str(PACKAGE_XML))
    return parser


def AddCentauro(plant: MultibodyPlant, scene_graph: SceneGraph, scenario: Scenario):
    """Adds the robot (pelvis welded at the scenario's height) and both hands.

    Collisions between each hand and its own wrist (links 5 to 7) are filtered out:
    they touch by construction.

    Returns:
        (arm model instance, {"left": hand instance, "right": hand instance})
    """
    parser = make_parser(plant)
    (robot,) = parser.AddModels(url=f"package://dualarm/centauro/{sdf_name(torso_free(scenario))}")
    plant.WeldFrames(
        plant.world_frame(),
        plant.GetFrameByName("pelvis", robot),
        RigidTransform([0.0, 0.0, scenario.pelvis_height]),
    )
    hands = {}
    for arm, (side, name) in enumerate(HAND_INSTANCES.items(), start=1):
        parser.SetAutoRenaming(True)
        (hand,) = parser.AddModels(url="package://dualarm/centauro/hand.sdf")
        plant.RenameModelInstance(hand, name)
        plant.WeldFrames(plant.GetFrameByName(f"arm{arm}_flange", robot), plant.GetFrameByName("hand_base", hand))
        hands[side] = hand
        wrist = [plant.GetBodyByName(f"arm{arm}_{i}", robot) for i in (5, 6, 7)]
        bodies = wrist + [plant.get_body(i) for i in plant.GetBodyIndices(hand)]
        scene_graph.collision_filter_manager().Apply(
            CollisionFilterDeclaration().ExcludeWithin(plant.CollectRegisteredGeometries(bodies))
        )
    return robot, hands


def AddTable(plant: MultibodyPlant, scenario: Scenario):
    """Adds the table (welded) and the floor; returns the table model instance."""
    parser = make_parser(plant)
    (table,) = parser.AddModels(url="package://dualarm/scene/table.sdf")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("table", table), RigidTransform(scenario.table_xyz))
    (floor,) = parser.AddModels(url="package://dualarm/scene/floor.sdf")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("floor", floor))
    return table


def object_pose_on_table(scenario: Scenario, model: ObjectModel) -> RigidTransform:
    """X_WO of the object resting on the table at the scenario's xy and yaw."""
    x, y = scenario.object.xy
    top = np.array(scenario.table_xyz) + [x, y, TABLE_HEIGHT + OBJECT_DROP_HEIGHT]
    yaw = model.presentation_yaw + scenario.object.yaw
    return RigidTransform(RollPitchYaw(0.0, 0.0, yaw), top)


def place_target(scenario: Scenario) -> RigidTransform:
    """X_WO where the place task should leave the object: on the table at place.xy, turned by place.yaw from
    the category's presentation pose."""
    x, y = scenario.place.xy
    top = np.array(scenario.table_xyz) + [x, y, TABLE_HEIGHT]
    yaw = catalog.presentation_yaw(scenario.object.category) + scenario.place.yaw
    return RigidTransform(RollPitchYaw(0.0, 0.0, yaw), top)


def drop_zone(scenario: Scenario, robot_spheres_W: np.ndarray | None = None) -> DropZone:
    """The clear task's drop zone in W (scenario.clear: its centre in the table_top frame), on the table's top; with
    the robot's spheres at its home between objects (S x 4: centre in W, radius; m; clear_home), those reaching below
    ZONE_KEEP_OUT_HEIGHT_M above the table top are its keep-out circles."""
    centre = np.array(scenario.table_xyz[:2]) + scenario.clear.zone_xy
    keep_out = ()
    if robot_spheres_W is not None:
        low = robot_spheres_W[robot_spheres_W[:, 2] - robot_spheres_W[:, 3] < scenario.table_xyz[2] + TABLE_HEIGHT
                              + ZONE_KEEP_OUT_HEIGHT_M]  # fmt: skip
        keep_out = tuple((float(x), float(y), float(r)) for x, y, _, r in low)
    table = np.array(scenario.table_xyz[:2])
    table_W = (tuple(map(float, table - TABLE_HALF_SIZE)), tuple(map(float, table + TABLE_HALF_SIZE)))
    return DropZone(
        (float(centre[0]), float(centre[1])), tuple(map(float, scenario.clear.zone_size)), keep_out, table_W
    )


# m: the robot's spheres at its home between objects reaching below this above the table top keep objects out of the
# drop zone (the tallest familiar object, a watering can's handle, stands about 30 cm)
ZONE_KEEP_OUT_HEIGHT_M = 0.32


def clear_home(scenario: Scenario) -> Scenario:
    """The scenario with the robot's arms where a clear sends them between objects (clear.home_arm_positions; the
    start where it is empty): the robot_spheres_W of drop_zone() are taken there."""
    home = scenario.clear.home_arm_positions
    return dataclasses.replace(scenario, initial_arm_positions=list(home)) if home else scenario


ZONE_MARK_RGBA = (0.15, 0.15, 0.15, 1.0)
ZONE_MARK_WIDTH_M = 0.01  # m: the lines that mark the drop zone's edges on the table, 1 mm high (seen only)


def AddDropZoneMarks(plant: MultibodyPlant, scenario: Scenario) -> None:
    """Marks the clear task's drop zone on the table: four dark lines along its edges, seen only (no collision)."""
    zone = drop_zone(scenario)
    z = scenario.table_xyz[2] + TABLE_HEIGHT + 0.0005
    (sx, sy), (cx, cy) = zone.size, zone.centre_W
    w = ZONE_MARK_WIDTH_M
    for name, centre, size in (
        ("near", (cx - sx / 2, cy), (w, sy + w, 0.001)),
        ("far", (cx + sx / 2, cy), (w, sy + w, 0.001)),
        ("right", (cx, cy - sy / 2), (sx + w, w, 0.001)),
        ("left", (cx, cy + sy / 2), (sx + w, w, 0.001)),
    ):
        plant.RegisterVisualGeometry(
            plant.world_body(), RigidTransform([*centre, z]), Box(*size), f"drop_zone_{name}", np.array(ZONE_MARK_RGBA)
        )


def AddBoxObstacle(plant: MultibodyPlant, scenario: Scenario):
    """The scenario's box on the table (welded to the world), if it has one."""
    box = scenario.obstacle
    if not box.present:
        return
    x, y = box.xy
    X_WB = RigidTransform(np.array(scenario.table_xyz) + [x, y, TABLE_HEIGHT + box.size[2] / 2])
    shape = Box(*box.size)
    body = plant.world_body()
    plant.RegisterVisualGeometry(body, X_WB, shape, "obstacle_visual", np.array([0.55, 0.35, 0.2, 1.0]))
    friction = CoulombFriction(0.6, 0.5)
    plant.RegisterCollisionGeometry(body, X_WB, shape, "obstacle_collision", friction)


def clutter_object_config(other: ClutterObjectConfig) -> ObjectConfig:
    """The ObjectConfig of a clutter object that is a category's generated instance."""
    return ObjectConfig(category=other.kind, instance=other.instance, xy=list(other.xy), yaw=other.yaw)


def clutter_pose_on_table(scenario: Scenario, other: ClutterObjectConfig) -> RigidTransform:
    """X_WB of a clutter object's body resting on the table (a category's yaw from its presentation pose)."""
    x, y = other.xy
    top = np.array(scenario.table_xyz) + [x, y, TABLE_HEIGHT + OBJECT_DROP_HEIGHT]
    yaw = other.yaw + (catalog.presentation_yaw(other.kind) if other.instance else 0.0)
    return RigidTransform(RollPitchYaw(0.0, 0.0, yaw), top)


def AddClutter(plant: MultibodyPlant, scene_graph: SceneGraph, scenario: Scenario) -> list:
    """Adds the scenario's other objects (table_clutter: scenario.clutter, and a pour's container last) as free bodies
    resting on the table, each in a model instance CLUTTER_INSTANCE.format(index); returns their bodies."""
    bodies = []
    friction = CoulombFriction(0.6, 0.5)
    for index, other in enumerate(table_clutter(scenario)):
        name = CLUTTER_INSTANCE.format(index)
        if other.instance:  # a generated instance of a category
            model_file = resolve_object(clutter_object_config(other)).model_file
            (instance,) = make_parser(plant).AddModels(file_name=str(model_file))
            plant.RenameModelInstance(instance, name)
            body = plant.get_body(plant.GetBodyIndices(instance)[0])
        else:
            instance = plant.AddModelInstance(name)
            width, _, height = other.size
            if other.kind == "box":
                inertia = SpatialInertia.SolidBoxWithMass(other.mass, *other.size)
                visual = collision = Box(*other.size)
                X_BS = RigidTransform([0.0, 0.0, height / 2])
            elif other.kind == "cylinder":
                inertia = SpatialInertia.SolidCylinderWithMass(other.mass, width / 2, height, [0.0, 0.0, 1.0])
                visual = collision = Cylinder(width / 2, height)
                X_BS = RigidTransform([0.0, 0.0, height / 2])
            else:  # a bowl or a pot: its own mesh to see, its convex hull to touch
                inertia = SpatialInertia.SolidCylinderWithMass(other.mass, width / 2, height, [0.0, 0.0, 1.0])
                mesh = str(bowl_file(width, height, pot=other.kind == "pot"))
                visual, collision, X_BS = Mesh(mesh), Convex(mesh), RigidTransform()
            body = plant.AddRigidBody(name, instance, inertia)
            plant.RegisterVisualGeometry(body, X_BS, visual, f"{name}_visual", np.append(other.color, 1.0))
            properties = ProximityProperties()
            properties.AddProperty("material", "coulomb_friction", friction)
            AddRigidHydroelasticProperties(0.01, properties)
            plant.RegisterCollisionGeometry(body, X_BS, collision, f"{name}_collision", properties)
        plant.SetDefaultFloatingBaseBodyPose(body, clutter_pose_on_table(scenario, other))
        _make_rigid_hydroelastic(plant, scene_graph, body)
        bodies.append(body)
    return bodies


def _make_rigid_hydroelastic(plant: MultibodyPlant, scene_graph: SceneGraph, body) -> None:
    """The body's collision geometries rigid hydroelastic (unless they say otherwise): it stands on the compliant
    table top over a patch; the hands still touch it at points."""
    inspector = scene_graph.model_inspector()
    for geometry in plant.GetCollisionGeometriesForBody(body):
        properties = ProximityProperties(inspector.GetProximityProperties(geometry))
        if not properties.HasGroup("hydroelastic"):
            AddRigidHydroelasticProperties(properties)
            scene_graph.AssignRole(plant.get_source_id(), geometry, properties, RoleAssign.kReplace)


def AddObject(plant: MultibodyPlant, scene_graph: SceneGraph, scenario: Scenario):
    """Adds the scenario's object as a free body resting on the table.

    Its collision pieces are made rigid hydroelastic (unless its model says otherwise), so that it stands
    on the compliant table top over a patch (sdf/scene/table.sdf); the hands still touch it at points.

    Returns:
        (object model instance, its ObjectModel)
    """
    model = resolve_object(scenario.object)
    parser = make_parser(plant)
    instances = parser.AddModels(file_name=str(model.model_file))
    if len(instances) != 1:
        raise ValueError(f"{model.model_file} must hold exactly one model, found {len(instances)}")
    (instance,) = instances
    plant.RenameModelInstance(instance, OBJECT_INSTANCE)
    bodies = plant.GetBodyIndices(instance)
    if not bodies:
        raise ValueError(f"{model.model_file} has no links")
    body = plant.get_body(bodies[0])
    plant.SetDefaultFloatingBaseBodyPose(body, object_pose_on_table(scenario, model))
    _make_rigid_hydroelastic(plant, scene_graph, body)
    return instance, model


def MakeStation(scenario: Scenario, meshcat: Meshcat | None = None) -> Diagram:
    """Builds the simulated station for `scenario`; see the module docstring for its ports.

    Args:
        scenario: the run's configuration.
        meshcat: if given, the station draws itself there.
    """
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(scenario.plant_config, builder)
    robot, hands = AddCentauro(plant, scene_graph, scenario)
    AddTable(plant, scenario)
    AddBoxObstacle(plant, scenario)
    if scenario.task == "aim":
        AddBoard(plant, scenario)
    if scenario.task == "clear":
        AddDropZoneMarks(plant, scenario)
    if scenario.object.present:
        AddObject(plant, scene_graph, scenario)
    AddClutter(plant, scene_graph, scenario)
    plant.Finalize()

    _set_arm_pd_gains(plant, robot, scenario)
    for hand in hands.values():
        _set_pd_gains(plant, hand, [scenario.hand_controller.kp] * 2, [scenario.hand_controller.kd] * 2)
    _set_default_positions(plant, robot, hands, scenario)

    _AddArmController(builder, plant, robot, scenario)
    for side, hand in hands.items():
        _AddHandController(builder, plant, hand, HAND_INSTANCES[side])
    _AddCamera(builder, plant, scene_graph, scenario)

    if meshcat is not None:
        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, MeshcatVisualizerParams(role=Role.kIllustration))
        _frame_the_table(meshcat, scenario)
    diagram = builder.Build()
    diagram.set_name("station")
    return diagram


def _frame_the_table(meshcat: Meshcat, scenario: Scenario):
    """Meshcat's camera in front of the robot, to its left, looking at the space between the chest and the table."""
    x, y, _ = scenario.table_xyz
    target = np.array([0.6 * x, y, scenario.pelvis_height - 0.15])
    meshcat.SetCameraPose(camera_in_world=target + [1.5, 1.3, 0.55], target_in_world=target)


@dataclass
class StationFrame:
    """The chest camera's images once the objects have settled, with the simulator's ground truth (for benchmarks
    and tests: the pick itself never reads labels or poses)."""

    rgb: np.ndarray  # H x W x 3 uint8, as the sensor model reports it
    depth: np.ndarray  # H x W float32, m
    X_WB: RigidTransform  # the camera body's pose (the station's camera0.pose)
    labels: np.ndarray  # H x W render labels: the plant's body index of what each pixel sees
    X_WO: RigidTransform | None  # the object's pose (None without one)
    object_label: int  # the object's render label (-1 without one)


def settled_frame(scenario: Scenario, at_s: float = 0.4) -> StationFrame:
    """The station's camera frame at context time at_s (the objects settled), the robot holding its start."""
    from pydrake.systems.analysis import Simulator  # (here alone: the station itself never simulates)

    station = MakeStation(scenario)
    simulator = Simulator(station)
    context = simulator.get_mutable_context()
    station.GetInputPort("centauro.position").FixValue(context, initial_positions(scenario))
    for hand in HAND_INSTANCES.values():
        station.GetInputPort(f"{hand}.position").FixValue(context, [scenario.initial_hand_width])
    simulator.AdvanceTo(at_s)
    camera = scenario.camera.name
    rgb = np.asarray(station.GetOutputPort(f"{camera}.rgb_image").Eval(context).data)[:, :, :3].copy()
    depth = np.asarray(station.GetOutputPort(f"{camera}.depth_image").Eval(context).data)[:, :, 0].copy()
    X_WB = station.GetOutputPort(f"{camera}.pose").Eval(context)
    plant = station.GetSubsystemByName("plant")
    X_WO, label = None, -1
    if plant.HasModelInstanceNamed(OBJECT_INSTANCE):
        body = plant.get_body(plant.GetBodyIndices(plant.GetModelInstanceByName(OBJECT_INSTANCE))[0])
        X_WO, label = body.EvalPoseInWorld(plant.GetMyContextFromRoot(context)), int(body.index())
    return StationFrame(rgb, depth, X_WB, true_label_image(station, context), X_WO, label)


def true_label_image(station: Diagram, context) -> np.ndarray:
    """Ground truth: the camera's H x W label image (render labels; body index values), from the station's context."""
    sensor = station.GetSubsystemByName("camera0.sensor")
    image = sensor.label_image_output_port().Eval(sensor.GetMyContextFromRoot(context))
    return np.asarray(image.data)[:, :, 0]


def _set_pd_gains(plant, instance, kp, kd):
    for index, p, d in zip(plant.GetJointActuatorIndices(instance), kp, kd, strict=True):
        plant.get_joint_actuator(index).set_controller_gains(PdControllerGains(p=p, d=d))


def _set_arm_pd_gains(plant, robot, scenario):
    """Each planned joint's actuator gains: the arms' per joint (both arms alike), the torso's own."""
    arm, torso = scenario.arm_controller, scenario.robot
    gains = dict(zip(joint_names(1) + joint_names(2), zip(arm.kp * 2, arm.kd * 2, strict=True), strict=True))
    gains[TORSO_JOINT] = (torso.torso_kp, torso.torso_kd)
    for index in plant.GetJointActuatorIndices(robot):
        actuator = plant.get_joint_actuator(index)
        kp, kd = gains[actuator.joint().name()]
        actuator.set_controller_gains(PdControllerGains(p=kp, d=kd))


def planned_from_instance(plant, robot, scenario) -> np.ndarray:
    """P (n x n) with q_planned = P q_instance: the robot instance's own order of positions (and of actuators:
    the torso first, then the arms) into the planned joints' order (the arms, then the torso)."""
    names = planned_joints(scenario)
    instance_rank = np.argsort(np.argsort([plant.GetJointByName(name, robot).position_start() for name in names]))
    return np.eye(len(names))[instance_rank]


def _set_default_positions(plant, robot, hands, scenario):
    for name, q in zip(planned_joints(scenario), initial_positions(scenario), strict=True):
        plant.GetJointByName(name, robot).set_default_angle(q)
    for hand in hands.values():
        for joint in ("finger_1_joint", "finger_2_joint"):
            plant.GetJointByName(joint, hand).set_default_translation(scenario.initial_hand_width / 2)


def _AddArmController(builder, plant, robot, scenario):
    """Position command -> desired state of the plant's PD actuators, plus gravity feed-forward; the robot's
    state in the planned joints' order."""
    n = plant.num_positions(robot)
    P = planned_from_instance(plant, robot, scenario)
    command = builder.AddSystem(PassThrough(n))
    command.set_name("centauro.command")
    to_instance = builder.AddNamedSystem("centauro.command_to_actuators", MatrixGain(P.T))
    interpolator = builder.AddSystem(
        StateInterpolatorWithDiscreteDerivative(n, scenario.plant_config.time_step, suppress_initial_transient=True)
    )
    interpolator.set_name("centauro.desired_state")
    builder.Connect(command.get_output_port(), to_instance.get_input_port())
    builder.Connect(to_instance.get_output_port(), interpolator.get_input_port())
    builder.Connect(interpolator.get_output_port(), plant.get_desired_state_input_port(robot))
    gravity = builder.AddSystem(GravityCompensation(plant, robot))
    gravity.set_name("centauro.gravity_compensation")
    builder.Connect(plant.get_state_output_port(), gravity.state_input)
    builder.Connect(gravity.actuation_output, plant.get_actuation_input_port(robot))

    builder.ExportInput(command.get_input_port(), "centauro.position")
    builder.ExportOutput(command.get_output_port(), "centauro.position_commanded")
    state = builder.AddNamedSystem("centauro.state", MatrixGain(np.kron(np.eye(2), P)))
    builder.Connect(plant.get_state_output_port(robot), state.get_input_port())
    builder.ExportOutput(state.get_output_port(), "centauro.state_estimated")
    demux = builder.AddSystem(Demultiplexer([n, n]))
    demux.set_name("centauro.state_demux")
    builder.Connect(state.get_output_port(), demux.get_input_port())
    builder.ExportOutput(demux.get_output_port(0), "centauro.position_measured")
    builder.ExportOutput(demux.get_output_port(1), "centauro.velocity_estimated")
    torque = builder.AddNamedSystem("centauro.torque", MatrixGain(P))
    builder.Connect(plant.get_net_actuation_output_port(robot), torque.get_input_port())
    builder.ExportOutput(torque.get_output_port(), "centauro.torque_commanded")
    status = builder.AddNamedSystem("centauro.status_link", FreshLink("centauro status"))
    builder.ExportOutput(status.GetOutputPort("health"), "centauro.status_health")


def _AddHandController(builder, plant, hand, name):
    """Opening width command -> both fingers' desired state; finger state -> (width, rate)."""
    to_fingers = builder.AddSystem(MatrixGain(np.array([[0.5], [0.5], [0.0], [0.0]])))
    to_fingers.set_name(f"{name}.controller")
    builder.Connect(to_fingers.get_output_port(), plant.get_desired_state_input_port(hand))
    builder.ExportInput(to_fingers.get_input_port(), f"{name}.position")
    to_width = builder.AddSystem(MatrixGain(np.array([[1.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 1.0]])))
    to_width.set_name(f"{name}.state_measured")
    builder.Connect(plant.get_state_output_port(hand), to_width.get_input_port())
    builder.ExportOutput(to_width.get_output_port(), f"{name}.state_measured")


def _AddCamera(builder, plant, scene_graph, scenario):
    """The chest RGB-D sensor, mounted at the robot's camera_mount frame (VTK, headless)."""
    config = scenario.camera
    if not scene_graph.HasRenderer(config.renderer_name):
        scene_graph.AddRenderer(config.renderer_name, MakeRenderEngineVtk(RenderEngineVtkParams()))
    color_camera, depth_camera = config.MakeCameras()
    mount = plant.GetFrameByName("camera_mount")
    X_PB = mount.GetFixedPoseInBodyFrame() @ config.X_PB.GetDeterministicValue()
    sensor = builder.AddSystem(
        RgbdSensor(plant.GetBodyFrameIdOrThrow(mount.body().index()), X_PB, color_camera, depth_camera)
    )
    sensor.set_name(f"{config.name}.sensor")
    builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
    color, depth = sensor.color_image_output_port(), sensor.depth_image_32F_output_port()
    parameters = sensor_model(scenario.camera_noise.preset, scenario.camera_noise.overrides)
    if parameters is not None:  # a real sensor's images: everything downstream sees these
        noise = builder.AddNamedSystem(
            f"{config.name}.noise", RgbdNoise(depth_camera.core().intrinsics(), parameters, scenario.random_seed)
        )
        builder.Connect(color, noise.GetInputPort("color_image"))
        builder.Connect(depth, noise.GetInputPort("depth_image"))
        color, depth = noise.GetOutputPort("color_image"), noise.GetOutputPort("depth_image")
    builder.ExportOutput(color, f"{config.name}.rgb_image")
    builder.ExportOutput(depth, f"{config.name}.depth_image")
    builder.ExportOutput(sensor.body_pose_in_world_output_port(), f"{config.name}.pose")
    images = builder.AddNamedSystem(f"{config.name}.image_link", FreshLink(f"{config.name} images"))
    builder.ExportOutput(images.GetOutputPort("health"), f"{config.name}.image_health")
