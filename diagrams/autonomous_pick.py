"""The pick diagram: the design card's chain of stages around a station.

  station.camera0 -> perception (camera_latch -> segmenter -> pose_estimator -> [registration_yaw_noise] ->
  shape_registrar) -> stomp_planner -> trajectory_source -> station.centauro.position
  pick_supervisor: asks perception for a frame and reads its one result, asks stomp_planner for plans and
  hand_command for the hands.

MakePickDiagram wires it around the simulated station or the hardware one that talks LCM to a
robot driver (both expose the same ports). With perception="ground_truth", a ground-truth source
with perception's output ports (the object's true grasp frames and surface) stands where perception
was: the same planner, trajectory source and supervisor (the "oracle" pick). Nothing else reads the
simulator's ground truth: run_pick judges the outcome on it only afterwards.
"""

import gc
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.lcm import DrakeLcm, DrakeLcmInterface
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Diagram, DiagramBuilder

from diagrams.aim_board import board_placement
from diagrams.aim_judge import AimJudge
from diagrams.clear_judge import ClearJudge
from diagrams.generation.clutter_scenes import robot_at_start
from diagrams.generation.objects.library import resolve_object
from diagrams.generation.part_labels import on_handles, true_part_surface
from diagrams.hardware_station import MakeHardwareStation, image_stale_after_s
from diagrams.lifetime import release
from diagrams.perception import MakeGroundTruthPerception, MakeObjectTracker, MakePerception, latch_offset
from diagrams.pick_simulation import (
    PickOutcome,
    PlaceJudge,
    object_body,
    pose_error,
    simulate_pick,
    station_plant,
)
from diagrams.planning_scene import make_planning_world
from diagrams.pour_container import true_opening
from diagrams.pour_judge import PourJudge
from diagrams.robot_driver import MakeRobotDriver
from diagrams.scenario import ObjectConfig, Scenario, initial_positions
from diagrams.station import HAND_INSTANCES, OBJECT_INSTANCE, MakeStation, clear_home, drop_zone, place_target
from systems.messages import ClearedObject, GraspPoses, Mode, PickStatus
from systems.perception.camera_latch import CameraLatch
from systems.perception.grasp_offset import GraspOffset
from systems.perception.robot_spheres import RobotSpheres
from systems.pick_supervisor import PickSupervisor
from systems.pick_tasks import aim_pick, clear_pick, lift_pick, place_pick, pour_pick
from systems.pick_visualiser import PickVisualiser
from systems.planning.heap import return_freed_heap
from systems.planning.pick_motions import PickMotions, PlannerConfig, PlanningError
from systems.planning.plan_telemetry import PlanTelemetryRecorder
from systems.planning.stomp_config import StompConfig
from systems.planning.stomp_planner import StompPlanner
from systems.robot_io.hand_command import HandCommandSource
from systems.robot_io.hand_drop_fault import HandDropFault
from systems.robot_io.simulated_links import CameraGapFault, StatusGapFault
from systems.robot_io.trajectory_source import JointTrajectorySource
from systems.shape_space.tool_frame import ToolFrame

