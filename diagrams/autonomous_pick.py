"""The autonomous pick: camera -> Segmenter -> PoseEstimator -> ShapeRegistrar -> IK + STOMP -> trajectory.

Nothing here reads the simulator's ground truth: the object's pose, shape and grasps
come from the camera images at t = 0 through the perception systems, wired to the
station in one diagram and evaluated there; the plan is then played by the same
execution diagram as the oracle's (diagrams/pick_simulation.py), and the outcome is
judged on ground truth only afterwards.
"""

import logging
import time
from dataclasses import dataclass

import numpy as np
from pydrake.common.schema import Transform
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder

from diagrams.hand_ik import SIDES, DualArmIk
from diagrams.objects.instance import HandGrasp, ObjectInfo
from diagrams.oracle_pick import JointPlan, PlanningError, plan_oracle_pick
from diagrams.perception import AddPerception
from diagrams.pick_simulation import MakeOracleDiagram, simulate_pick
from diagrams.scenario import Scenario
from diagrams.station import MakeStation
from systems.shape_registrar import ShapeRegistrar


@dataclass
class Perceived:
    category: str
    X_WO: RigidTransform
    cloud_W: np.ndarray  # the reconstructed whole object
    grasps_W: dict[str, RigidTransform]
    seconds: float


def perceive(scenario: Scenario) -> Perceived:
    """Runs segmentation, pose estimation and shape registration on the station's first camera images.

    Raises:
        PlanningError: nothing found, or no grasps (with the stage's message).
    """
    builder = DiagramBuilder()
    station = builder.AddNamedSystem("station", MakeStation(scenario))
    _, pose_estimator = AddPerception(builder, station, scenario)
    registrar = builder.AddNamedSystem("shape_registrar", ShapeRegistrar())
    builder.Connect(pose_estimator.GetOutputPort("estimate"), registrar.GetInputPort("estimate"))
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    start = time.perf_counter()
    estimate = pose_estimator.GetOutputPort("estimate").Eval(pose_estimator.GetMyContextFromRoot(context))
    if not estimate.found:
        raise PlanningError(f"perception: {estimate.message}")
    registrar_context = registrar.GetMyContextFromRoot(context)
    grasps = registrar.GetOutputPort("grasp_poses").Eval(registrar_context)
    if not grasps.found:
        raise PlanningError(f"registration: {grasps.message}")
    X_WO = registrar.GetOutputPort("X_WO").Eval(registrar_context)
    cloud = registrar.GetOutputPort("reconstructed_cloud_W").Eval(registrar_context)
    seconds = time.perf_counter() - start
    logging.info("perceived a %s in %.2f s (%s)", estimate.category, seconds, grasps.message)
    return Perceived(estimate.category, X_WO, cloud, grasps.poses_W, seconds)


def plan_autonomous_pick(scenario: Scenario, perceived: Perceived) -> JointPlan:
    """The pick plan from perceived grasps; the object's reconstruction is the obstacle for reach planning."""
    ik = DualArmIk(scenario, obstacle_points_W=perceived.cloud_W)
    # The perceived grasps, as if of an object whose frame is the world's.
    grasps = {
        side: HandGrasp(
            Transform(perceived.grasps_W[f"{side}_pregrasp"]), Transform(perceived.grasps_W[f"{side}_grasp"])
        )
        for side in SIDES
    }
    return plan_oracle_pick(ik, np.array(scenario.initial_arm_positions), RigidTransform(), ObjectInfo(grasps=grasps))


def run_autonomous_pick(scenario: Scenario, meshcat=None, record=None):
    """Perceives, plans and simulates the pick; returns (PickOutcome, Perceived).

    Raises:
        PlanningError: perception, registration or planning failed (names the stage).
    """
    start = time.perf_counter()
    perceived = perceive(scenario)
    plan = plan_autonomous_pick(scenario, perceived)
    planning_s = time.perf_counter() - start
    logging.info("image to trajectory in %.2f s: %.1f s of motion", planning_s, plan.duration)
    outcome = simulate_pick(MakeOracleDiagram(scenario, plan, meshcat), scenario, plan.duration, meshcat, record)
    outcome.planning_s = planning_s
    return outcome, perceived
