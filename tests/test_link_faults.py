"""Silent links: the robot's status or the camera's images stop in the middle of a pick, and come back.

The trajectory source pauses while the status is stale and plays on from where it was; the camera latch takes only
an image received since it was asked; the supervisor names the cause when either stays away too long; end to end, a
place with both faults injected completes.
"""

import dataclasses

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U
from pydrake.trajectories import PiecewisePolynomial

from diagrams.autonomous_pick import run_pick
from diagrams.scenario import FaultConfig
from systems.messages import Mode, PerceptionResult, PickStatus, PlanResult, Playback, Stage
from systems.perception.camera_latch import CameraLatch
from systems.pick_checks import CAMERA_WAIT_S, STATUS_LOST_S
from systems.pick_supervisor import PickSupervisor
from systems.pick_tasks import lift_pick
from systems.robot_io.lcm_safety import LinkHealth
from systems.robot_io.simulated_links import CameraGapFault, FreshLink, StatusGapFault
from systems.robot_io.trajectory_source import JointTrajectorySource

FRESH = LinkHealth("status", received=1)


def _plan(start_s: float, end_s: float, plan_id: int = 1) -> PlanResult:
    """A straight move of two joints from 0 to 1 rad over [start_s, end_s]."""
    trajectory = PiecewisePolynomial.FirstOrderHold([start_s, end_s], np.array([[0.0, 1.0], [0.0, 1.0]]))
    return PlanResult(plan_id, "move", True, trajectory)


def _source_playing(pause_at_last_status: bool = False):
    """A trajectory source (2 joints) given _plan(0, 2), its simulator and context."""
    source = JointTrajectorySource(num_joints=2, pause_at_last_status=pause_at_last_status)
    simulator = Simulator(source)
    context = simulator.get_mutable_context()
    source.GetInputPort("plan").FixValue(context, _plan(0.0, 2.0))
    source.GetInputPort("position_measured").FixValue(context, np.zeros(2))
    return source, simulator, context


def test_the_trajectory_source_pauses_while_the_status_is_stale_and_plays_on_from_where_it_was():
    source, simulator, context = _source_playing()
    health = source.GetInputPort("status_health")
    health.FixValue(context, FRESH)
    simulator.AdvanceTo(0.5)
    health.FixValue(context, dataclasses.replace(FRESH, stale=True))
    simulator.AdvanceTo(1.5)  # a second stale: held at a quarter of the way
    np.testing.assert_allclose(source.GetOutputPort("position").Eval(context), [0.25, 0.25], atol=0.01)
    playback = source.GetOutputPort("playback").Eval(context)
    assert playback.plan_id == 1 and playback.time_s == pytest.approx(0.5, abs=0.01)
    assert playback.paused_for_s == pytest.approx(1.0, abs=0.01)
    health.FixValue(context, FRESH)
    simulator.AdvanceTo(2.5)  # back: on from a quarter, a second behind the context's time
    np.testing.assert_allclose(source.GetOutputPort("position").Eval(context), [0.75, 0.75], atol=0.01)
    playback = source.GetOutputPort("playback").Eval(context)
    assert playback.paused_for_s == 0.0 and playback.paused_total_s == pytest.approx(1.0, abs=0.01)
    assert playback.time_s == pytest.approx(1.5, abs=0.01)
    simulator.AdvanceTo(4.0)
    np.testing.assert_allclose(source.GetOutputPort("position").Eval(context), [1.0, 1.0])


