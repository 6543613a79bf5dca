"""The planner, trajectory source, hand command and camera latch stages, each alone."""

import time

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.sensors import ImageRgba8U
from pydrake.trajectories import PiecewisePolynomial

from diagrams.planning_scene import grasp_configuration, make_pick_motions, true_grasp_poses
from diagrams.scenario import initial_positions
from systems.messages import GraspPoses, HandCommand, PlanRequest, PlanResult
from systems.perception.camera_latch import CameraLatch
from systems.planning import pick_motions, stomp_planner
from systems.planning.plan_telemetry import PlanTelemetry
from systems.planning.sphere_model import on_the_robot
from systems.planning.stomp_planner import StompPlanner
from systems.planning.straight_motions import WouldTouch
from systems.robot_io.hand_command import HandCommandSource
from systems.robot_io.joint_plan import SPEED_FRACTION
from systems.robot_io.trajectory_source import JointTrajectorySource

LATENCY_S = 0.3


@pytest.fixture(scope="module")
def planner(scenario):
    return StompPlanner(make_pick_motions(scenario), LATENCY_S, grasp_depth_margin=0.01)


def _planner_context(planner, request, grasps):
    context = planner.CreateDefaultContext()
    planner.GetInputPort("request").FixValue(context, AbstractValue.Make(request))
    planner.GetInputPort("grasp_poses").FixValue(context, AbstractValue.Make(grasps))
    planner.GetInputPort("obstacle_cloud_W").FixValue(context, AbstractValue.Make(np.zeros((0, 3))))
    return context


def test_planner_plans_a_request_once_and_releases_it_after_its_latency(planner, scenario):
    q_start = initial_positions(scenario)
    poses = true_grasp_poses(scenario)
    request = PlanRequest(id=1, phase="reach", q_start=q_start, path="free", targets="pregrasp")
    context = _planner_context(planner, request, GraspPoses(True, poses))
    simulator = Simulator(planner, context)
    simulator.AdvanceTo(LATENCY_S - 0.05)
    assert planner.GetOutputPort("plan").Eval(context).id == -1  # planned, but its latency has not passed
    simulator.AdvanceTo(LATENCY_S + 0.02)
    plan = planner.GetOutputPort("plan").Eval(context)
    assert plan.id == 1 and plan.success, plan.message
    trajectory = plan.trajectory
    assert trajectory.start_time() == pytest.approx(LATENCY_S)  # requested at t = 0
    np.testing.assert_allclose(trajectory.value(trajectory.start_time()).ravel(), q_start, atol=1e-9)
    world = planner.motions.world
    reached = world.grasp_frame_poses(trajectory.value(trajectory.end_time()).ravel())
    for side in ("left", "right"):
        assert np.linalg.norm(reached[side].translation() - poses[f"{side}_pregrasp"].translation()) < 0.004
        assert plan.grasp_offsets_G[side].IsExactlyIdentity()  # reached as perceived: no other grasp chosen
    times = np.linspace(trajectory.start_time(), trajectory.end_time(), 300)
    q = np.array([trajectory.value(t).ravel() for t in times])
    v = np.array([trajectory.EvalDerivative(t).ravel() for t in times])
    assert np.all(q >= world.lower - 1e-9) and np.all(q <= world.upper + 1e-9)
    assert np.all(np.abs(v) <= SPEED_FRACTION * world.velocity_limits * 1.01)

    # The straight approach goes grasp_depth_margin deeper along z_G than the grasp it was given: the perceived
    # one, or the one a reach chose (here the left one slid 1.5 cm along its handle).
    at_pregrasps = trajectory.value(trajectory.end_time()).ravel()
    slid = {"left": RigidTransform([0.015, 0.0, 0.0]), "right": RigidTransform()}
    for request_id, offsets in ((2, None), (3, slid)):
        approach = PlanRequest(id=request_id, phase="approach", q_start=at_pregrasps, path="straight",
                               targets="grasp", grasp_offsets_G=offsets)  # fmt: skip
        planner.GetInputPort("request").FixValue(context, AbstractValue.Make(approach))
        simulator.AdvanceTo(context.get_time() + LATENCY_S + 0.02)
        plan = planner.GetOutputPort("plan").Eval(context)
        assert plan.id == request_id and plan.success, plan.message
        reached = world.grasp_frame_poses(plan.trajectory.value(plan.trajectory.end_time()).ravel())
        for side in ("left", "right"):
            X_WG = poses[f"{side}_grasp"] @ (offsets or {}).get(side, RigidTransform())
            X_GR = X_WG.InvertAndCompose(reached[side])
            assert np.linalg.norm(X_GR.translation() - [0, 0, 0.01]) < 0.002 * np.sqrt(3) + 1e-4


