"""The pick diagram: the design card's chain of stages around a station.

  station.camera0 -> camera_latch -> segmenter -> pose_estimator -> [registration_yaw_noise] ->
  shape_registrar -> stomp_planner -> trajectory_source -> station.centauro.position
  pick_sequencer: asks camera_latch for a frame, stomp_planner for plans, hand_command for the hands.

MakePickDiagram wires it around the simulated station or the hardware one that talks LCM to a
robot driver (both expose the same ports). With perception="ground_truth", a ground-truth source
(the object's true grasp frames and surface) stands where camera_latch ... shape_registrar were: the
same planner, trajectory source and sequencer (the "oracle" pick). Nothing else reads the
simulator's ground truth: run_pick judges the outcome on it only afterwards.
"""

import logging
from pathlib import Path

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat, Rgba
from pydrake.lcm import DrakeLcm, DrakeLcmInterface
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource

from diagrams.generation.objects.library import resolve_object
from diagrams.hardware_station import MakeHardwareStation
from diagrams.perception import AddPerception, MakeObjectTracker
from diagrams.pick_simulation import PickOutcome, PlaceJudge, pose_error, simulate_pick, station_plant
from diagrams.planning_scene import make_dual_arm_ik, object_surface_W, true_grasp_poses
from diagrams.robot_driver import MakeRobotDriver
from diagrams.scenario import Scenario
from diagrams.station import HAND_INSTANCES, MakeStation, object_pose_on_table, place_target
from systems.messages import GraspPoses
from systems.perception.camera_latch import CameraLatch
from systems.perception.pose_estimator import to_point_cloud
from systems.perception.pose_noise import PoseYawOffset, draw_yaw_offset
from systems.perception.robot_spheres import RobotSpheres
from systems.perception.shape_registrar import ShapeRegistrar
from systems.pick_sequencer import PickSequencer, PickStatus, lift_task, place_task
from systems.planning.pick_motions import PickMotions, PlanningError
from systems.planning.stomp_planner import StompPlanner
from systems.robot_io.hand_command import HandCommandSource
from systems.robot_io.trajectory_source import JointTrajectorySource

# Perceive once the object has settled on the table, s.
PERCEIVE_AT_S = 0.5
# A pick that has not ended by then is stopped, s.
MAX_PICK_S = 60.0
# The hands close this much further along their approach axis z_G than the perceived grasp, m:
# registration is off by 1-2 cm, and the fingertips reach only 2.5 cm past the grasp frame, so a
# hand that stops short can close on the handle's edge and lose it in the lift (the paper's
# real-robot failure, §V-C: "the approaching pose ... should be closer to the object").
GRASP_DEPTH_MARGIN = 0.01
# The ground-truth source's object surface: this many points (the planner thins to its own density).
TRUE_SURFACE_POINTS = 4000
PERCEPTION_SOURCES = ("camera", "ground_truth")