def test_behind_a_command_guard_the_source_pauses_where_the_plan_was_at_the_last_status():
    """The guard holds the position the robot last reported; the status is stale only a watchdog period later. So
    the pause holds the plan's point at the last status (0.3 s: 0.15 rad), and the plan goes on from there once
    the status returns: nothing the robot never received is caught up (a restarted driver's can swept off)."""
    source, simulator, context = _source_playing(pause_at_last_status=True)
    health = source.GetInputPort("status_health")
    health.FixValue(context, FRESH)
    simulator.AdvanceTo(1.3)
    health.FixValue(context, dataclasses.replace(FRESH, received_at=0.3, stale=True))
    simulator.AdvanceTo(1.8)
    np.testing.assert_allclose(source.GetOutputPort("position").Eval(context), [0.15, 0.15], atol=1e-9)
    assert source.GetOutputPort("playback").Eval(context).paused_for_s == pytest.approx(1.5, abs=0.01)
    health.FixValue(context, dataclasses.replace(FRESH, received_at=1.8))
    simulator.AdvanceTo(2.3)  # back: on from 0.15 rad, half a second played since
    np.testing.assert_allclose(source.GetOutputPort("position").Eval(context), [0.4, 0.4], atol=0.01)
    # A status that stopped before the plan started (2.2 s; the plan from 2.4 s): held at the plan's start, and on
    # from there once back, no later (paused from 2.2 s, the plan would wait 0.2 s longer: 0.3 rad at 3.5 s).
    source.GetInputPort("plan").FixValue(context, _plan(2.4, 3.4, plan_id=2))
    simulator.AdvanceTo(2.6)
    health.FixValue(context, dataclasses.replace(FRESH, received_at=2.2, stale=True))
    simulator.AdvanceTo(3.0)
    np.testing.assert_allclose(source.GetOutputPort("position").Eval(context), [0.0, 0.0], atol=1e-9)
    health.FixValue(context, dataclasses.replace(FRESH, received_at=3.0))
    simulator.AdvanceTo(3.5)
    np.testing.assert_allclose(source.GetOutputPort("position").Eval(context), [0.5, 0.5], atol=0.02)


def test_a_stopped_plan_is_held_where_it_was_stopped_until_the_next_plan():
    source, simulator, context = _source_playing()
    source.GetInputPort("status_health").FixValue(context, FRESH)
    simulator.AdvanceTo(0.6)
    source.GetInputPort("stop").FixValue(context, [1.0, 0.5])  # (the supervisor saw the drop at 0.5 s)
    simulator.AdvanceTo(1.5)
    np.testing.assert_allclose(source.GetOutputPort("position").Eval(context), [0.25, 0.25], atol=1e-9)
    playback = source.GetOutputPort("playback").Eval(context)
    assert playback.time_s == pytest.approx(0.5) and playback.paused_for_s == 0.0  # (a stop is no status pause)
    source.GetInputPort("plan").FixValue(context, _plan(1.6, 2.6, plan_id=2))  # the recovery, from there
    simulator.AdvanceTo(2.1)
    np.testing.assert_allclose(source.GetOutputPort("position").Eval(context), [0.5, 0.5], atol=0.01)
    assert source.GetOutputPort("playback").Eval(context).paused_total_s == 0.0


def test_without_a_status_link_the_source_plays_at_context_time():
    source, simulator, context = _source_playing()
    simulator.AdvanceTo(1.0)
    np.testing.assert_allclose(source.GetOutputPort("position").Eval(context), [0.5, 0.5], atol=0.01)
    assert source.GetOutputPort("playback").Eval(context).time_s == pytest.approx(1.0)


def test_the_status_gap_starts_in_the_first_carry_repeats_the_last_status_and_goes_stale_after_the_watchdog():
    fault = StatusGapFault(after_s=0.5, duration_s=2.0, stale_after_s=0.25, num_joints=2)
    simulator = Simulator(fault)
    context = simulator.get_mutable_context()
    fault.GetInputPort("position_measured").FixValue(context, [0.1, 0.2])
    status = fault.GetInputPort("status")
    status.FixValue(context, PickStatus(mode=Mode.LIFT))
    simulator.AdvanceTo(1.0)
    assert not fault.GetOutputPort("health").Eval(context).stale  # (not in a carry)
    status.FixValue(context, PickStatus(mode=Mode.CARRY, phase_start_s=1.0))
    simulator.AdvanceTo(1.6)  # the gap began at 1.5
    fault.GetInputPort("position_measured").FixValue(context, [0.3, 0.4])
    np.testing.assert_allclose(fault.GetOutputPort("position_measured").Eval(context), [0.1, 0.2])
    assert not fault.GetOutputPort("health").Eval(context).stale
    simulator.AdvanceTo(1.8)
    health = fault.GetOutputPort("health").Eval(context)
    assert health.stale and health.received_at == pytest.approx(1.5, abs=0.011)
    simulator.AdvanceTo(3.6)  # back
    assert not fault.GetOutputPort("health").Eval(context).stale
    np.testing.assert_allclose(fault.GetOutputPort("position_measured").Eval(context), [0.3, 0.4])
    status.FixValue(context, PickStatus(mode=Mode.CARRY, phase_start_s=3.6))
    simulator.AdvanceTo(5.0)  # once only
    assert not fault.GetOutputPort("health").Eval(context).stale


