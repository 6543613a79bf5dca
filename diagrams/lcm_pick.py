"""Runs the pick diagram on the LCM backend: against a robot, or against a spawned robot driver.

run_on_robot: the hardware station against whatever answers on the bus (no ground truth).
run_with_spawned_driver: scripts/robot_driver.py as a subprocess on a UDP multicast bus,
judged by the driver's own simulator at the end. Multicast must not leave the machine: call
it inside a private network namespace with only loopback (rerun_in_private_namespace).
"""

import json
import logging
import math
import os
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

from pydrake.geometry import Meshcat
from pydrake.lcm import DrakeLcm, DrakeLcmInterface
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, EventStatus

from diagrams.autonomous_pick import (
    PERCEIVE_AT_S,
    MakePickDiagram,
    PickReport,
    PickWatcher,
    attempt_failures,
    max_time_s,
    pick_report,
    taken_on,
)
from diagrams.hardware_station import command_stream, wait_for_robot
from diagrams.paths import REPO_ROOT
from diagrams.pick_simulation import SAMPLE_S, PickOutcome
from diagrams.scenario import FaultConfig, Scenario, planned_joints
from systems.messages import Mode, PickStatus
from systems.robot_io.lcm_safety import CommandGuard, MessageMonitor
from systems.robot_io.robot_clock import RobotClock

# The bus inside the private namespace: loopback multicast, never routed (ttl=0).
NAMESPACE_LCM_URL = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304"
NAMESPACE_SETUP = (
    "ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo"
    # Room for the camera's large messages (per namespace on recent kernels; best effort).
    " && (sysctl -qw net.core.rmem_max=8388608 net.core.rmem_default=8388608 2>/dev/null || true)"
)
# After the plan, the robot holds at least this long on its own clock, s.
ROBOT_HOLD_S = 2.5
# A spawned driver needs a few seconds to start (imports, model, renderer).
DRIVER_START_TIMEOUT_S = 60.0
# The spawned driver simulates the robot and renders and noises each camera frame in one loop: its status stops
# while it does (about 0.2 s a frame on the project's 2-core VM, the driver alone; longer while the pick perceives
# beside it), where a real robot's controller streams on. Its status is watched this long before the guard trips.
SPAWNED_DRIVER_WATCHDOG_S = 1.0
# With a driver restart injected (faults.driver_restart_after_objects), the robot's status may stop this long: a
# new driver process takes 4.4 s to start alone on the project's 2-core VM, about 5 s beside the pick (measured).
DRIVER_RESTART_LOST_S = 30.0


@dataclass
class RobotRun:
    """What a pick against a robot on the bus saw (nothing judged: there is no ground truth)."""

    report: PickReport  # the supervisor's final status, the stages' times, the closure deviations
    problems: list[str] = field(default_factory=list)  # safety problems: tripped watchdogs, rejected messages
    # On a real bus, the arm commands' figures: {"sent": n, "max_gap_s": s, "late": sends more than two periods
    # after the one before}; {} on memq://.
    commands: dict = field(default_factory=dict)


def run_pick_on_robot(
    scenario: Scenario,
    lcm: DrakeLcmInterface | None = None,
    meshcat: Meshcat | None = None,
    on_sample: Callable[[PickStatus, float], None] | None = None,
) -> RobotRun:
    """Runs the pick diagram in real time, never ahead of the robot's clock (RobotClock), against a robot (or
    scripts/robot_driver.py) over LCM; on_sample(status, t) after every SAMPLE_S step (the supervisor's status, the
    pick's time in s).

    Raises:
        RobotNotResponding: no status or images within scenario.hardware.status_timeout_s.
    """
    lcm = lcm or DrakeLcm(scenario.lcm)
    diagram = MakePickDiagram(scenario, meshcat, hardware=True, lcm=lcm)
    station = diagram.GetSubsystemByName("station")
    config = scenario.hardware
    robot_clock = RobotClock(lcm, config.arm_status_channel, len(planned_joints(scenario)), config.watchdog_s)
    logging.info("waiting for the robot on %s", lcm.get_lcm_url())
    wait_for_robot(scenario, lcm, robot_time_s=PERCEIVE_AT_S)  # a simulated scene has settled by then
    simulator = Simulator(diagram)
    simulator.set_target_realtime_rate(1.0)
    context = simulator.get_mutable_context()
    watch = PickWatcher(diagram, max_time_s=max_time_s(scenario))
    simulator.Initialize()
    robot_clock.line_up(context.get_time())

    def keep_behind_the_robot(root_context) -> EventStatus:
        """After every step: the pick never runs ahead of a robot slower than real time (RobotClock)."""
        robot_clock.wait_for(root_context.get_time())
        return EventStatus.Succeeded()

    simulator.set_monitor(keep_behind_the_robot)
    tripped, problems, commands = False, [], {}
    stream = command_stream(station)
    try:
        while context.get_time() + SAMPLE_S <= watch.end_time(context) + 1e-9:
            started = time.monotonic()
            simulator.AdvanceTo(context.get_time() + SAMPLE_S)
            if time.monotonic() - started > 2 * SAMPLE_S:
                # The robot held while we perceived or planned: do not replay the lost wall time faster than
                # real time.
                simulator.ResetStatistics()
            if on_sample is not None:
                on_sample(watch.status(context), context.get_time())
            tripped, problems = safety_problems(station, context)
            if tripped:
                logging.error("stopping: %s", "; ".join(problems))
                break
        if not tripped:
            _hold_while_the_robot_catches_up(simulator, robot_clock)
    finally:
        logging.info("waited %.1f s of wall time for the robot's clock", robot_clock.waited_s)
        if stream is not None:
            stream.stop()
            commands = {"sent": stream.sends, "max_gap_s": stream.max_gap_s, "late": stream.late_sends}
            logging.info("arm commands: %d sent, %d more than two periods after the one before, largest gap %.1f ms",
                         stream.sends, stream.late_sends, 1000 * stream.max_gap_s)  # fmt: skip
    return RobotRun(pick_report(diagram, context), problems, commands)