def MakePickDiagram(
    scenario: Scenario,
    meshcat: Meshcat | None = None,
    hardware: bool = False,
    lcm: DrakeLcmInterface | None = None,
    perception: str = "camera",
) -> Diagram:
    """The whole pick around the simulated station, or with `hardware`, the LCM one.

    Args:
        scenario: the run's configuration.
        meshcat: the simulated station draws itself there.
        hardware: build the LCM station (diagrams/hardware_station.py) instead of the simulation.
        lcm: the LCM bus of the hardware station (default: one on scenario.lcm.lcm_url).
        perception: "camera" (the autonomous chain) or "ground_truth" (the object's true grasp frames
            and surface, from the scenario: the oracle pick).

    Raises:
        PlanningError: ground truth asked for an object that has no grasp frames.
    """
    if perception not in PERCEPTION_SOURCES:
        raise ValueError(f"unknown perception {perception!r}: one of {PERCEPTION_SOURCES}")
    builder = DiagramBuilder()
    if hardware:
        station = builder.AddNamedSystem("station", MakeHardwareStation(scenario, lcm))
    else:
        station = builder.AddNamedSystem("station", MakeStation(scenario, meshcat))
    motions = PickMotions(make_dual_arm_ik(scenario))
    if hardware:  # the robot holds while the computer thinks: the plan starts once it exists
        motions.ik.stomp.config.time_limit_s = scenario.planning.hardware_time_limit_s
        latency_s = 0.0
    else:  # simulated planning takes a fixed time, whatever the machine: iterations, not seconds, limit STOMP
        motions.ik.stomp.config.time_limit_s = np.inf
        latency_s = scenario.planning.latency_s
    motions.ik.stomp.config.seed = scenario.random_seed
    margin = GRASP_DEPTH_MARGIN if perception == "camera" else 0.0
    planner = builder.AddNamedSystem("stomp_planner", StompPlanner(motions, latency_s, margin))
    source = builder.AddNamedSystem("trajectory_source", JointTrajectorySource())
    hands = builder.AddNamedSystem("hand_command", HandCommandSource())
    if scenario.task == "place":
        sequencer = PickSequencer(place_task(), PERCEIVE_AT_S, place_target(scenario))
    else:
        sequencer = PickSequencer(lift_task(), PERCEIVE_AT_S)
    builder.AddNamedSystem("pick_sequencer", sequencer)

    measured = station.GetOutputPort("centauro.position_measured")
    if perception == "camera":
        grasps, cloud, X_WO = _AddCameraPerception(builder, station, sequencer, scenario)
        if scenario.place.looks:
            _AddLooks(builder, station, sequencer, scenario, motions.ik.stomp, cloud, X_WO)
    else:
        grasps, cloud, X_WO = _AddGroundTruth(builder, scenario)
    builder.Connect(X_WO, sequencer.GetInputPort("X_WO"))
    builder.Connect(grasps, planner.GetInputPort("grasp_poses"))
    builder.Connect(cloud, planner.GetInputPort("obstacle_cloud_W"))
    builder.Connect(grasps, sequencer.GetInputPort("grasp_poses"))
    builder.Connect(sequencer.GetOutputPort("plan_request"), planner.GetInputPort("request"))
    builder.Connect(planner.GetOutputPort("plan"), source.GetInputPort("plan"))
    builder.Connect(planner.GetOutputPort("plan"), sequencer.GetInputPort("plan"))
    builder.Connect(measured, source.GetInputPort("position_measured"))
    builder.Connect(measured, sequencer.GetInputPort("position_measured"))
    builder.Connect(source.GetOutputPort("position"), station.GetInputPort("centauro.position"))
    builder.Connect(sequencer.GetOutputPort("hand_command"), hands.GetInputPort("command"))
    for side, hand in HAND_INSTANCES.items():
        builder.Connect(hands.GetOutputPort("width"), station.GetInputPort(f"{hand}.position"))
        builder.Connect(station.GetOutputPort(f"{hand}.state_measured"), sequencer.GetInputPort(f"{side}_hand_state"))
    diagram = builder.Build()
    diagram.set_name("pick")
    return diagram


def _AddCameraLatch(builder, name: str, station, scenario, trigger, frame_id):
    """A CameraLatch on the scenario's camera, taking a frame when `trigger` asks and telling `frame_id`."""
    camera = scenario.camera.name
    latch = builder.AddNamedSystem(name, CameraLatch())
    for port, source in (("color_image", "rgb_image"), ("depth_image", "depth_image"), ("camera_pose", "pose")):
        builder.Connect(station.GetOutputPort(f"{camera}.{source}"), latch.GetInputPort(port))
    builder.Connect(trigger, latch.GetInputPort("trigger"))
    builder.Connect(latch.GetOutputPort("frame_id"), frame_id)
    return latch


def _AddCameraPerception(builder, station, sequencer, scenario):
    """camera -> camera_latch -> segmenter -> pose_estimator -> [yaw noise] -> shape_registrar; the
    sequencer triggers the latch and reads each stage's result. Returns the registrar's grasp poses,
    reconstructed cloud and X_WO ports."""
    trigger, frame_id = sequencer.GetOutputPort("trigger"), sequencer.GetInputPort("frame_id")
    latch = _AddCameraLatch(builder, "camera_latch", station, scenario, trigger, frame_id)
    segmenter, pose_estimator = AddPerception(
        builder, *(latch.GetOutputPort(p) for p in ("color_image", "depth_image", "camera_pose")), scenario
    )
    registrar = builder.AddNamedSystem("shape_registrar", ShapeRegistrar())
    estimate = pose_estimator.GetOutputPort("estimate")
    if scenario.registration_yaw_noise > 0:
        offset = draw_yaw_offset(scenario.registration_yaw_noise, scenario.random_seed)
        noise = builder.AddNamedSystem("registration_yaw_noise", PoseYawOffset(offset))
        builder.Connect(estimate, noise.get_input_port())
        estimate = noise.get_output_port()
    builder.Connect(estimate, registrar.GetInputPort("estimate"))
    builder.Connect(segmenter.GetOutputPort("segmentation"), sequencer.GetInputPort("segmentation"))
    builder.Connect(pose_estimator.GetOutputPort("estimate"), sequencer.GetInputPort("estimate"))
    cloud = registrar.GetOutputPort("reconstructed_cloud_W")
    builder.Connect(cloud, sequencer.GetInputPort("reconstructed_cloud_W"))
    return registrar.GetOutputPort("grasp_poses"), cloud, registrar.GetOutputPort("X_WO")