def _image(value: float) -> tuple[ImageRgba8U, ImageDepth32F]:
    color, depth = ImageRgba8U(4, 3), ImageDepth32F(4, 3)
    depth.mutable_data[:] = value
    return color, depth


def test_the_latch_waits_through_a_camera_gap_for_an_image_received_since_it_was_asked():
    builder = DiagramBuilder()
    fault = builder.AddSystem(CameraGapFault(at_s=0.2, duration_s=1.0, stale_after_s=0.5))
    latch = builder.AddSystem(CameraLatch(robot_positions=2))
    for name in ("color_image", "depth_image"):
        builder.ExportInput(fault.GetInputPort(name), name)
        builder.Connect(fault.GetOutputPort(name), latch.GetInputPort(name))
    builder.Connect(fault.GetOutputPort("health"), latch.GetInputPort("image_health"))
    builder.ExportInput(latch.GetInputPort("trigger"), "trigger")
    builder.ExportInput(latch.GetInputPort("camera_pose"), "camera_pose")
    builder.ExportOutput(latch.GetOutputPort("frame_id"), "frame_id")
    builder.ExportOutput(latch.GetOutputPort("depth_image"), "depth_image")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    color, depth = _image(0.7)
    diagram.GetInputPort("color_image").FixValue(context, color)
    diagram.GetInputPort("depth_image").FixValue(context, depth)
    diagram.GetInputPort("trigger").FixValue(context, [0.0])
    diagram.GetInputPort("camera_pose").FixValue(context, RigidTransform())
    simulator.AdvanceTo(0.3)  # in the gap
    diagram.GetInputPort("depth_image").FixValue(context, _image(0.9)[1])  # what the camera would send now
    diagram.GetInputPort("trigger").FixValue(context, [1.0])
    simulator.AdvanceTo(1.15)
    assert diagram.GetOutputPort("frame_id").Eval(context)[0] == 0  # asked in the gap: waits
    simulator.AdvanceTo(1.25)  # the images are back
    assert diagram.GetOutputPort("frame_id").Eval(context)[0] == 1
    assert diagram.GetOutputPort("depth_image").Eval(context).data[0, 0, 0] == pytest.approx(0.9)


def test_a_fresh_link_reports_its_last_message_now():
    link = FreshLink("camera")
    context = link.CreateDefaultContext()
    context.SetTime(2.5)
    health = link.GetOutputPort("health").Eval(context)
    assert health.received == 1 and health.received_at == 2.5 and not health.stale


def _supervisor(result: PerceptionResult | None = None, **options):
    dut = PickSupervisor(lift_pick(check=False), perceive_at_s=0.1, **options)
    context = dut.CreateDefaultContext()
    for port, value in (("position_measured", np.zeros(14)), ("frame_id", [0.0]), ("look_frame_id", [0.0])):
        dut.GetInputPort(port).FixValue(context, value)
    for side in ("left", "right"):
        dut.GetInputPort(f"{side}_hand_state").FixValue(context, [0.05, 0.0])
    dut.GetInputPort("plan").FixValue(context, PlanResult())
    dut.GetInputPort("perception").FixValue(context, result or PerceptionResult(False, Stage.SEGMENTATION, "nothing"))
    return dut, context, Simulator(dut, context)


def test_a_hand_that_opens_during_a_held_move_stops_the_move_where_the_arms_are():
    dut = PickSupervisor(lift_pick(check=False), perceive_at_s=0.1, max_attempts=2)
    context = dut.CreateDefaultContext()
    for port, value in (("position_measured", np.zeros(14)), ("frame_id", [1.0]), ("look_frame_id", [0.0])):
        dut.GetInputPort(port).FixValue(context, value)
    hands = [dut.GetInputPort(f"{side}_hand_state") for side in ("left", "right")]
    for hand in hands:
        hand.FixValue(context, [0.03, 0.0])  # holding
    dut.GetInputPort("plan").FixValue(context, PlanResult())
    dut.GetInputPort("perception").FixValue(context, PerceptionResult(True, X_WO_seen=RigidTransform([0.7, 0, 0.8])))
    simulator = Simulator(dut, context)

    def answer(duration: float = 0.1):
        request = dut.GetOutputPort("plan_request").Eval(context)
        t = context.get_time()
        q = np.column_stack([request.q_start, request.q_start + 1.0])
        trajectory = PiecewisePolynomial.FirstOrderHold([t, t + duration], q)
        dut.GetInputPort("plan").FixValue(context, PlanResult(request.id, request.phase, True, trajectory))
        return trajectory

    simulator.AdvanceTo(0.15)
    answer()  # reach
    simulator.AdvanceTo(0.3)
    answer()  # approach
    simulator.AdvanceTo(2.0)  # closed, checked
    assert dut.GetOutputPort("status").Eval(context).mode == Mode.LIFT
    lift = answer(duration=2.0)
    simulator.AdvanceTo(2.5)
    hands[0].FixValue(context, [0.1, 0.0])  # the left hand opened
    simulator.AdvanceTo(2.52)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.task == "recover" and status.attempt_failures[0][1].startswith("grasp: during the lift: the left")
    plan_id, stopped_s = dut.GetOutputPort("stop").Eval(context)
    assert plan_id == status.request.id and 2.5 <= stopped_s <= 2.52  # (the lift's: the recovery opens the hands first)
    np.testing.assert_allclose(status.plan_end_q, lift.value(stopped_s).ravel())  # the recovery's moves start there