def _hold_while_the_robot_catches_up(simulator: Simulator, robot_clock: RobotClock, timeout_s: float = 60.0):
    """Keeps commanding the final hold until the robot's own clock has run ROBOT_HOLD_S past the moment the plan
    ended here: a robot (or a driver) slower than real time has then also held the object that long."""
    context = simulator.get_context()
    target, deadline = robot_clock.robot_s + ROBOT_HOLD_S, time.monotonic() + timeout_s
    while robot_clock.robot_s < target and time.monotonic() < deadline:
        simulator.AdvanceTo(context.get_time() + SAMPLE_S)


def safety_problems(station: Diagram, context) -> tuple[bool, list[str]]:
    """What the hardware station's monitors and guards report: (a watchdog tripped, the problems in words)."""
    tripped, problems = False, []
    for system in station.GetSystems():
        system_context = system.GetMyContextFromRoot(context)
        if isinstance(system, CommandGuard):
            report = system.GetOutputPort("report").Eval(system_context)
            tripped |= report.tripped
            if report.tripped:
                problems.append(f"watchdog: {report.message}")
            if report.rejected_commands:
                problems.append(f"{system.get_name()}: {report.rejected_commands} non-finite commands rejected")
        elif isinstance(system, MessageMonitor):
            health = system.GetOutputPort("health").Eval(system_context)
            if health.rejected:
                problems.append(
                    f"{health.channel}: {health.rejected} malformed messages rejected ({health.last_error})"
                )
    return tripped, problems


def run_on_robot(scenario: Scenario, lcm_url: str | None = None, meshcat: Meshcat | None = None) -> PickOutcome:
    """The pick against a robot on the bus; success means the plan was played out with no safety problem."""
    lcm = DrakeLcm(lcm_url) if lcm_url else DrakeLcm(scenario.lcm)
    return _outcome(run_pick_on_robot(scenario, lcm, meshcat), scenario.task)


def _outcome(run: RobotRun, task: str) -> PickOutcome:
    report, problems, status = run.report, run.problems, run.report.status
    played = status.mode == Mode.DONE
    message = (
        status.message if status.mode == Mode.FAILED else ("plan played out" if played else f"stopped in {status.mode}")
    )
    if problems:
        message += "; " + "; ".join(problems)
    outcome = PickOutcome(played and not problems, math.nan, math.nan, message=message)
    outcome.stages, outcome.failed_stage = report.stages, status.failed_stage
    outcome.attempts_made, outcome.attempt_failures = status.attempt, attempt_failures(status)
    outcome.planning_s = report.stages.get("image_to_trajectory", 0.0)
    outcome.closure = report.closure
    outcome.commands = run.commands
    if task == "clear":  # what the robot made of each object it took on (where they ended is the driver's to judge)
        outcome.clear = {"taken_on": [taken_on(done) for done in status.objects], "summary": status.message}
    return outcome


def namespaces_available() -> bool:
    """Whether this process may create a private network namespace (root, unshare and ip present)."""
    if os.geteuid() != 0 or not shutil.which("unshare") or not shutil.which("ip"):
        return False
    probe = subprocess.run(["unshare", "-n", "sh", "-c", NAMESPACE_SETUP], capture_output=True, timeout=10)
    return probe.returncode == 0


def rerun_in_private_namespace(argv: list[str]) -> int:
    """Runs this command again (with --in-namespace) inside a new loopback-only network namespace."""
    command = shlex.join([sys.executable, *argv, "--in-namespace"])
    logging.info("entering a private network namespace (loopback only)")
    return subprocess.call(["unshare", "-n", "sh", "-c", f"{NAMESPACE_SETUP} && exec {command}"])


