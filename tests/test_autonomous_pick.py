"""The pick sequencer and the shape registrar alone, and the autonomous pick diagram end to end
(no ground truth until judging), including its failure paths."""

import numpy as np
import pytest
import trimesh
from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat, MeshcatParams
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator

from diagrams.autonomous_pick import (
    GRASP_DEPTH_MARGIN,
    PERCEIVE_AT_S,
    MakePickDiagram,
    draw_perception,
    make_pick_planner,
    run_pick,
)
from diagrams.hand_ik import DualArmIk
from diagrams.objects.library import resolve_object
from diagrams.scenario import replace_object
from diagrams.station import object_pose_on_table
from systems.joint_plan import JointPlan
from systems.pick_sequencer import PickSequencer, PickStatus
from systems.pose_estimator import ObjectEstimate
from systems.segmenter import Segmentation
from systems.shape_registrar import GraspPoses, ShapeRegistrar
from systems.shape_space.space import POSE_NAMES

Q0 = np.linspace(-0.5, 0.5, 14)


def test_shape_registrar_system_alone(scenario):
    registrar = ShapeRegistrar()
    context = registrar.CreateDefaultContext()
    X_WO = RigidTransform([0.73, 0.0, 0.76])
    space = registrar.registrars["drill"].space
    observed = X_WO.multiply(space.reconstruct(np.zeros(space.latent_size)).T).T[::3]
    registrar.GetInputPort("estimate").FixValue(
        context, AbstractValue.Make(ObjectEstimate(True, "drill", X_WO, observed))
    )
    grasps = registrar.GetOutputPort("grasp_poses").Eval(context)
    assert grasps.found and set(grasps.poses_W) == set(POSE_NAMES)
    refined = registrar.GetOutputPort("X_WO").Eval(context)
    assert np.linalg.norm(refined.translation() - X_WO.translation()) < 0.01
    assert len(registrar.GetOutputPort("reconstructed_cloud_W").Eval(context)) > 1000

    registrar.GetInputPort("estimate").FixValue(context, AbstractValue.Make(ObjectEstimate(False, message="empty")))
    nothing = registrar.GetOutputPort("grasp_poses").Eval(context)
    assert not nothing.found and "nothing to register" in nothing.message
    assert len(registrar.GetOutputPort("reconstructed_cloud_W").Eval(context)) == 0


def _two_step_plan(grasps, cloud, q_now):
    plan = JointPlan()
    plan.append(q_now, 0.1, 0.0)
    plan.append(q_now + 0.2, 0.1, 1.0)
    plan.phases["reach"] = plan.duration
    plan.append(q_now + 0.2, 0.0, 1.0)
    plan.phases["close"] = plan.duration
    return plan


def _sequencer_context(dut, segmentation_found=True, grasps_found=True):
    context = dut.CreateDefaultContext()
    dut.GetInputPort("position_measured").FixValue(context, Q0)
    mask = np.ones((4, 4), bool)
    for port, value in (
        ("segmentation", Segmentation(segmentation_found, "drill", mask, 16, "ok" if segmentation_found else "none")),
        ("estimate", ObjectEstimate(True, "drill", points_W=np.ones((7, 3)))),
        ("grasp_poses", GraspPoses(grasps_found, {}, "ok" if grasps_found else "diverged")),
        ("reconstructed_cloud_W", np.zeros((0, 3))),
    ):
        dut.GetInputPort(port).FixValue(context, AbstractValue.Make(value))
    for port in ("color_image", "depth_image"):
        dut.GetInputPort(port).FixValue(context, dut.GetInputPort(port).Allocate())
    return context


def _advance(dut, context, t):
    simulator = Simulator(dut, context)
    simulator.AdvanceTo(t)
    return context


def test_sequencer_holds_then_plays_the_plan_after_perceiving():
    dut = PickSequencer(_two_step_plan, hand_width=0.1, perceive_at_s=0.5)
    context = _sequencer_context(dut)
    np.testing.assert_array_equal(dut.GetOutputPort("arm_position").Eval(context), Q0)  # before any update
    _advance(dut, context, 0.3)
    assert dut.GetOutputPort("status").Eval(context).mode == "waiting"
    np.testing.assert_array_equal(dut.GetOutputPort("arm_position").Eval(context), Q0)
    _advance(dut, context, 0.6)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.plan is not None and status.plan_start_s >= 0.5
    assert set(status.stage_seconds) >= {"segmentation", "pose", "registration", "planning", "image_to_trajectory"}
    assert status.seen_points_W.shape == (7, 3) and status.reconstruction_W.shape == (0, 3)
    _advance(dut, context, status.plan_start_s + 1.5)
    assert dut.GetOutputPort("status").Eval(context).mode == "close"
    np.testing.assert_allclose(dut.GetOutputPort("arm_position").Eval(context), Q0 + 0.2)
    assert dut.GetOutputPort("hand_width").Eval(context)[0] == pytest.approx(0.05)
    _advance(dut, context, status.plan_start_s + 3.0)
    assert dut.GetOutputPort("status").Eval(context).mode == "done"


