"""The autonomous pick diagram: camera -> Segmenter -> PoseEstimator -> ShapeRegistrar -> PickSequencer -> arms.

MakePickDiagram wires the perception systems and the PickSequencer (which plans with
IK + STOMP on the perceived grasps, the reconstruction as the obstacle, and plays the
plan) around a station: the simulated one, or the hardware one that talks LCM to a
robot driver; both expose the same ports. Nothing here reads the simulator's ground
truth: run_pick judges the outcome on it only afterwards.
"""

import logging
from pathlib import Path

import numpy as np
from pydrake.common.schema import Transform
from pydrake.geometry import Meshcat, Rgba
from pydrake.lcm import DrakeLcm, DrakeLcmInterface
from pydrake.math import RigidTransform
from pydrake.systems.framework import Diagram, DiagramBuilder

from diagrams.hand_ik import SIDES, DualArmIk
from diagrams.hardware_station import MakeHardwareStation
from diagrams.objects.instance import HandGrasp, ObjectInfo
from diagrams.oracle_pick import OPEN_WIDTH, plan_oracle_pick
from diagrams.perception import AddPerception
from diagrams.pick_simulation import PickOutcome, simulate_pick, station_plant
from diagrams.robot_driver import MakeRobotDriver
from diagrams.scenario import Scenario
from diagrams.station import HAND_INSTANCES, MakeStation
from systems.joint_plan import JointPlan
from systems.pick_sequencer import PickSequencer, PickStatus
from systems.pose_estimator import to_point_cloud
from systems.pose_noise import PoseYawOffset, draw_yaw_offset
from systems.shape_registrar import GraspPoses, ShapeRegistrar

# Perceive once the object has settled on the table, s.
PERCEIVE_AT_S = 0.5
# A pick that has not ended by then is stopped, s.
MAX_PICK_S = 60.0
# The hands close this much further along their approach axis z_G than the perceived grasp, m:
# registration is off by 1-2 cm, and the fingertips reach only 2.5 cm past the grasp frame, so a
# hand that stops short can close on the handle's edge and lose it in the lift (the paper's
# real-robot failure, §V-C: "the approaching pose ... should be closer to the object").
GRASP_DEPTH_MARGIN = 0.01
DEEPER = RigidTransform([0.0, 0.0, GRASP_DEPTH_MARGIN])
# The reconstruction, thinned to about this many points, is the reach's obstacle: the margin about it
# (hand_ik.PERCEIVED_SHAPE_MARGIN) was set for a cloud this dense, and planning cost grows with it.
OBSTACLE_POINTS = 2000


