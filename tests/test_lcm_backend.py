"""The LCM backend: port parity with the simulation, checked decoding, the command guard and watchdog,
fault injection, and picks through LCM (in-process over memq://, and across processes in a private
loopback-only network namespace)."""

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from drake import lcmt_iiwa_command, lcmt_iiwa_status, lcmt_schunk_wsg_status
from pydrake.common.value import AbstractValue
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator

from diagrams import lcm_pick
from diagrams.autonomous_pick import MakePickDiagram, run_pick
from diagrams.hardware_station import MakeHardwareStation, RobotModel, RobotNotResponding, wait_for_robot
from diagrams.paths import REPO_ROOT
from diagrams.robot_driver import (
    MakeRobotDriver,
    driver_state,
    read_driver_state,
    set_plant_state,
    write_driver_state,
)
from diagrams.scenario import FaultConfig, initial_positions, load_scenario, replace_object
from diagrams.station import MakeStation
from systems.messages import ClearedObject, Mode, PickStatus
from systems.robot_io.lcm_messages import MalformedMessage, RawMessage, decode_arm_status, decode_images
from systems.robot_io.lcm_safety import CommandGuard, LinkHealth
from systems.robot_io.robot_clock import RobotClock


def port_names(diagram):
    inputs = {diagram.get_input_port(i).get_name() for i in range(diagram.num_input_ports())}
    outputs = {diagram.get_output_port(i).get_name() for i in range(diagram.num_output_ports())}
    return inputs, outputs


def test_sim_and_hardware_stations_have_the_same_ports(scenario):
    assert port_names(MakeHardwareStation(scenario, DrakeLcm("memq://"))) == port_names(MakeStation(scenario))


def test_hardware_camera_pose_equals_the_simulated_one(scenario):
    sim = MakeStation(scenario)
    hardware = MakeHardwareStation(scenario, DrakeLcm("memq://"))
    X_sim = sim.GetOutputPort("camera0.pose").Eval(sim.CreateDefaultContext())
    X_hw = hardware.GetOutputPort("camera0.pose").Eval(hardware.CreateDefaultContext())
    np.testing.assert_allclose(X_hw.GetAsMatrix4(), X_sim.GetAsMatrix4(), atol=1e-12)


def status_message(q, utime=1000, joints=15):
    message = lcmt_iiwa_status()
    message.utime, message.num_joints = utime, joints
    for name in lcmt_iiwa_status.__slots__[2:]:
        setattr(message, name, list(q) if "position" in name else [0.0] * joints)
    return message


def test_decoding_rejects_garbage_wrong_sizes_and_nan():
    q = np.linspace(-1, 1, 15)
    _, values = decode_arm_status(RawMessage(status_message(q).encode(), 1), joints=15)
    np.testing.assert_array_equal(values[15:30], q)
    with pytest.raises(MalformedMessage, match="not a valid lcmt_iiwa_status"):
        decode_arm_status(RawMessage(b"\x00garbage", 2), joints=15)
    with pytest.raises(MalformedMessage, match="7 joints"):
        decode_arm_status(RawMessage(status_message(q[:7], joints=7).encode(), 3), joints=15)
    with pytest.raises(MalformedMessage, match="NaN"):
        decode_arm_status(RawMessage(status_message(np.full(15, np.nan)).encode(), 4), joints=15)
    with pytest.raises(MalformedMessage):
        decode_images(RawMessage(b"not an image array", 5))


def guard_context(guard, desired, measured, health):
    context = guard.CreateDefaultContext()
    guard.GetInputPort("desired").FixValue(context, desired)
    guard.GetInputPort("measured").FixValue(context, measured)
    guard.GetInputPort("status_health").FixValue(context, AbstractValue.Make(health))
    return context