@pytest.mark.parametrize(
    ("segmentation_found", "grasps_found", "planner_fails", "stage"),
    [(False, True, False, "segmentation"), (True, False, False, "registration"), (True, True, True, "planning")],
)
def test_sequencer_stops_at_the_failing_stage_and_holds(segmentation_found, grasps_found, planner_fails, stage):
    def planner(grasps, cloud, q_now):
        if planner_fails:
            raise RuntimeError("pre-grasp: no collision-free IK solution")
        return _two_step_plan(grasps, cloud, q_now)

    dut = PickSequencer(planner, hand_width=0.1, perceive_at_s=0.1)
    context = _advance(dut, _sequencer_context(dut, segmentation_found, grasps_found), 1.0)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.mode == "failed" and status.failed_stage == stage and status.message.startswith(stage)
    np.testing.assert_array_equal(dut.GetOutputPort("arm_position").Eval(context), Q0)
    assert dut.GetOutputPort("hand_width").Eval(context)[0] == 0.1


def test_viewer_draws_what_the_plan_was_made_from():
    plan = _two_step_plan(None, None, Q0)
    plan.grasp_paths_W = {"left": np.zeros((5, 3)), "right": np.ones((5, 3))}
    points = np.random.default_rng(0).uniform(size=(50, 3))
    status = PickStatus("planned", plan=plan, seen_points_W=points, reconstruction_W=points[:10])
    meshcat = Meshcat(MeshcatParams(host="localhost"))
    draw_perception(meshcat, status)
    for path in ("camera_points", "reconstruction", "grasp_path_left", "grasp_path_right"):
        assert meshcat.HasPath(f"/drake/perception/{path}")


def test_pick_planner_closes_the_hands_deeper_than_the_perceived_grasp(scenario):
    """The grasp targets are the perceived ones moved GRASP_DEPTH_MARGIN along each hand's approach axis;
    one planner (one robot model) plans for successive clouds."""
    model = resolve_object(scenario.object)
    X_WO = object_pose_on_table(scenario, model)
    poses = {name: X_WO @ X_OG for name, X_OG in model.info.control_poses().items()}
    plan_pick = make_pick_planner(scenario)
    q0 = np.array(scenario.initial_arm_positions)
    mesh = trimesh.load(model.model_file.parent / "visual.obj", force="mesh")
    surface = X_WO.multiply(trimesh.sample.sample_surface_even(mesh, 2000, seed=0)[0].T).T
    for cloud in (surface, np.zeros((0, 3))):
        plan = plan_pick(GraspPoses(True, poses), cloud, q0)
        reached = DualArmIk(scenario).grasp_frame_poses(plan.configuration_at("approach"))
        for side in ("left", "right"):
            X_GR = poses[f"{side}_grasp"].InvertAndCompose(reached[side])
            # (within the IK's position tolerance: a 2 mm box in W)
            assert np.linalg.norm(X_GR.translation() - [0, 0, GRASP_DEPTH_MARGIN]) < 0.002 * np.sqrt(3) + 1e-4


def test_pick_diagram_structure(scenario):
    diagram = MakePickDiagram(scenario)
    for name in ("station", "segmenter", "pose_estimator", "shape_registrar", "pick_sequencer"):
        assert diagram.HasSubsystemNamed(name)


def test_autonomous_pick_of_an_unseen_drill(scenario):
    outcome = run_pick(replace_object(scenario, category="drill", instance="test_1", yaw=0.25))
    assert outcome.success, outcome.message
    assert outcome.stages["image_to_trajectory"] > 0 and not outcome.failed_stage


def test_empty_table_stops_at_segmentation(scenario):
    empty = replace_object(scenario, present=False)
    outcome = run_pick(empty)
    assert not outcome.success and outcome.failed_stage == "segmentation", outcome.message
    assert outcome.sim_time_s < PERCEIVE_AT_S + 0.2  # stopped right there


def test_object_out_of_reach_stops_at_planning(scenario):
    far = replace_object(scenario, category="drill", instance="test_0", xy=[0.3, 0.0])
    outcome = run_pick(far)
    assert not outcome.success and outcome.failed_stage == "planning", outcome.message