def make_pick_planner(scenario: Scenario):
    """plan_pick(grasps, cloud_W, q_now) -> JointPlan for the PickSequencer.

    IK on the perceived grasps (as if of an object whose frame is the world's), STOMP for
    the reach around the reconstructed cloud, straight approach, close, closed-chain lift.
    The robot model (and its IK seed table) is built here, once.
    Raises PlanningError (a RuntimeError) naming the phase that failed.
    """

    ik = DualArmIk(scenario)  # the robot model and its IK seed table: built once, not per image

    def plan_pick(grasps: GraspPoses, cloud_W: np.ndarray, q_now: np.ndarray) -> JointPlan:
        ik.set_obstacle_points(cloud_W[:: max(1, len(cloud_W) // OBSTACLE_POINTS)] if len(cloud_W) else None)
        poses = {name: Transform(X_WG) for name, X_WG in grasps.poses_W.items()}
        for side in SIDES:
            poses[f"{side}_grasp"] = Transform(grasps.poses_W[f"{side}_grasp"] @ DEEPER)
        info = ObjectInfo(grasps={side: HandGrasp(poses[f"{side}_pregrasp"], poses[f"{side}_grasp"]) for side in SIDES})
        plan = plan_oracle_pick(ik, q_now, RigidTransform(), info)
        plan.grasp_paths_W = _grasp_paths(ik, plan)
        return plan

    return plan_pick


def _grasp_paths(ik: DualArmIk, plan: JointPlan, samples: int = 120) -> dict[str, np.ndarray]:
    """Each hand's grasp frame origin along the plan, samples x 3 in W (for the viewer)."""
    trajectory = plan.arm_trajectory()
    q = np.column_stack([trajectory.value(t) for t in np.linspace(0, plan.duration, samples)]).T
    return {side: X[:, :3, 3] for side, X in zip(SIDES, ik.stomp.end_effectors.poses(q), strict=True)}


def MakePickDiagram(
    scenario: Scenario, meshcat: Meshcat | None = None, hardware: bool = False, lcm: DrakeLcmInterface | None = None
) -> Diagram:
    """The whole autonomous pick around the simulated station, or with `hardware`, the LCM one.

    Args:
        scenario: the run's configuration.
        meshcat: the simulated station draws itself there.
        hardware: build the LCM station (diagrams/hardware_station.py) instead of the simulation.
        lcm: the LCM bus of the hardware station (default: one on scenario.lcm.lcm_url).
    """
    builder = DiagramBuilder()
    if hardware:
        station = builder.AddNamedSystem("station", MakeHardwareStation(scenario, lcm))
    else:
        station = builder.AddNamedSystem("station", MakeStation(scenario, meshcat))
    segmenter, pose_estimator = AddPerception(builder, station, scenario)
    registrar = builder.AddNamedSystem("shape_registrar", ShapeRegistrar())
    estimate_to_register = pose_estimator.GetOutputPort("estimate")
    if scenario.registration_yaw_noise > 0:
        offset = draw_yaw_offset(scenario.registration_yaw_noise, scenario.random_seed)
        noise = builder.AddNamedSystem("registration_yaw_noise", PoseYawOffset(offset))
        builder.Connect(estimate_to_register, noise.get_input_port())
        estimate_to_register = noise.get_output_port()
    sequencer = builder.AddNamedSystem(
        "pick_sequencer", PickSequencer(make_pick_planner(scenario), OPEN_WIDTH, PERCEIVE_AT_S)
    )
    camera = scenario.camera.name
    builder.Connect(estimate_to_register, registrar.GetInputPort("estimate"))
    for port, source in (
        ("color_image", station.GetOutputPort(f"{camera}.rgb_image")),
        ("depth_image", station.GetOutputPort(f"{camera}.depth_image")),
        ("segmentation", segmenter.GetOutputPort("segmentation")),
        ("estimate", pose_estimator.GetOutputPort("estimate")),
        ("grasp_poses", registrar.GetOutputPort("grasp_poses")),
        ("reconstructed_cloud_W", registrar.GetOutputPort("reconstructed_cloud_W")),
        ("position_measured", station.GetOutputPort("centauro.position_measured")),
    ):
        builder.Connect(source, sequencer.GetInputPort(port))
    builder.Connect(sequencer.GetOutputPort("arm_position"), station.GetInputPort("centauro.position"))
    for hand in HAND_INSTANCES.values():
        builder.Connect(sequencer.GetOutputPort("hand_width"), station.GetInputPort(f"{hand}.position"))
    diagram = builder.Build()
    diagram.set_name("autonomous_pick")
    return diagram


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
        meshcat.SetObject(path, to_point_cloud(points_W), point_size=0.006, rgba=rgba)
    for side, path_W in status.plan.grasp_paths_W.items():
        meshcat.SetLine(f"perception/grasp_path_{side}", path_W.T, 3.0, Rgba(0.1, 0.8, 0.2, 1.0))


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
    scenario: Scenario, meshcat: Meshcat | None = None, record: Path | None = None, backend: str = "sim"
) -> PickOutcome:
    """Simulates the autonomous pick until the plan has been played (or a stage failed); judged on ground truth.

    Args:
        backend: "sim" (the simulated station) or "lcm-memq" (the hardware station against the
            robot driver emulator over an in-process LCM bus).
    """
    if backend == "sim":
        diagram = pick = MakePickDiagram(scenario, meshcat)
        plant = station_plant(diagram)
    elif backend == "lcm-memq":
        diagram = MakeLcmPickWorld(scenario, DrakeLcm("memq://"), meshcat)
        pick = diagram.GetSubsystemByName("pick")
        plant = station_plant(diagram.GetSubsystemByName("robot_driver"))
    else:
        raise ValueError(f"unknown backend {backend!r}: sim or lcm-memq")
    watch = PickWatcher(pick, meshcat)
    outcome = simulate_pick(diagram, scenario, watch.end_time, meshcat, record, plant=plant)
    return watch.finish(outcome)


class PickWatcher:
    """Follows the PickSequencer during a simulation: logs mode changes, draws the perception once,
    and says when the pick has ended."""

    def __init__(self, pick: Diagram, meshcat: Meshcat | None = None):
        self.pick, self.meshcat = pick, meshcat
        self.mode, self.drawn = "", False

    def status(self, context) -> PickStatus:
        return pick_status(self.pick, context)

    def end_time(self, context) -> float:
        """When to stop, in context seconds: the plan's end, now if a stage failed, MAX_PICK_S at most."""
        status = self.status(context)
        if status.mode != self.mode:
            note = f": {status.message}" if status.mode == "failed" else ""
            logging.info("t = %5.2f s  %s%s", context.get_time(), status.mode, note)
            self.mode = status.mode
        if self.meshcat is not None and status.plan is not None and not self.drawn:
            draw_perception(self.meshcat, status)
            self.drawn = True
        return context.get_time() if status.mode == "failed" else min(status.end_s, MAX_PICK_S)

    def finish(self, outcome: PickOutcome) -> PickOutcome:
        """The outcome with the stages' times and, if one failed, its name and reason."""
        status = self.status(outcome.context)
        outcome.stages = status.stage_seconds
        outcome.planning_s = status.stage_seconds.get("image_to_trajectory", 0.0)
        if status.mode == "failed":
            outcome.failed_stage, outcome.message = status.failed_stage, status.message
        elif status.mode not in ("hold", "done"):  # (the last sample may fall just before the plan's end)
            outcome.success = False
            outcome.message = f"stopped in mode {status.mode!r} after {MAX_PICK_S} s"
        return outcome