def test_command_guard_limits_rejects_nan_holds_while_the_status_stops_and_trips_when_it_stays_away():
    lower, upper, speed = np.full(2, -1.0), np.full(2, 1.0), np.full(2, 2.0)
    guard = CommandGuard(lower, upper, speed, period_s=0.01, lost_after_s=1.0)
    measured = np.array([0.0, 0.5])
    context = guard_context(guard, np.array([5.0, 0.5]), measured, LinkHealth("S"))
    with pytest.raises(RuntimeError, match="no status from the robot"):
        guard.GetOutputPort("command").Eval(context)  # nothing before a status

    fresh = LinkHealth("S", received=1, received_at=0.0)
    context = guard_context(guard, np.array([5.0, 0.5]), measured, fresh)
    simulator = Simulator(guard, context)
    simulator.AdvanceTo(0.1)  # ten updates towards a target beyond the limit
    command = guard.GetOutputPort("command").Eval(context)
    assert command[0] == pytest.approx(min(1.0, 10 * 2.0 * 0.01), abs=0.021) and command[0] <= 1.0
    assert np.all(np.isfinite(command)) and np.all(command >= lower) and np.all(command <= upper)
    guard.GetInputPort("desired").FixValue(context, np.array([np.nan, 0.0]))
    simulator.AdvanceTo(0.15)
    report = guard.GetOutputPort("report").Eval(context)
    assert report.rejected_commands >= 1 and np.all(np.isfinite(guard.GetOutputPort("command").Eval(context)))

    stale = dataclasses.replace(fresh, received_at=0.15, stale=True)
    guard.GetInputPort("status_health").FixValue(context, AbstractValue.Make(stale))
    guard.GetInputPort("measured").FixValue(context, np.array([0.3, 0.4]))
    guard.GetInputPort("desired").FixValue(context, np.array([-0.9, -0.9]))
    simulator.AdvanceTo(0.3)
    report = guard.GetOutputPort("report").Eval(context)
    assert report.holding and not report.tripped and report.holds == 1 and "holding" in report.message
    np.testing.assert_allclose(guard.GetOutputPort("command").Eval(context), [0.3, 0.4])  # holds, ignores desired

    # The status is back: on from the held position, velocity-limited.
    guard.GetInputPort("status_health").FixValue(
        context, AbstractValue.Make(dataclasses.replace(fresh, received_at=0.3))
    )
    simulator.AdvanceTo(0.35)
    report = guard.GetOutputPort("report").Eval(context)
    assert not report.holding and not report.tripped
    np.testing.assert_allclose(guard.GetOutputPort("command").Eval(context), [0.2, 0.3], atol=0.021)

    # Away longer than lost_after_s: tripped, holding for good.
    guard.GetInputPort("status_health").FixValue(
        context, AbstractValue.Make(dataclasses.replace(stale, received_at=0.35))
    )
    simulator.AdvanceTo(1.5)
    held = guard.GetOutputPort("command").Eval(context).copy()
    guard.GetInputPort("status_health").FixValue(
        context, AbstractValue.Make(dataclasses.replace(fresh, received_at=1.5))
    )
    simulator.AdvanceTo(1.6)
    report = guard.GetOutputPort("report").Eval(context)
    assert report.tripped and report.holds == 2 and report.message.endswith("for good")
    np.testing.assert_allclose(guard.GetOutputPort("command").Eval(context), held)


def test_no_driver_gives_a_clear_timeout_naming_the_channels(scenario):
    quick = dataclasses.replace(scenario, hardware=dataclasses.replace(scenario.hardware, status_timeout_s=0.2))
    with pytest.raises(RobotNotResponding, match="CENTAURO_STATUS.*robot_driver"):
        wait_for_robot(quick, DrakeLcm("memq://"))