@pytest.mark.parametrize(
    ("request_", "grasps", "reason"),
    [
        (PlanRequest(id=3, phase="reach", targets="pregrasp"), GraspPoses(False, message="diverged"), "no grasp poses"),
        (PlanRequest(id=4, phase="reach", path="fly"), GraspPoses(False), "unknown path"),
    ],
)
def test_planner_names_what_it_could_not_plan(planner, scenario, request_, grasps, reason):
    request_.q_start = initial_positions(scenario)
    context = _planner_context(planner, request_, grasps)
    Simulator(planner, context).AdvanceTo(LATENCY_S + 0.02)
    plan = planner.GetOutputPort("plan").Eval(context)
    assert plan.id == request_.id and not plan.success and plan.trajectory is None
    assert plan.message.startswith("reach: ") and reason in plan.message


@pytest.mark.slow
def test_planner_reports_an_unreachable_goal(planner, scenario):
    far = {name: RigidTransform([2.0, 0.0, 1.0]) @ X for name, X in true_grasp_poses(scenario).items()}
    request = PlanRequest(id=5, phase="reach", q_start=initial_positions(scenario))
    context = _planner_context(planner, request, GraspPoses(True, far))
    Simulator(planner, context).AdvanceTo(LATENCY_S + 0.02)
    plan = planner.GetOutputPort("plan").Eval(context)
    assert not plan.success and "no collision-free IK solution" in plan.message


def test_a_back_off_beyond_reach_ends_where_the_arms_stop_and_an_approach_does_not(planner, scenario, monkeypatch):
    """A retreat (back_off) whose whole line is out of reach (made 45 cm here) plans the part the arms reach along
    it; an approach to grasps the arms reach only part of the way to fails."""
    monkeypatch.setattr(stomp_planner, "RETREAT_M", 0.45)
    q_grasp = grasp_configuration(scenario, planner.motions)
    start = planner.motions.world.grasp_frame_poses(q_grasp)
    back_off = PlanRequest(id=7, phase="back_off", q_start=q_grasp, path="straight", targets="retreat")
    context = _planner_context(planner, back_off, GraspPoses(False))
    plan = planner.plan(back_off, 0.0, context)
    assert plan.success, plan.message
    end = planner.motions.world.grasp_frame_poses(plan.trajectory.value(plan.trajectory.end_time()).ravel())
    for side in ("left", "right"):
        moved = start[side].InvertAndCompose(end[side]).translation()  # in G: back along z_G only
        assert -0.45 + 0.01 < moved[2] <= -0.45 / 3 + 0.002 and np.abs(moved[:2]).max() < 0.002
    far = {f"{side}_grasp": X @ RigidTransform([0.0, 0.0, -0.45]) for side, X in start.items()}
    approach = PlanRequest(id=8, phase="approach", q_start=q_grasp, path="straight", targets="grasp")
    plan = planner.plan(approach, 0.0, _planner_context(planner, approach, GraspPoses(True, far)))
    assert not plan.success and "IK failed" in plan.message


def test_a_held_move_asked_for_a_full_back_off_fails_where_the_arms_cannot_back_off_from_its_end(
    planner, scenario, monkeypatch
):
    """A clear's set-down (a held move 2 cm down) asked to leave room for the whole back-off: planned where the
    arms reach 10 cm back from its end, refused, naming the back-off, where they do not (made 45 cm here); without
    the ask the same move is planned."""
    q_grasp = grasp_configuration(scenario, planner.motions)
    down = RigidTransform([0.0, 0.0, -0.02])
    for request_id, back_off_m, full, planned in ((10, 0.1, True, True), (11, 0.45, True, False),
                                                   (12, 0.45, False, True)):  # fmt: skip
        monkeypatch.setattr(stomp_planner, "RETREAT_M", back_off_m)
        set_down = PlanRequest(id=request_id, phase="set_down", q_start=q_grasp, path="held", X_motion_W=down,
                               full_back_off=full)  # fmt: skip
        plan = planner.plan(set_down, 0.0, _planner_context(planner, set_down, GraspPoses(False)))
        assert plan.success == planned, plan.message
        if not planned:
            assert plan.message.startswith("set_down: the hands could not back off 45 cm from its end")