class SpawnedDriver:
    """scripts/robot_driver.py as a subprocess (`command`), and the faults done to it, as a robot's driver fails:

    - faults.driver_restart_after_objects = k: once k objects are taken on, the driver is killed (SIGKILL) and a new
      one started from the state it last wrote (--resume);
    - faults.status_gap_in_carry_after_s = a: that long into the first carry (pick time), the driver is frozen
      (SIGSTOP) for faults.status_gap_s: its status and images stop, its world waits, then it goes on (SIGCONT).
    """

    def __init__(self, command: list[str], faults: FaultConfig):
        self.command, self.faults = command, faults
        self.process = subprocess.Popen(command)
        self.restarted = self.frozen = self.freeze_done = False
        self.frozen_s: tuple[float, float] | None = None  # the freeze's start and end, pick time, s

    def on_sample(self, status: PickStatus, t: float):
        """Injects the faults due at pick time t (s), the supervisor's status given."""
        if self.faults.driver_restart_after_objects and not self.restarted:
            self._restart_after_objects(len(status.objects))
        if self.faults.status_gap_in_carry_after_s >= 0:
            self._freeze_in_the_carry(status.mode, t)

    def _restart_after_objects(self, taken_on: int):
        if taken_on >= self.faults.driver_restart_after_objects:
            logging.warning(
                "fault: the robot driver killed after %d objects; starting it again from its state", taken_on
            )
            self.process.kill()
            self.process.wait()
            self.process, self.restarted = subprocess.Popen([*self.command, "--resume"]), True

    def _freeze_in_the_carry(self, mode: Mode, t: float):
        if self.frozen_s is None and mode == Mode.CARRY:  # (the first carry: when to freeze, when to go on)
            start = t + self.faults.status_gap_in_carry_after_s
            self.frozen_s = (start, start + self.faults.status_gap_s)
        if self.frozen_s is None or self.freeze_done:
            return
        start, end = self.frozen_s
        if not self.frozen and t >= start:
            logging.warning("fault: the robot driver frozen for %.1f s in the carry", self.faults.status_gap_s)
            self.process.send_signal(signal.SIGSTOP)
            self.frozen = True
        elif self.frozen and t >= end:
            self.process.send_signal(signal.SIGCONT)
            self.frozen, self.freeze_done = False, True

    def stop(self):
        """Asks the driver to stop (it writes its result), kills it after a minute."""
        self.process.send_signal(signal.SIGCONT)
        self.process.send_signal(signal.SIGTERM)
        try:
            self.process.wait(timeout=60)
        except subprocess.TimeoutExpired:
            self.process.kill()


def run_with_spawned_driver(scenario: Scenario, driver_arguments: list[str]) -> PickOutcome:
    """Starts scripts/robot_driver.py on NAMESPACE_LCM_URL, runs the pick against it, then stops it;
    the lift (or the clear) is judged by the driver's simulator (its --result file). The faults of SpawnedDriver
    are done to the driver's process (the pick's diagram has none)."""
    if not _only_loopback():
        raise RuntimeError("refusing to use UDP multicast outside a private loopback-only network namespace")
    faults = scenario.faults
    lost_s = max(scenario.hardware.status_lost_s, DRIVER_RESTART_LOST_S if faults.driver_restart_after_objects else 0)
    scenario = replace(
        scenario,
        hardware=replace(
            scenario.hardware,
            status_timeout_s=max(scenario.hardware.status_timeout_s, DRIVER_START_TIMEOUT_S),
            watchdog_s=max(scenario.hardware.watchdog_s, SPAWNED_DRIVER_WATCHDOG_S),
            status_lost_s=lost_s,
        ),
        faults=replace(faults, status_gap_in_carry_after_s=-1.0, driver_restart_after_objects=0),  # (the driver's)
    )
    with tempfile.TemporaryDirectory() as folder:
        result, state = Path(folder) / "driver.json", Path(folder) / "driver_state.json"
        command = [sys.executable, str(REPO_ROOT / "scripts" / "robot_driver.py"), *driver_arguments]
        command += ["--lcm-url", NAMESPACE_LCM_URL, "--result", str(result), "--state", str(state)]
        driver = SpawnedDriver(command, faults)
        try:
            run = run_pick_on_robot(scenario, DrakeLcm(NAMESPACE_LCM_URL), on_sample=driver.on_sample)
        finally:
            driver.stop()
        outcome = _outcome(run, scenario.task)
        if not result.is_file():
            outcome.success, outcome.message = False, f"{outcome.message}; the driver wrote no result"
            return outcome
        judged = json.loads(result.read_text())
    outcome.success = outcome.success and judged["success"]
    outcome.lift_height_m, outcome.min_hold_height_m = judged["lift_height_m"], judged["min_hold_height_m"]
    outcome.hands_in_contact = judged["hands_in_contact"]
    outcome.clear = {**(judged.get("clear") or {}), **outcome.clear}  # a clear's judgement (diagrams/clear_judge.py)
    outcome.message = f"{judged['message']} (judged by the driver); pick: {outcome.message}"
    return outcome


def _only_loopback() -> bool:
    """True when the only network interface is lo (inside the private namespace)."""
    return [name for _, name in socket.if_nameindex()] == ["lo"]
