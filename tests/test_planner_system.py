"""The planner and trajectory source systems: event-driven planning, playback, failures held, never executed."""

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from diagrams.hand_ik import DualArmIk
from diagrams.objects.library import resolve_object
from diagrams.oracle_pick import world_grasps
from diagrams.station import object_pose_on_table
from systems.joint_plan import SPEED_FRACTION
from systems.planner import JointTrajectorySource, PlanRequest, StompPlanner


@pytest.fixture(scope="module")
def setup(scenario):
    model = resolve_object(scenario.object)
    X_WO = object_pose_on_table(scenario, model)
    ik = DualArmIk(scenario, obstacle=model, X_WO=X_WO)
    q_start = np.array(scenario.initial_arm_positions)
    goal = ik.solve(world_grasps(X_WO, model.info, "pregrasp"), q_start)
    assert goal.success
    return ik, q_start, goal.q


def build(ik, hold):
    builder = DiagramBuilder()
    planner = builder.AddNamedSystem("planner", StompPlanner(ik.stomp, ik.planning_obstacles, ik.velocity_limits))
    source = builder.AddNamedSystem("source", JointTrajectorySource(hold))
    builder.Connect(planner.GetOutputPort("plan"), source.GetInputPort("plan"))
    builder.ExportInput(planner.GetInputPort("request"), "request")
    builder.ExportOutput(source.GetOutputPort("position"), "position")
    builder.ExportOutput(planner.GetOutputPort("plan"), "plan")
    return builder.Build()


def test_planner_plans_once_and_the_source_plays_it_within_limits(setup):
    ik, q_start, q_goal = setup
    diagram = build(ik, hold=q_start)
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    request = PlanRequest(id=1, q_start=q_start, q_goal=q_goal, start_time=0.05)
    diagram.GetInputPort("request").FixValue(context, AbstractValue.Make(request))
    simulator.AdvanceTo(0.03)
    plan = diagram.GetOutputPort("plan").Eval(context)
    assert plan.success and plan.id == 1, plan.message
    trajectory = plan.trajectory
    np.testing.assert_allclose(trajectory.value(trajectory.start_time()).ravel(), q_start, atol=1e-9)
    np.testing.assert_allclose(trajectory.value(trajectory.end_time()).ravel(), q_goal, atol=1e-9)
    times = np.linspace(trajectory.start_time(), trajectory.end_time(), 300)
    q = np.array([trajectory.value(t).ravel() for t in times])
    v = np.array([trajectory.EvalDerivative(t).ravel() for t in times])
    assert np.all(q >= ik.lower - 1e-9) and np.all(q <= ik.upper + 1e-9)
    assert np.all(np.abs(v) <= SPEED_FRACTION * ik.velocity_limits * 1.01)
    simulator.AdvanceTo(trajectory.end_time() + 0.1)
    np.testing.assert_allclose(diagram.GetOutputPort("position").Eval(context), q_goal, atol=1e-9)


def test_a_failed_plan_is_reported_and_the_source_holds(setup):
    ik, q_start, _ = setup
    rng = np.random.default_rng(1)
    colliding = next(q for q in rng.uniform(ik.lower, ik.upper, size=(2000, 14)) if ik.in_collision(q))
    diagram = build(ik, hold=q_start)
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.GetInputPort("request").FixValue(
        context, AbstractValue.Make(PlanRequest(id=7, q_start=q_start, q_goal=colliding))
    )
    simulator.AdvanceTo(0.5)
    plan = diagram.GetOutputPort("plan").Eval(context)
    assert plan.id == 7 and not plan.success and "collides" in plan.message
    np.testing.assert_allclose(diagram.GetOutputPort("position").Eval(context), q_start)