def test_a_held_move_takes_the_first_of_its_alternatives_that_reaches(planner, scenario):
    """A pour's tilt rolled about the outflow, made simple: a lift of 45 cm (out of reach) is refused with its reason;
    with alternatives (another 45 cm, then 3 cm) the first that reaches is planned, and its achieved motion is that
    one's; where none reaches, the first's reason is given with the count of the others tried."""
    q_grasp = grasp_configuration(scenario, planner.motions)
    up_3, far = RigidTransform([0.0, 0.0, 0.03]), RigidTransform([0.0, 0.0, 0.45])
    for request_id, alternatives, planned in ((30, (), False), (31, (far, up_3), True), (32, (far,), False)):
        lift = PlanRequest(id=request_id, phase="pour", q_start=q_grasp, path="held", X_motion_W=far,
                           alternatives=alternatives)  # fmt: skip
        plan = planner.plan(lift, 0.0, _planner_context(planner, lift, GraspPoses(False)))
        assert plan.success == planned, plan.message
        if planned:  # (the left hand moved 3 cm up)
            hand = planner.motions.world.grasp_frame_poses(q_grasp)["left"].translation()
            np.testing.assert_allclose(plan.achieved_motion_W.multiply(hand), hand + [0.0, 0.0, 0.03], atol=0.002)
        else:
            assert plan.message.startswith("pour: the moved hands are out of reach"), plan.message
            assert ("nor any of 1 other options" in plan.message) == bool(alternatives)


# Where the held-out bulb can's pick stood at its pre-grasps at -0.25 rad when a look found the can moved (seed 5): the
# back-off's first step along -z_G would take the right forearm into the torso.
BACK_OFF_INTO_THE_TORSO = np.array(
    [1.229181, 2.449151, 0.717312, -0.856175, -0.2098, -1.360193, -0.109704, 0.489876, -0.014, 0.649261, -2.37731,
     0.70284, 1.284568, -0.573261, 0.0]
)  # fmt: skip


def test_a_back_off_whose_first_step_would_touch_the_robot_stays_where_it_is(planner, scenario):
    """Before, the back-off drove the forearm into the torso and the pick went on from there; refused outright, the
    pick would stop. The hands stay where they are (a move of no length), and the next reach leaves from there."""
    motions = planner.motions
    assert not motions.world.penetrations(BACK_OFF_INTO_THE_TORSO)
    back = {side: X @ RigidTransform([0.0, 0.0, -stomp_planner.RETREAT_M])
            for side, X in motions.world.grasp_frame_poses(BACK_OFF_INTO_THE_TORSO).items()}  # fmt: skip
    with pytest.raises(WouldTouch, match="step 1 of 3: the arms would touch the robot"):
        motions.straight(BACK_OFF_INTO_THE_TORSO, back, min_steps=1)
    back_off = PlanRequest(id=9, phase="back_off", q_start=BACK_OFF_INTO_THE_TORSO, path="straight", targets="retreat")
    plan = planner.plan(back_off, 0.0, _planner_context(planner, back_off, GraspPoses(False)))
    assert plan.success, plan.message
    for t in np.linspace(plan.trajectory.start_time(), plan.trajectory.end_time(), 5):
        np.testing.assert_allclose(plan.trajectory.value(t).ravel(), BACK_OFF_INTO_THE_TORSO, atol=1e-12)


def test_a_relaxing_move_ends_where_the_arms_are_within_their_limits(planner, scenario):
    """The command after a set-down (q_start) is brought to where the arms are measured (q_goal), slowly; a joint
    measured past its limit is commanded to the limit; an unknown measurement is refused."""
    world = planner.motions.world
    q_start = grasp_configuration(scenario, planner.motions)
    measured = q_start + 0.005
    measured[3] = world.upper[3] + 0.01
    relax = PlanRequest(id=10, phase="relax", q_start=q_start, path="straight", targets="measured", q_goal=measured)
    plan = planner.plan(relax, 0.0, _planner_context(planner, relax, GraspPoses(False)))
    assert plan.success, plan.message
    trajectory = plan.trajectory
    np.testing.assert_allclose(trajectory.value(trajectory.start_time()).ravel(), q_start, atol=1e-12)
    np.testing.assert_allclose(trajectory.value(trajectory.end_time()).ravel(), np.clip(measured, world.lower,
                               world.upper), atol=1e-12)  # fmt: skip
    assert trajectory.end_time() - trajectory.start_time() >= pick_motions.SPARSE_SEGMENT_S - 1e-9
    relax.q_goal = np.full_like(q_start, np.nan)
    plan = planner.plan(relax, 0.0, _planner_context(planner, relax, GraspPoses(False)))
    assert not plan.success and "not finite" in plan.message