class ScriptedBus:
    """Stands in for DrakeLcm in wait_for_robot: every HandleSubscriptions delivers the same messages."""

    def __init__(self, messages: dict[str, bytes]):
        self.messages, self.handlers = messages, {}

    def Subscribe(self, channel, handler):
        self.handlers[channel] = handler

    def HandleSubscriptions(self, timeout_ms):
        for channel, data in self.messages.items():
            self.handlers[channel](data)
        return len(self.messages)

    def get_lcm_url(self):
        return "scripted://"


def test_waiting_for_the_robot_counts_only_valid_messages(scenario):
    """A valid arm status beside garbage on the hand and camera channels is not a working robot."""
    config = dataclasses.replace(scenario.hardware, status_timeout_s=0.1)
    quick = dataclasses.replace(scenario, hardware=config)
    garbage = {c: b"garbage" for c in (config.left_hand_status_channel, config.right_hand_status_channel)}
    bus = ScriptedBus({config.arm_status_channel: status_message(np.zeros(15)).encode(), **garbage})
    with pytest.raises(RobotNotResponding, match="no valid message on CAMERA0_IMAGES, LEFT_HAND_STATUS, RIGHT_HAND"):
        wait_for_robot(quick, bus)


class FakeRobot:
    """Publishes arm and hand status on a memq bus by hand, to drive the hardware station alone."""

    def __init__(self, scenario, lcm, q):
        self.config, self.lcm, self.q = scenario.hardware, lcm, q

    def publish(self, arm=True):
        if arm:
            self.lcm.Publish(self.config.arm_status_channel, status_message(self.q).encode())
        hand = lcmt_schunk_wsg_status()
        hand.actual_position_mm = 100.0
        for channel in (self.config.left_hand_status_channel, self.config.right_hand_status_channel):
            self.lcm.Publish(channel, hand.encode())


def received_commands(lcm, channel):
    commands = []
    lcm.Subscribe(channel, lambda data: commands.append(lcmt_iiwa_command.decode(data)))
    return commands


def test_hardware_station_faults_end_in_a_safe_reported_state(scenario):
    lcm = DrakeLcm("memq://")
    station = MakeHardwareStation(scenario, lcm)
    q0 = initial_positions(scenario)
    robot = FakeRobot(scenario, lcm, q0)
    commands = received_commands(lcm, scenario.hardware.arm_command_channel)
    simulator = Simulator(station)
    context = simulator.get_mutable_context()
    station.GetInputPort("centauro.position").FixValue(context, q0 + 0.05)
    for hand in ("left_hand", "right_hand"):
        station.GetInputPort(f"{hand}.position").FixValue(context, [0.1])
    guard = station.GetSubsystemByName("centauro.command_guard")
    monitor = station.GetSubsystemByName("centauro.status")

    def step(until, arm=True, garbage=False):
        while context.get_time() < until - 1e-9:
            robot.publish(arm)
            if garbage:
                lcm.Publish(scenario.hardware.arm_status_channel, b"\xffgarbage")
            simulator.AdvanceTo(context.get_time() + 0.005)

    step(0.2)
    assert commands, "commands flow once a status has arrived"
    np.testing.assert_allclose(commands[-1].joint_position, q0 + 0.05, atol=1e-9)
    # A garbage message: dropped and counted, the last good status is kept.
    step(0.25, garbage=True)
    health = monitor.GetOutputPort("health").Eval(monitor.GetMyContextFromRoot(context))
    assert health.rejected >= 1 and not health.stale
    # A NaN command: rejected, the last good command is sent instead.
    station.GetInputPort("centauro.position").FixValue(context, np.full(15, np.nan))
    step(0.35)
    report = guard.GetOutputPort("report").Eval(guard.GetMyContextFromRoot(context))
    assert report.rejected_commands >= 1 and np.all(np.isfinite(commands[-1].joint_position))
    # A command beyond the joint limits is clamped.
    model = RobotModel(scenario)
    station.GetInputPort("centauro.position").FixValue(context, model.upper + 1.0)
    step(2.5)
    assert np.all(np.array(commands[-1].joint_position) <= model.upper + 1e-12)
    # The status stops mid-motion: the watchdog holds the last measured position.
    station.GetInputPort("centauro.position").FixValue(context, q0 - 0.3)
    step(3.0, arm=False)
    report = guard.GetOutputPort("report").Eval(guard.GetMyContextFromRoot(context))
    assert report.holding and not report.tripped and "no valid status on CENTAURO_STATUS" in report.message
    np.testing.assert_allclose(commands[-1].joint_position, np.clip(q0, model.lower, model.upper), atol=1e-9)