def _AddLooks(builder, station, sequencer, scenario, stomp, model_cloud_W, model_X_WO):
    """The sequencer's looks at the held object: look_latch (the frame and the arms' joints then) ->
    robot_spheres -> object_tracker, which fits the first look's reconstruction (model_cloud_W, seen at
    model_X_WO) near the sequencer's expected_X_WO."""
    trigger, frame_id = sequencer.GetOutputPort("look_trigger"), sequencer.GetInputPort("look_frame_id")
    look = _AddCameraLatch(builder, "look_latch", station, scenario, trigger, frame_id)
    builder.Connect(station.GetOutputPort("centauro.position_measured"), look.GetInputPort("robot_position"))
    robot = builder.AddNamedSystem("robot_spheres", RobotSpheres(stomp))
    builder.Connect(look.GetOutputPort("robot_position"), robot.GetInputPort("position"))
    tracker = builder.AddNamedSystem("object_tracker", MakeObjectTracker(scenario))
    for port, source in (
        ("depth_image", look.GetOutputPort("depth_image")),
        ("camera_pose", look.GetOutputPort("camera_pose")),
        ("robot_spheres_W", robot.GetOutputPort("spheres_W")),
        ("expected_X_WO", sequencer.GetOutputPort("expected_X_WO")),
        ("model_cloud_W", model_cloud_W),
        ("model_X_WO", model_X_WO),
    ):
        builder.Connect(source, tracker.GetInputPort(port))
    builder.Connect(tracker.GetOutputPort("estimate"), sequencer.GetInputPort("look"))


def _AddGroundTruth(builder, scenario):
    """Sources of the object's true grasp frames and surface where the station puts it (the oracle)."""
    try:
        poses = true_grasp_poses(scenario)
    except ValueError as error:
        raise PlanningError(str(error)) from error
    model = resolve_object(scenario.object)
    X_WO = object_pose_on_table(scenario, model)
    surface, _ = object_surface_W(model, X_WO, TRUE_SURFACE_POINTS)
    grasps = builder.AddNamedSystem(
        "ground_truth.grasp_poses", ConstantValueSource(AbstractValue.Make(GraspPoses(True, poses, "ground truth")))
    )
    cloud = builder.AddNamedSystem("ground_truth.object_cloud_W", ConstantValueSource(AbstractValue.Make(surface)))
    pose = builder.AddNamedSystem("ground_truth.X_WO", ConstantValueSource(AbstractValue.Make(X_WO)))
    return grasps.get_output_port(), cloud.get_output_port(), pose.get_output_port()


def pick_status(diagram: Diagram, context) -> PickStatus:
    sequencer = diagram.GetSubsystemByName("pick_sequencer")
    return sequencer.GetOutputPort("status").Eval(sequencer.GetMyContextFromRoot(context))


def draw_perception(meshcat: Meshcat, status: PickStatus):
    """What the plan was made from (the camera's object points, the reconstruction) and the planned
    grasp-frame paths, in meshcat."""
    for path, points_W, rgba in (
        ("perception/camera_points", status.seen_points_W, Rgba(0.1, 0.4, 1.0, 1.0)),
        ("perception/reconstruction", status.reconstruction_W, Rgba(1.0, 0.6, 0.0, 1.0)),
    ):
        if points_W is not None:  # (a ground-truth pick sees nothing)
            meshcat.SetObject(path, to_point_cloud(points_W), point_size=0.006, rgba=rgba)
    for index, paths in enumerate(status.grasp_paths_W):
        for side, path_W in paths.items():
            meshcat.SetLine(f"perception/grasp_path_{index}_{side}", path_W.T, 3.0, Rgba(0.1, 0.8, 0.2, 1.0))