def test_the_supervisor_names_a_camera_that_sends_no_frame():
    dut, context, simulator = _supervisor()
    simulator.AdvanceTo(0.1 + CAMERA_WAIT_S - 0.05)
    assert dut.GetOutputPort("status").Eval(context).mode == Mode.PERCEIVING  # still waiting
    simulator.AdvanceTo(0.1 + CAMERA_WAIT_S + 0.05)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.mode == Mode.FAILED and status.failed_stage == Stage.CAMERA
    assert "the camera's images stopped" in status.message


@pytest.mark.parametrize("lost_s", [None, 30.0])
def test_the_supervisor_waits_for_a_paused_move_and_names_a_status_that_stays_away(lost_s):
    """As long as the scenario's hardware.status_lost_s (None: STATUS_LOST_S; 30 s: a spawned driver restarted)."""
    seen = PerceptionResult(True, X_WO_seen=RigidTransform([0.7, 0.0, 0.8]))
    dut, context, simulator = _supervisor(seen, status_lost_s=lost_s)
    lost_s = lost_s or STATUS_LOST_S
    dut.GetInputPort("frame_id").FixValue(context, [1.0])
    simulator.AdvanceTo(0.15)
    request = dut.GetOutputPort("plan_request").Eval(context)
    assert dut.GetOutputPort("status").Eval(context).mode == Mode.REACH
    trajectory = PiecewisePolynomial.FirstOrderHold([0.15, 0.25], np.column_stack([request.q_start] * 2))
    dut.GetInputPort("plan").FixValue(context, PlanResult(request.id, request.phase, True, trajectory))
    playback = dut.GetInputPort("playback")
    playback.FixValue(context, Playback(request.id, 0.2, paused_for_s=1.0))  # paused before the end
    simulator.AdvanceTo(1.0)
    assert dut.GetOutputPort("status").Eval(context).mode == Mode.REACH  # waits for the played end
    playback.FixValue(context, Playback(request.id, 0.2, paused_for_s=lost_s - 0.1))
    simulator.AdvanceTo(1.1)
    assert dut.GetOutputPort("status").Eval(context).mode == Mode.REACH
    playback.FixValue(context, Playback(request.id, 0.2, paused_for_s=lost_s + 0.1))
    simulator.AdvanceTo(1.2)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.mode == Mode.FAILED and status.failed_stage == Stage.STATUS
    assert f"the robot's status stopped for {lost_s:.0f} s during the reach" in status.message


@pytest.mark.slow
def test_a_place_goes_on_through_a_camera_gap_before_perceiving_and_a_silent_status_in_the_carry(scenario):
    """Sensor on. The camera's images stop for 5 s from 0.2 s (perception, asked at 0.5 s, waits for them); the
    robot's status stops for 2 s, 1 s into the carry (the arms hold once it is stale, then play on). The can is
    placed as without the faults."""
    faults = FaultConfig(camera_gap_at_s=0.2, camera_gap_s=5.0, status_gap_in_carry_after_s=1.0, status_gap_s=2.0)
    outcome = run_pick(dataclasses.replace(scenario, task="place", faults=faults))
    assert outcome.success, outcome.message
    assert outcome.waits["frames_waited_s"] >= 4.6  # (the first frame: asked at 0.5 s, the images back at 5.2 s)
    watchdog_s = scenario.hardware.watchdog_s
    assert outcome.waits["status_held_s"] == pytest.approx(2.0 - watchdog_s, abs=0.05)