def test_driver_rejects_bad_commands_and_holds(scenario):
    lcm = DrakeLcm("memq://")
    driver = MakeRobotDriver(scenario, lcm)
    simulator = Simulator(driver)
    context = simulator.get_mutable_context()
    statuses = []
    lcm.Subscribe(scenario.hardware.arm_status_channel, lambda data: statuses.append(lcmt_iiwa_status.decode(data)))
    simulator.AdvanceTo(0.05)
    assert statuses, "the driver publishes its status from the start"
    bad = lcmt_iiwa_command()
    bad.num_joints, bad.joint_position = 15, [float("nan")] * 15
    lcm.Publish(scenario.hardware.arm_command_channel, bad.encode())
    simulator.AdvanceTo(0.1)
    lcm.Publish(scenario.hardware.arm_command_channel, b"garbage")
    simulator.AdvanceTo(0.3)
    monitor = driver.GetSubsystemByName("centauro.command")
    health = monitor.GetOutputPort("health").Eval(monitor.GetMyContextFromRoot(context))
    assert health.rejected == 2 and health.received == 0
    np.testing.assert_allclose(statuses[-1].joint_position_commanded, initial_positions(scenario))
    np.testing.assert_allclose(statuses[-1].joint_position_measured, initial_positions(scenario), atol=0.01)


def test_a_restarted_driver_goes_on_from_the_world_and_commands_its_predecessor_wrote(scenario, tmp_path):
    """A driver commanded to a new arm pose writes its state; a new driver built from that file holds the same
    command and stands in the same world at the same clock; a file that is not a driver's state is refused."""
    lcm = DrakeLcm("memq://")
    first = MakeRobotDriver(scenario, lcm)
    simulator = Simulator(first)
    command = lcmt_iiwa_command()
    q = np.array(initial_positions(scenario)) + 0.1
    command.num_joints, command.joint_position = len(q), q.tolist()
    simulator.AdvanceTo(0.1)
    lcm.Publish(scenario.hardware.arm_command_channel, command.encode())
    simulator.AdvanceTo(1.0)
    path = tmp_path / "state.json"
    write_driver_state(path, driver_state(first, simulator.get_context(), settled_state=None))
    saved = read_driver_state(path, scenario)
    np.testing.assert_allclose(saved.commands["centauro.command"], q)

    second = MakeRobotDriver(scenario, DrakeLcm("memq://"), commands=saved.commands)
    context = second.CreateDefaultContext()
    set_plant_state(second, context, saved.plant_state, saved.time_s)
    assert context.get_time() == pytest.approx(1.0)
    again = driver_state(second, context, None)
    np.testing.assert_allclose(again.plant_state, saved.plant_state)
    np.testing.assert_allclose(again.commands["centauro.command"], q)  # held until the pick commands again

    path.write_text('{"time_s": 1.0}')
    with pytest.raises(ValueError, match="not a robot driver's state file"):
        read_driver_state(path, scenario)