def MakeLcmPickWorld(scenario: Scenario, lcm: DrakeLcmInterface, meshcat: Meshcat | None = None) -> Diagram:
    """The robot driver emulator ("robot_driver") and the hardware-backend pick diagram ("pick") side by side.

    They share no port: everything between them goes as encoded LCM messages over `lcm`
    (an in-process memq:// bus), so one simulator steps both in lockstep.
    """
    builder = DiagramBuilder()
    builder.AddNamedSystem("robot_driver", MakeRobotDriver(scenario, lcm, meshcat))
    builder.AddNamedSystem("pick", MakePickDiagram(scenario, hardware=True, lcm=lcm))
    world = builder.Build()
    world.set_name("lcm_pick_world")
    return world


def run_pick(
    scenario: Scenario,
    meshcat: Meshcat | None = None,
    record: Path | None = None,
    backend: str = "sim",
    perception: str = "camera",
) -> PickOutcome:
    """Simulates the pick until it is done (or a stage failed), then judges it on ground truth.

    Args:
        backend: "sim" (the simulated station) or "lcm-memq" (the hardware station against the
            robot driver emulator over an in-process LCM bus).
        perception: "camera" (autonomous) or "ground_truth" (the oracle pick).
    """
    if backend == "sim":
        diagram = pick = MakePickDiagram(scenario, meshcat, perception=perception)
        plant = station_plant(diagram)
    elif backend == "lcm-memq":
        diagram = MakeLcmPickWorld(scenario, DrakeLcm("memq://"), meshcat)
        pick = diagram.GetSubsystemByName("pick")
        plant = station_plant(diagram.GetSubsystemByName("robot_driver"))
    else:
        raise ValueError(f"unknown backend {backend!r}: sim or lcm-memq")
    watch = PickWatcher(pick, meshcat)
    make_judge = None
    if scenario.task == "place":

        def make_judge(plant, context):
            return PlaceJudge(plant, context, place_target(scenario), lambda c: watch.status(c).mode)

    outcome = simulate_pick(diagram, scenario, watch.end_time, meshcat, record, plant=plant, make_judge=make_judge)
    return watch.finish(outcome)


class PickWatcher:
    """Follows the PickSequencer during a simulation: logs mode changes, draws what each plan was made
    from, and says when the pick has ended."""

    def __init__(self, pick: Diagram, meshcat: Meshcat | None = None):
        self.pick, self.meshcat = pick, meshcat
        self.mode, self.drawn_plans = "", 0

    def status(self, context) -> PickStatus:
        return pick_status(self.pick, context)

    def end_time(self, context) -> float:
        """When to stop, in context seconds: now if the pick is done or failed, else MAX_PICK_S."""
        status = self.status(context)
        if status.mode != self.mode:
            note = f": {status.message}" if status.mode == "failed" else ""
            logging.info("t = %5.2f s  %s%s", context.get_time(), status.mode, note)
            self.mode = status.mode
        if self.meshcat is not None and len(status.grasp_paths_W) > self.drawn_plans:
            draw_perception(self.meshcat, status)
            self.drawn_plans = len(status.grasp_paths_W)
        return context.get_time() if status.mode in ("done", "failed") else MAX_PICK_S

    def finish(self, outcome: PickOutcome) -> PickOutcome:
        """The outcome with the stages' times, the closure deviations and, if a stage failed, its name and reason."""
        status = self.status(outcome.context)
        outcome.stages = status.stage_seconds
        outcome.planning_s = status.stage_seconds.get("image_to_trajectory", 0.0)
        outcome.closure = status.closure
        if status.object_seen_W is not None and outcome.object_rest_W is not None:
            outcome.perception = pose_error(status.object_seen_W, outcome.object_rest_W)
        if status.mode == "failed":
            outcome.success = False
            outcome.failed_stage, outcome.message = status.failed_stage, status.message
        elif status.mode != "done":
            outcome.success = False
            outcome.message = f"stopped in mode {status.mode!r} after {MAX_PICK_S} s"
        return outcome