def _line(q0, q1, t0, t1):
    return PiecewisePolynomial.FirstOrderHold([t0, t1], np.column_stack([q0, q1]))


def test_a_free_move_plans_around_the_objects_a_clear_set_down(planner, scenario):
    """The move home from the grasps, with a 12 cm cube of points where its straight joint line takes the right hand
    halfway (PlanRequest.set_down_W: what a clear set down, which the camera may not see): no sphere of the robot
    meets the cube along the played plan, where the straight line goes through it."""
    world = planner.motions.world
    q_home, q_start = initial_positions(scenario), grasp_configuration(scenario, planner.motions)
    halfway = world.grasp_frame_poses(0.5 * (q_start + q_home))["right"].translation()
    steps = np.arange(-0.06, 0.061, 0.01)
    cube = halfway + np.array([[x, y, z] for x in steps for y in steps for z in steps])

    def spheres(q):
        return np.column_stack([world.spheres.centres_W(world.kinematics.body_poses(q[None]))[0], world.spheres.radius])

    line = [q_start + s * (q_home - q_start) for s in np.linspace(0.0, 1.0, 50)]
    assert any(on_the_robot(cube, spheres(q), 0.0).any() for q in line)  # (the cube stands in the straight way)
    request = PlanRequest(id=7, phase="next_object_home", q_start=q_start, path="free", targets="home",
                          q_goal=q_home, set_down_W=cube)  # fmt: skip
    context = _planner_context(planner, request, GraspPoses(False))
    Simulator(planner, context).AdvanceTo(LATENCY_S + 0.02)
    plan = planner.GetOutputPort("plan").Eval(context)
    assert plan.success, plan.message
    trajectory = plan.trajectory
    for t in np.linspace(trajectory.start_time(), trajectory.end_time(), 200):
        assert not on_the_robot(cube, spheres(trajectory.value(t).ravel()), 0.0).any(), t
    np.testing.assert_allclose(trajectory.value(trajectory.end_time()).ravel(), q_home, atol=1e-6)


def test_trajectory_source_holds_plays_and_ignores_failed_plans():
    dut = JointTrajectorySource()
    context = dut.CreateDefaultContext()
    measured = np.linspace(-0.5, 0.5, 14)
    dut.GetInputPort("position_measured").FixValue(context, measured)
    dut.GetInputPort("plan").FixValue(context, AbstractValue.Make(PlanResult()))
    simulator = Simulator(dut, context)
    simulator.AdvanceTo(0.5)
    np.testing.assert_array_equal(dut.GetOutputPort("position").Eval(context), measured)  # held before any plan

    goal = measured + 0.2
    plan = PlanResult(id=1, success=True, trajectory=_line(measured, goal, 1.0, 2.0))
    dut.GetInputPort("plan").FixValue(context, AbstractValue.Make(plan))
    dut.GetInputPort("position_measured").FixValue(context, measured + 5)  # the latched hold stays
    simulator.AdvanceTo(0.8)
    np.testing.assert_allclose(dut.GetOutputPort("position").Eval(context), measured)  # before its start: its start
    simulator.AdvanceTo(1.5)
    np.testing.assert_allclose(dut.GetOutputPort("position").Eval(context), measured + 0.1)  # at context time
    simulator.AdvanceTo(3.0)
    np.testing.assert_allclose(dut.GetOutputPort("position").Eval(context), goal)  # held at its end

    failed = PlanResult(id=2, success=False, message="no path")
    dut.GetInputPort("plan").FixValue(context, AbstractValue.Make(failed))
    simulator.AdvanceTo(3.5)
    np.testing.assert_allclose(dut.GetOutputPort("position").Eval(context), goal)  # never executed