def test_the_pick_waits_for_a_robot_clock_behind_its_own_but_not_for_a_silent_robot():
    """RobotClock: pick time 0 lined up with the robot's 10 s; the pick's next step (0.05 s) waits for the robot's
    status of 10.05 s; a robot silent for quiet_after_s is not waited for; one back from a silence is lined up
    again."""
    lcm = DrakeLcm("memq://")
    clock = RobotClock(lcm, "STATUS", joints=2, quiet_after_s=0.5)

    def status(robot_s):
        lcm.Publish("STATUS", status_message([0.0, 0.0], utime=int(robot_s * 1e6), joints=2).encode())

    status(10.0)
    lcm.HandleSubscriptions(0)
    clock.line_up(0.0)
    status(10.05)  # (not yet handled)
    clock.wait_for(0.05)
    assert clock.robot_s == pytest.approx(10.05)
    clock.quiet_after_s = 0.0  # silent from now on
    clock.wait_for(0.5)  # not waited for
    assert clock.robot_s == pytest.approx(10.05) and clock.offset_s == pytest.approx(10.0)
    clock.quiet_after_s = 0.5
    status(10.1)  # back, while the pick's clock ran on to 5 s
    lcm.HandleSubscriptions(0)
    clock.wait_for(5.0)
    assert clock.offset_s == pytest.approx(10.1 - 5.0)


def test_a_driver_restart_asked_of_a_pick_without_a_spawned_driver_is_refused_by_name(scenario):
    faults = FaultConfig(driver_restart_after_objects=1)
    with pytest.raises(ValueError, match="driver_restart_after_objects is done to a spawned robot driver"):
        MakePickDiagram(dataclasses.replace(scenario, task="clear", faults=faults))