# Perceive once the object has settled on the table, s.
PERCEIVE_AT_S = 0.5
# A pick that has not ended by then is stopped, s (a pour: POUR_PICK_S; its held moves are more and longer).
MAX_PICK_S = 60.0
POUR_PICK_S = 90.0
# The hands close this much further along their approach axis z_G than the perceived grasp, m:
# registration is off by 1-2 cm, and the fingertips reach only 2.5 cm past the grasp frame, so a
# hand that stops short can close on the handle's edge and lose it in the lift (the paper's
# real-robot failure, §V-C: "the approaching pose ... should be closer to the object").
GRASP_DEPTH_MARGIN = 0.01
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
        meshcat: the simulated station draws itself there, and the pick_visualiser what perception saw and
            the planned grasp paths.
        hardware: build the LCM station (diagrams/hardware_station.py) instead of the simulation.
        lcm: the LCM bus of the hardware station (default: one on scenario.lcm.lcm_url).
        perception: "camera" (the autonomous chain) or "ground_truth" (the object's true grasp frames
            and surface, from the scenario: the oracle pick).

    Raises:
        PlanningError: ground truth asked for an object that has no grasp frames.
    """
    if perception not in PERCEPTION_SOURCES:
        raise ValueError(f"unknown perception {perception!r}: one of {PERCEPTION_SOURCES}")
    if scenario.faults.driver_restart_after_objects:
        raise ValueError(
            "faults.driver_restart_after_objects is done to a spawned robot driver's process: "
            "pick.py --backend lcm --spawn-driver, in a private network namespace (as root)"
        )
    if scenario.task == "aim" and scenario.object.category != "drill":
        raise ValueError(f"the aim task aims a drill's bit: the object must be a drill, not {scenario.object.category}")
    if scenario.task == "pour" and scenario.object.category != "watering_can":
        raise ValueError(f"the pour task pours from a can: the object must be a watering_can, not "
                         f"{scenario.object.category}")  # fmt: skip
    if scenario.task == "clear" and perception != "camera":
        raise ValueError("the clear task finds its objects one by one with the camera: no ground-truth perception")
    builder = DiagramBuilder()
    if hardware:
        station = builder.AddNamedSystem("station", MakeHardwareStation(scenario, lcm))
    else:
        station = builder.AddNamedSystem("station", MakeStation(scenario, meshcat))
    if hardware:  # the robot holds while the computer thinks: the plan starts once it exists
        time_limit_s, latency_s = scenario.planning.hardware_time_limit_s, 0.0
    else:  # simulated planning takes a fixed time, whatever the machine: iterations, not seconds, limit STOMP
        time_limit_s, latency_s = np.inf, scenario.planning.latency_s
    config = PlannerConfig(stomp=StompConfig(time_limit_s=time_limit_s, seed=scenario.random_seed))
    # The camera's pick knows the scenario's box as it knows everything on the table: as the camera sees it.
    motions = PickMotions(make_planning_world(scenario, known_box=perception != "camera"), config)
    n = motions.world.kinematics.dof  # the planned joints: the arms, and the torso if it is free
    margin = GRASP_DEPTH_MARGIN if perception == "camera" else 0.0
    planner = builder.AddNamedSystem("stomp_planner", StompPlanner(motions, latency_s, margin))
    source = builder.AddNamedSystem("trajectory_source", JointTrajectorySource(n, pause_at_last_status=hardware))
    hands = builder.AddNamedSystem("hand_command", HandCommandSource())
    from_camera = perception == "camera"
    held_looks = scenario.place.looks and scenario.task in ("place", "aim", "pour", "clear")
    looks = from_camera and (held_looks or scenario.look_before_approach)
    if scenario.task == "place":
        tasks = place_pick(check=scenario.look_before_approach, held_looks=scenario.place.looks)
        place_target_W = place_target(scenario)
    elif scenario.task == "aim":  # (set down again where it was taken)
        tasks, place_target_W = aim_pick(check=scenario.look_before_approach, held_looks=scenario.place.looks), None
    elif scenario.task == "pour":  # (set down again where it was taken)
        tasks, place_target_W = pour_pick(check=scenario.look_before_approach, held_looks=scenario.place.looks), None
    elif scenario.task == "clear":  # (each object to its spot in the drop zone)
        tasks, place_target_W = clear_pick(check=scenario.look_before_approach, held_looks=scenario.place.looks), None
    else:
        tasks, place_target_W = lift_pick(check=scenario.look_before_approach), None
    at_home = clear_home(scenario)
    clearing = {"drop_zone": drop_zone(scenario, robot_at_start(at_home)), "max_objects": scenario.clear.max_objects,
                "home_q": initial_positions(at_home)}  # fmt: skip
    supervisor = PickSupervisor(
        tasks,
        PERCEIVE_AT_S,
        place_target_W,
        from_camera,
        looks,
        scenario.max_attempts,
        num_joints=n,
        status_lost_s=scenario.hardware.status_lost_s,
        pour_tilt_rad=np.radians(scenario.pour.tilt_deg),
        **(clearing if scenario.task == "clear" else {}),
    )
    builder.AddNamedSystem("pick_supervisor", supervisor)
    telemetry = builder.AddNamedSystem("plan_telemetry", PlanTelemetryRecorder())
    measured, status_health = _RobotStatus(builder, station, scenario, supervisor, n, hardware)
    camera = _CameraImages(builder, station, scenario, hardware)

    if from_camera:
        robot_at_frame = RobotSpheres(motions.world.kinematics, motions.world.spheres)
        seen = builder.AddNamedSystem(
            "perception", MakePerception(scenario, None, robot_at_frame, motions.world.torso_axis_W)
        )
        _ConnectCamera(builder, camera, seen, supervisor.GetOutputPort("trigger"))
        builder.Connect(measured, seen.GetInputPort("robot_position"))
        if looks:
            robot_spheres = RobotSpheres(motions.world.kinematics, motions.world.spheres)
            _AddLooks(builder, camera, measured, supervisor, seen, scenario, robot_spheres)
    else:
        try:
            seen = builder.AddNamedSystem("ground_truth", MakeGroundTruthPerception(scenario))
        except ValueError as error:
            raise PlanningError(str(error)) from error
    builder.Connect(seen.GetOutputPort("frame_id"), supervisor.GetInputPort("frame_id"))
    builder.Connect(seen.GetOutputPort("result"), supervisor.GetInputPort("perception"))
    if scenario.task == "aim":
        builder.Connect(seen.GetOutputPort("board"), supervisor.GetInputPort("board"))
    if scenario.task == "pour":
        builder.Connect(seen.GetOutputPort("container"), supervisor.GetInputPort("container"))
    if scenario.task == "clear":
        builder.Connect(supervisor.GetOutputPort("left_out"), seen.GetInputPort("left_out"))
    grasps = seen.GetOutputPort("grasp_poses")
    if any(scenario.faults.grasp_offset_G):
        if hardware:
            raise ValueError("faults are injected in simulation only: faults.grasp_offset_G must be zero on hardware")
        faults = scenario.faults
        offset = GraspOffset(faults.grasp_offset_G, faults.grasp_offset_attempts, faults.grasp_offset_object)
        fault = builder.AddNamedSystem("grasp_offset_fault", offset)
        builder.Connect(grasps, fault.GetInputPort("grasp_poses"))
        builder.Connect(supervisor.GetOutputPort("status"), fault.GetInputPort("status"))
        grasps = fault.GetOutputPort("grasp_poses")
    builder.Connect(grasps, planner.GetInputPort("grasp_poses"))
    builder.Connect(seen.GetOutputPort("reconstructed_cloud_W"), planner.GetInputPort("obstacle_cloud_W"))
    builder.Connect(seen.GetOutputPort("scene_cloud_W"), planner.GetInputPort("scene_cloud_W"))
    builder.Connect(supervisor.GetOutputPort("plan_request"), planner.GetInputPort("request"))
    plan = planner.GetOutputPort("plan")
    for system in (source, supervisor, telemetry):
        builder.Connect(plan, system.GetInputPort("plan"))
    builder.Connect(measured, source.GetInputPort("position_measured"))
    builder.Connect(status_health, source.GetInputPort("status_health"))
    builder.Connect(source.GetOutputPort("playback"), supervisor.GetInputPort("playback"))
    builder.Connect(supervisor.GetOutputPort("stop"), source.GetInputPort("stop"))
    builder.Connect(measured, supervisor.GetInputPort("position_measured"))
    builder.Connect(source.GetOutputPort("position"), station.GetInputPort("centauro.position"))
    builder.Connect(supervisor.GetOutputPort("hand_command"), hands.GetInputPort("command"))
    width = hands.GetOutputPort("width")
    if scenario.faults.drop_in_carry_after_s >= 0:
        if hardware:
            raise ValueError("faults are injected in simulation only: faults.drop_in_carry_after_s must be negative")
        drop = builder.AddNamedSystem("hand_drop_fault", HandDropFault(scenario.faults.drop_in_carry_after_s))
        builder.Connect(width, drop.GetInputPort("width"))
        builder.Connect(supervisor.GetOutputPort("status"), drop.GetInputPort("status"))
        width = drop.GetOutputPort("width")
    for side, hand in HAND_INSTANCES.items():
        builder.Connect(width, station.GetInputPort(f"{hand}.position"))
        builder.Connect(station.GetOutputPort(f"{hand}.state_measured"), supervisor.GetInputPort(f"{side}_hand_state"))
    if meshcat is not None:
        visualiser = builder.AddNamedSystem("pick_visualiser", PickVisualiser(meshcat))
        builder.Connect(supervisor.GetOutputPort("status"), visualiser.GetInputPort("status"))
        builder.Connect(seen.GetOutputPort("result"), visualiser.GetInputPort("perception"))
        builder.Connect(plan, visualiser.GetInputPort("plan"))
    diagram = builder.Build()
    diagram.set_name("pick")
    return diagram


def _RobotStatus(builder, station, scenario, supervisor, num_joints: int, hardware: bool):
    """The robot's measured joints and its status link's health: the station's, or with faults.status_gap_s, through
    a StatusGapFault (simulation; a spawned driver's is done to its process: diagrams/lcm_pick.py)."""
    measured, health = (
        station.GetOutputPort("centauro.position_measured"),
        station.GetOutputPort("centauro.status_health"),
    )
    faults = scenario.faults
    if faults.status_gap_in_carry_after_s < 0:
        return measured, health
    if hardware:
        raise ValueError(
            "faults.status_gap_in_carry_after_s must be negative against a robot: it is injected in simulation, or "
            "on a spawned driver (pick.py --spawn-driver freezes the driver's process)"
        )
    gap = StatusGapFault(
        faults.status_gap_in_carry_after_s, faults.status_gap_s, scenario.hardware.watchdog_s, num_joints
    )
    fault = builder.AddNamedSystem("status_gap_fault", gap)
    builder.Connect(measured, fault.GetInputPort("position_measured"))
    builder.Connect(supervisor.GetOutputPort("status"), fault.GetInputPort("status"))
    return fault.GetOutputPort("position_measured"), fault.GetOutputPort("health")


def _CameraImages(builder, station, scenario, hardware: bool) -> dict:
    """The scenario camera's outputs by the latch's input names: the station's, or with faults.camera_gap_at_s,
    through a CameraGapFault (simulation only)."""
    name = scenario.camera.name
    ports = {
        latched: station.GetOutputPort(f"{name}.{output}")
        for latched, output in (
            ("color_image", "rgb_image"),
            ("depth_image", "depth_image"),
            ("camera_pose", "pose"),
            ("image_health", "image_health"),
        )
    }
    faults = scenario.faults
    if faults.camera_gap_at_s < 0:
        return ports
    if hardware:
        raise ValueError("faults are injected in simulation only: faults.camera_gap_at_s must be negative")
    gap = CameraGapFault(faults.camera_gap_at_s, faults.camera_gap_s, image_stale_after_s(scenario.hardware))
    fault = builder.AddNamedSystem("camera_gap_fault", gap)
    for image in ("color_image", "depth_image"):
        builder.Connect(ports[image], fault.GetInputPort(image))
        ports[image] = fault.GetOutputPort(image)
    ports["image_health"] = fault.GetOutputPort("health")
    return ports


def _ConnectCamera(builder, camera: dict, latched, trigger):
    """The camera (_CameraImages) and a trigger into a system that latches its frames (perception, a look latch)."""
    for port, output in camera.items():
        builder.Connect(output, latched.GetInputPort(port))
    builder.Connect(trigger, latched.GetInputPort("trigger"))


def _AddLooks(builder, camera, measured, supervisor, perception, scenario, robot_spheres):
    """The supervisor's looks at the held object: look_latch (the frame and the arms' joints then) ->
    robot_spheres -> object_tracker, which fits perception's reconstruction (seen at its X_WO) near the
    supervisor's expected_X_WO."""
    latch = CameraLatch(robot_positions=robot_spheres.kinematics.dof, offset_s=latch_offset(scenario, look=True))
    look = builder.AddNamedSystem("look_latch", latch)
    _ConnectCamera(builder, camera, look, supervisor.GetOutputPort("look_trigger"))
    builder.Connect(look.GetOutputPort("frame_id"), supervisor.GetInputPort("look_frame_id"))
    builder.Connect(measured, look.GetInputPort("robot_position"))
    robot = builder.AddNamedSystem("robot_spheres", robot_spheres)
    builder.Connect(look.GetOutputPort("robot_position"), robot.GetInputPort("position"))
    tracker = builder.AddNamedSystem("object_tracker", MakeObjectTracker(scenario))
    for port, source in (
        ("depth_image", look.GetOutputPort("depth_image")),
        ("camera_pose", look.GetOutputPort("camera_pose")),
        ("robot_spheres_W", robot.GetOutputPort("spheres_W")),
        ("expected_X_WO", supervisor.GetOutputPort("expected_X_WO")),
        ("model_cloud_W", perception.GetOutputPort("reconstructed_cloud_W")),
        ("model_X_WO", perception.GetOutputPort("X_WO")),
    ):
        builder.Connect(source, tracker.GetInputPort(port))
    builder.Connect(tracker.GetOutputPort("estimate"), supervisor.GetInputPort("look"))


def _subsystem_output(diagram: Diagram, context, system: str, port: str):
    """The value of `port` of the pick diagram's subsystem named `system`."""
    subsystem = diagram.GetSubsystemByName(system)
    return subsystem.GetOutputPort(port).Eval(subsystem.GetMyContextFromRoot(context))


def pick_status(diagram: Diagram, context) -> PickStatus:
    return _subsystem_output(diagram, context, "pick_supervisor", "status")


@dataclass
class PickReport:
    """What the pick diagram tells of a pick once it has ended (no ground truth): the supervisor's final
    status, each stage's wall seconds ("segmentation", "pose", "registration", "planning": the first plan;
    "image_to_trajectory": from the latch of the frame perceived to the first trajectory planned after it,
    the simulator's work between included (a pick that failed first: to the plan or the perception result that
    failed; with ground truth, no image: the first plan's seconds); "planning_total": every plan; "look": the
    last look at the held object) and the held moves' largest closure deviations; the category perception took and,
    where the user named it, what the segmenter's network made of the object ("" where it did not perceive)."""

    status: PickStatus
    stages: dict[str, float]
    closure: dict[str, float]
    category: str = ""
    network_category: str = ""
    grasps: GraspPoses | None = None  # the grasps perceived in the attempt's frame (None where it did not perceive)
    status_held_s: float = 0.0  # how long the trajectory source held while the robot's status was stale, s


def pick_report(diagram: Diagram, context) -> PickReport:
    status = pick_status(diagram, context)
    stages, category, network_category, result, grasps = {}, "", "", None, None
    if status.perceived:  # (perception's result is cached: reading it again computes nothing)
        supervisor = diagram.GetSubsystemByName("pick_supervisor")
        result = supervisor.GetInputPort("perception").Eval(supervisor.GetMyContextFromRoot(context))
        stages.update(result.stage_seconds)
        category, network_category = result.category, result.network_category
        grasps = result.grasps
    plans = _subsystem_output(diagram, context, "plan_telemetry", "telemetry")
    if plans.plans:
        stages["planning"] = plans.first_planning_s
        stages["image_to_trajectory"] = plans.first_planning_s
        stages["planning_total"] = plans.planning_total_s
    if result is not None and math.isfinite(result.latched_wall_s):
        latency = plans.latency_after(result.latched_wall_s)
        stages["image_to_trajectory"] = (
            latency if math.isfinite(latency) else (result.finished_wall_s - result.latched_wall_s)
        )
    if status.looks_read:  # (the tracker's last estimate is cached: its inputs change only with a new look)
        stages["look"] = _subsystem_output(diagram, context, "object_tracker", "estimate").compute_s
    held_s = _subsystem_output(diagram, context, "trajectory_source", "playback").paused_total_s
    return PickReport(status, stages, plans.closure, category, network_category, grasps, held_s)


def attempt_failures(status: PickStatus) -> list[dict[str, str]]:
    """Each failed attempt's {"stage", "message"}, in order (the last is the pick's if it failed)."""
    return [{"stage": stage, "message": message} for stage, message in status.attempt_failures]


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
    """Simulates the pick until it is done (or a stage failed), then judges it on ground truth. Its diagram is freed
    before it returns, and the heap it held given back to the system (a process runs many picks: evaluate.py's
    workers, the endurance benchmark); the outcome has no context.

    Args:
        backend: "sim" (the simulated station) or "lcm-memq" (the hardware station against the
            robot driver emulator over an in-process LCM bus).
        perception: "camera" (autonomous) or "ground_truth" (the oracle pick).
    """
    outcome = _simulated_pick(scenario, meshcat, record, backend, perception)
    gc.collect()
    return_freed_heap()
    return outcome


def _simulated_pick(
    scenario: Scenario, meshcat: Meshcat | None, record: Path | None, backend: str, perception: str
) -> PickOutcome:
    """run_pick's pick, its diagram released (diagrams/lifetime.py)."""
    if backend == "sim":
        diagram = pick = MakePickDiagram(scenario, meshcat, perception=perception)
        plant = station_plant(diagram)
    elif backend == "lcm-memq":
        diagram = MakeLcmPickWorld(scenario, DrakeLcm("memq://"), meshcat)
        pick = diagram.GetSubsystemByName("pick")
        plant = station_plant(diagram.GetSubsystemByName("robot_driver"))
    else:
        raise ValueError(f"unknown backend {backend!r}: sim or lcm-memq")
    judged = scenario.object if scenario.object.present else None
    watch = PickWatcher(pick, true_grasps_O(scenario), judged, true_tool_O(scenario), max_time_s(scenario), plant)

    def mode_of(context):
        return watch.status(context).mode

    make_judge = None
    if scenario.task == "place":

        def make_judge(plant, context):
            return PlaceJudge(plant, context, place_target(scenario), mode_of)

    elif scenario.task == "clear":

        def make_judge(plant, context):
            return ClearJudge(plant, context, scenario, drop_zone(scenario), mode_of)

    elif scenario.task == "aim":
        tool_O = true_tool_O(scenario)
        if tool_O is None:
            raise ValueError("the aim task is judged on the drill's true tool frame: its model has none")

        def make_judge(plant, context):
            return AimJudge(plant, context, mode_of, board_placement(scenario), tool_O)

    elif scenario.task == "pour":
        tool_O = true_tool_O(scenario)
        if tool_O is None:
            raise ValueError("the pour task is judged on the can's true tool frame: its model has none")

        def make_judge(plant, context):
            return PourJudge(
                plant, context, mode_of, true_opening(scenario), tool_O, np.radians(scenario.pour.tilt_deg)
            )

    outcome = simulate_pick(
        diagram, scenario, watch.end_time, meshcat, record, plant=plant, make_judge=make_judge, mode_of=mode_of
    )
    outcome = watch.finish(outcome)
    outcome.context = None  # (nothing of the diagram may be touched once it is released)
    release(diagram)
    return outcome


def max_time_s(scenario: Scenario) -> float:
    """The simulated time a pick may take (a clear: MAX_PICK_S per object it may take on, and one more; a pour:
    POUR_PICK_S), s."""
    if scenario.task == "clear":
        return MAX_PICK_S * (scenario.clear.max_objects + 1)
    return POUR_PICK_S if scenario.task == "pour" else MAX_PICK_S


def taken_on(done: ClearedObject) -> dict:
    """A clear's record of one object it took on, for the outcome JSON."""
    record = {"category": done.category, "seen_xy_W": list(done.seen_xy_W), "attempts": done.attempts,
              "cleared": done.cleared, "target_xy_W": list(done.target_xy_W) if done.target_xy_W else None}  # fmt: skip
    if not done.cleared:
        record.update(failed_stage=done.failed_stage, message=done.message)
    if done.later_pass:
        record["later_pass"] = True
    return record


def true_grasps_O(scenario: Scenario) -> dict[str, RigidTransform] | None:
    """The scenario's object's true control poses in O (POSE_NAMES -> X_OG), for judging; None where its model has
    none (a user's mesh without an info.yaml beside it)."""
    if not scenario.object.present:
        return None
    model = resolve_object(scenario.object)
    return None if model.info is None else model.info.control_poses()


def true_tool_O(scenario: Scenario) -> ToolFrame | None:
    """The scenario's object's true tool frame in O, for judging; None where its model has none."""
    if not scenario.object.present:
        return None
    model = resolve_object(scenario.object)
    return None if model.info is None else model.info.tool_frame()


def grasp_errors(poses_W: dict, X_WO: RigidTransform, true_O: dict) -> dict[str, float]:
    """How far each perceived grasp frame's origin lies from the true one on the object at rest, m."""
    hands = ("left", "right")
    return {
        h: float(np.linalg.norm(poses_W[f"{h}_grasp"].translation() - (X_WO @ true_O[f"{h}_grasp"]).translation()))
        for h in hands
    }


class PickWatcher:
    """Follows the PickSupervisor during a simulation: logs mode changes and says when the pick has ended."""

    def __init__(
        self,
        pick: Diagram,
        true_grasps_O: dict[str, RigidTransform] | None = None,
        judged_object: ObjectConfig | None = None,
        true_tool_O: ToolFrame | None = None,
        max_time_s: float = MAX_PICK_S,
        plant: MultibodyPlant | None = None,
    ):
        """true_grasps_O: the object's true control poses in O, where known: the perceived grasps are judged on them
        (the outcome's perception["grasp_errors_m"]); judged_object: the object, whose true parts (where known) say
        whether each grasp lay on its own handle (perception["grasps_on_handles"]; read only once grasps exist);
        true_tool_O: its true tool frame in O, where known: the perceived one is judged on it
        (perception["tool_errors"]); max_time_s: the simulated time the pick may take, s; plant: the simulated
        robot's plant (in the root context), where the object's true pose is read when perception gives the pick
        its belief: the perceived pose and grasps are judged on where the object stood then, not where it first
        settled (an earlier attempt may have moved it). Without it, they are judged on where it first settled."""
        self.pick, self.mode, self.max_time_s = pick, "", max_time_s
        self.true_grasps_O, self.judged_object, self.true_tool_O = true_grasps_O, judged_object, true_tool_O
        self.plant = plant if plant is not None and plant.HasModelInstanceNamed(OBJECT_INSTANCE) else None
        self.seen_W, self.X_WO_when_seen = None, None  # the belief's perceived pose (3 x 4), and the true one then

    def status(self, context) -> PickStatus:
        return pick_status(self.pick, context)

    def end_time(self, context) -> float:
        """When to stop, in context seconds: now if the pick is done or failed, else max_time_s."""
        status = self.status(context)
        seen_W = None if status.belief is None else status.belief.seen_W.GetAsMatrix34()
        if self.plant is not None and seen_W is not None and not np.array_equal(seen_W, self.seen_W):
            self.seen_W = seen_W
            self.X_WO_when_seen = object_body(self.plant).EvalPoseInWorld(self.plant.GetMyContextFromRoot(context))
        if status.mode != self.mode:
            note = f": {status.message}" if status.mode == Mode.FAILED else ""
            logging.info("t = %5.2f s  %s%s", context.get_time(), status.mode, note)
            self.mode = status.mode
        return context.get_time() if status.mode in (Mode.DONE, Mode.FAILED) else self.max_time_s

    def finish(self, outcome: PickOutcome) -> PickOutcome:
        """The outcome with the stages' times, the closure deviations and, if a stage failed, its name and reason."""
        report = pick_report(self.pick, outcome.context)
        status = report.status
        outcome.stages = report.stages
        outcome.planning_s = report.stages.get("image_to_trajectory", 0.0)
        outcome.closure = report.closure
        outcome.waits = {"status_held_s": report.status_held_s, "frames_waited_s": status.frames_waited_s}
        X_WO_true = self.X_WO_when_seen if self.X_WO_when_seen is not None else outcome.object_rest_W  # when seen
        if status.belief is not None and X_WO_true is not None:
            outcome.perception = pose_error(status.belief.seen_W, X_WO_true)
        if report.category:
            outcome.perception["category"] = report.category
        if report.network_category:
            outcome.perception["network_category"] = report.network_category
        if report.grasps is not None:
            outcome.perception["grasps"] = report.grasps.message
            if report.grasps.found and self.true_grasps_O and X_WO_true is not None:
                outcome.perception["grasp_errors_m"] = grasp_errors(
                    report.grasps.poses_W, X_WO_true, self.true_grasps_O
                )
            tool = report.grasps.tool_W
            if tool is not None and self.true_tool_O is not None and X_WO_true is not None:
                tip, axis = tool.errors(self.true_tool_O.moved(X_WO_true))
                outcome.perception["tool_errors"] = {"tip_m": tip, "axis_rad": axis}
            truth = None
            if report.grasps.found and self.judged_object is not None and X_WO_true is not None:
                truth = true_part_surface(self.judged_object)
            if truth is not None:
                X_OW = X_WO_true.inverse()
                grasps_O = {h: (X_OW @ report.grasps.poses_W[f"{h}_grasp"]).translation() for h in ("left", "right")}
                outcome.perception["grasps_on_handles"] = on_handles(truth, grasps_O)
        outcome.attempts_made, outcome.attempt_failures = status.attempt, attempt_failures(status)
        if outcome.clear:  # a clear (judged so): what the robot made of each object it took on
            outcome.clear["taken_on"] = [taken_on(done) for done in status.objects]
            outcome.clear["summary"] = status.message
        if outcome.place:
            outcome.place["corrections"] = status.place_corrections  # in the last attempt: set down again
        if status.mode == Mode.FAILED:
            outcome.success = False
            outcome.failed_stage, outcome.message = status.failed_stage, status.message
        elif status.mode != Mode.DONE:
            outcome.success = False
            outcome.message = (
                f"stopped in mode {str(status.mode)!r} of attempt {status.attempt}: the pick's {self.max_time_s} s of "
                "simulated time ran out"
            )
        return outcome