def test_trajectory_source_waits_for_a_finite_measurement():
    dut = JointTrajectorySource()
    context = dut.CreateDefaultContext()
    dut.GetInputPort("plan").FixValue(context, AbstractValue.Make(PlanResult()))
    dut.GetInputPort("position_measured").FixValue(context, np.full(14, np.nan))
    simulator = Simulator(dut, context)
    simulator.AdvanceTo(0.2)
    assert np.all(np.isnan(dut.GetOutputPort("position").Eval(context)))  # (the guard sends nothing then)
    dut.GetInputPort("position_measured").FixValue(context, np.ones(14))
    simulator.AdvanceTo(0.3)
    np.testing.assert_array_equal(dut.GetOutputPort("position").Eval(context), np.ones(14))


def test_hand_command_ramps_the_opening():
    dut = HandCommandSource()
    context = dut.CreateDefaultContext()
    dut.GetInputPort("command").FixValue(context, AbstractValue.Make(HandCommand(0.0, 0.1, 1.0, 1.0)))
    for t, width in ((0.5, 0.1), (1.5, 0.05), (2.5, 0.0)):
        context.SetTime(t)
        assert dut.GetOutputPort("width").Eval(context)[0] == pytest.approx(width)


def test_camera_latch_holds_one_frame_until_asked_again():
    dut = CameraLatch()
    context = dut.CreateDefaultContext()

    def show(value):
        image = ImageRgba8U(4, 3)
        np.asarray(image.mutable_data)[:] = value
        dut.GetInputPort("color_image").FixValue(context, AbstractValue.Make(image))

    show(10)
    dut.GetInputPort("depth_image").FixValue(context, dut.GetInputPort("depth_image").Allocate())
    dut.GetInputPort("camera_pose").FixValue(context, AbstractValue.Make(RigidTransform([1.0, 2.0, 3.0])))
    dut.GetInputPort("trigger").FixValue(context, [0.0])
    dut.GetInputPort("robot_position").FixValue(context, np.full(14, 0.5))
    simulator = Simulator(dut, context)
    simulator.AdvanceTo(0.1)
    assert dut.GetOutputPort("frame_id").Eval(context)[0] == 0
    assert dut.GetOutputPort("color_image").Eval(context).size() == 0  # nothing latched yet
    assert np.isnan(dut.GetOutputPort("latched_wall_s").Eval(context)[0])
    dut.GetInputPort("trigger").FixValue(context, [1.0])
    before = time.perf_counter()
    simulator.AdvanceTo(0.2)
    assert dut.GetOutputPort("frame_id").Eval(context)[0] == 1
    assert before <= dut.GetOutputPort("latched_wall_s").Eval(context)[0] <= time.perf_counter()
    show(20)  # the camera and the robot move on; the latch does not
    dut.GetInputPort("robot_position").FixValue(context, np.full(14, 0.7))
    simulator.AdvanceTo(0.3)
    assert np.all(np.asarray(dut.GetOutputPort("color_image").Eval(context).data) == 10)
    np.testing.assert_array_equal(dut.GetOutputPort("robot_position").Eval(context), np.full(14, 0.5))
    np.testing.assert_allclose(dut.GetOutputPort("camera_pose").Eval(context).translation(), [1, 2, 3])
    dut.GetInputPort("trigger").FixValue(context, [2.0])
    simulator.AdvanceTo(0.4)
    assert np.all(np.asarray(dut.GetOutputPort("color_image").Eval(context).data) == 20)


def test_plan_telemetry_times_the_first_trajectory_after_a_frame():
    """From a frame's latch to the first successful plan after it, failed plans before it included; without one,
    to the last plan (the pick failed there)."""
    telemetry = PlanTelemetry()
    for id_, finished, success in ((1, 10.0, True), (2, 20.5, False), (3, 21.0, True), (4, 22.0, True)):
        telemetry = telemetry.with_plan(PlanResult(id_, success=success, planning_s=0.5, finished_wall_s=finished))
    assert telemetry.plans == 3 and telemetry.last_id == 4 and telemetry.first_planning_s == 0.5
    assert telemetry.latency_after(20.0) == pytest.approx(1.0)  # a retry's frame: plan 2 failed, plan 3 is its first
    assert telemetry.latency_after(9.0) == pytest.approx(1.0)
    failed = PlanTelemetry().with_plan(PlanResult(1, success=False, finished_wall_s=5.0))
    assert failed.plans == 0 and failed.latency_after(4.0) == pytest.approx(1.0)
    assert np.isnan(failed.latency_after(6.0))