def _process_state(process: subprocess.Popen, states: str, within_s: float = 5.0) -> str:
    """The process's state letter from /proc (T: stopped), once it is one of `states` or `within_s` has passed (a
    signal is delivered when the kernel next schedules the process: on a loaded machine, not at once)."""
    deadline = time.monotonic() + within_s
    while True:
        state = Path(f"/proc/{process.pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        if state in states or time.monotonic() > deadline:
            return state
        time.sleep(0.01)


def test_a_spawned_drivers_faults_kill_and_restart_it_after_k_objects_and_freeze_it_in_the_carry():
    """SpawnedDriver on a stand-in process: killed and started again with --resume once an object is taken on;
    frozen 1 s into the first carry, for 2 s of pick time, then going on."""
    faults = FaultConfig(driver_restart_after_objects=1, status_gap_in_carry_after_s=1.0, status_gap_s=2.0)
    driver = lcm_pick.SpawnedDriver([sys.executable, "-c", "import time; time.sleep(120)"], faults)
    first = driver.process
    carrying = PickStatus(mode=Mode.CARRY, objects=(ClearedObject("watering_can", (0.6, 0.0), 1, cleared=True),))
    try:
        driver.on_sample(PickStatus(mode=Mode.REACH), 1.0)
        assert driver.process is first and first.poll() is None
        driver.on_sample(carrying, 5.0)
        assert first.poll() == -signal.SIGKILL and driver.process.args[-1] == "--resume"
        time.sleep(0.2)
        driver.on_sample(carrying, 6.0)
        assert _process_state(driver.process, "T") == "T"
        driver.on_sample(carrying, 7.9)
        time.sleep(0.2)
        assert _process_state(driver.process, "T", within_s=0.0) == "T"  # (still stopped)
        driver.on_sample(carrying, 8.1)
        assert _process_state(driver.process, "RS") in "RS"
        driver.on_sample(carrying, 20.0)  # (once)
        time.sleep(0.2)
        assert _process_state(driver.process, "RS", within_s=0.0) in "RS"
    finally:
        driver.process.kill()
        driver.process.wait()


@pytest.mark.slow
def test_autonomous_pick_through_lcm_in_process(scenario):
    outcome = run_pick(replace_object(scenario, category="drill", instance="test_1", yaw=0.25), backend="lcm-memq")
    assert outcome.success, outcome.message


# As root (CI), network namespaces must work: these tests then fail rather than skip.
needs_namespaces = pytest.mark.skipif(
    os.geteuid() != 0, reason="creating a private network namespace needs root (CI runs as root)"
)


@pytest.mark.slow
@needs_namespaces
def test_driver_across_processes_over_udp_in_a_private_namespace(tmp_path):
    """The driver in its own process; this side only waits for status and images, bounded in time."""
    client = f"""
import sys
from pydrake.lcm import DrakeLcm
from diagrams.hardware_station import wait_for_robot
from diagrams.scenario import load_scenario
lcm = DrakeLcm("{lcm_pick.NAMESPACE_LCM_URL}")
wait_for_robot(load_scenario(), lcm)
print("robot answered")
"""
    driver = f"{sys.executable} {REPO_ROOT / 'scripts' / 'robot_driver.py'} --duration 8 --lcm-url "
    driver += f"'{lcm_pick.NAMESPACE_LCM_URL}' --result {tmp_path / 'driver.json'}"
    script = f"{lcm_pick.NAMESPACE_SETUP} && ({driver} &) && {sys.executable} -c '{client}' && wait"
    done = subprocess.run(
        ["unshare", "-n", "sh", "-c", script], capture_output=True, text=True, timeout=240, cwd=REPO_ROOT
    )
    assert done.returncode == 0 and "robot answered" in done.stdout, done.stderr[-2000:]
    deadline = time.monotonic() + 60
    while not (tmp_path / "driver.json").is_file() and time.monotonic() < deadline:
        time.sleep(0.5)
    assert json.loads((tmp_path / "driver.json").read_text())["sim_time_s"] > 0


@pytest.mark.slow
@needs_namespaces
def test_a_clear_with_a_spawned_driver_killed_and_restarted_between_objects_clears_the_can(tmp_path):
    """The default scenario's unseen can cleared over LCM (its pick, lift, carry, set-down): the driver as a
    subprocess, both in one private loopback-only namespace; the driver killed (SIGKILL) once the can is in the zone
    and started again from its state; the pick waits for it and ends the clear. Judged by the driver's simulator."""
    report = tmp_path / "r.json"
    command = [sys.executable, "scripts/pick.py", "--backend", "lcm", "--spawn-driver", "--json", str(report)]
    command += ["--task", "clear", "--scenario_text", "{faults: {driver_restart_after_objects: 1}}"]
    done = subprocess.run(command, capture_output=True, text=True, timeout=800, cwd=REPO_ROOT)
    result = json.loads(report.read_text())
    assert done.returncode == 0 and result["success"], done.stdout[-3000:] + done.stderr[-3000:]
    assert "fault: the robot driver killed after 1 objects" in done.stderr
    assert "resuming from" in done.stderr and "the status on CENTAURO_STATUS is back" in done.stderr
    (can,) = result["clear"]["objects"]
    assert can["cleared"] and result["clear"]["taken_on"][0]["cleared"]
    assert result["backend"] == "lcm" and result["sensor"] == "kinect_v2"
    # The arm commands never stalled while the pick perceived and planned (0.3-3 s of compute; a 2.41 s gap
    # before the stream, then up to 105 ms while the real-time streamer waited for a preempted writer). Per-send
    # jitter is this VM's, not the pick's: every send within two control periods of the one before in 13 of 14
    # picks, but the VM alone wakes a lone real-time loop up to 27 ms late under load
    # (scripts/benchmark_command_stream.py), and with the driver also simulating the camera's sensor model one
    # of six picks here had 16 of 4265 sends late, the latest 35 ms; CI's loaded VM gave 14 ms on a lone stream.
    # So this guards against stalls (0.3-3 s): no gap over 50 periods (0.25 s), at most 1 % of the sends late. (A
    # bound of 20 periods failed once, 106 ms, with two evaluation workers sharing the VM's two cores.)
    commands, period = result["commands"], load_scenario().hardware.control_period_s
    assert commands["sent"] > 1000 and commands["late"] <= 0.01 * commands["sent"]
    assert commands["max_gap_s"] <= 50 * period
