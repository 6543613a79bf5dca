"""The arm command stream: a process of its own that sends the latest arm command every control period.

The pick diagram's process perceives and plans in discrete events; while it does (and while its
Python holds the interpreter lock in long library calls: up to 0.27 s measured for a thread), it
cannot publish. So the command the CommandGuard last produced is handed, through shared memory,
to a separate process that publishes it on the LCM bus every period, whatever the diagram's
process is doing. While the computer thinks the robot stands still, and the last command is
exactly its hold. The streamer sends nothing before the guard's first command, stops when told
or when its parent process is gone, and counts the largest gap between its own sends.

CommandStreamSender is the diagram's side: a LeafSystem that writes the command into the stream
every period.
"""

import argparse
import contextlib
import gc
import logging
import os
import subprocess
import sys
import time
import weakref
from multiprocessing import resource_tracker, shared_memory

import numpy as np
from pydrake.systems.framework import EventStatus, LeafSystem

# SCHED_FIFO priority of the streamer (1-99): above ordinary processes, below the kernel's own threads.
STREAM_RT_PRIORITY = 20
# Shared layout (float64): [version, stop, utime, max_gap_s, sends, late, q_0 .. q_n-1]; late: the sends more
# than two periods after the one before. The writer makes the version
# odd while it writes and even after (a sequence lock): the reader retries a torn read.
_VERSION, _STOP, _UTIME, _MAX_GAP, _SENDS, _LATE, _Q = range(7)


def _prepare_real_time():
    """What a robot's control loop does, as far as the OS allows (root on Linux), best effort (the figures
    say what it got): real-time scheduling (else a lower nice value), and no garbage collector pauses (the
    loop makes no reference cycles)."""
    gc.disable()
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(STREAM_RT_PRIORITY))
        return
    except (AttributeError, PermissionError, OSError):
        pass
    try:
        os.nice(-10)
    except (AttributeError, PermissionError, OSError):
        logging.info("the command stream runs at normal priority")


def _read(shared: np.ndarray, previous: np.ndarray | None, attempts: int = 3) -> np.ndarray | None:
    """A consistent copy of the shared command, or `previous` when the writer is in the middle of writing.
    Never waits for the writer: it runs at normal priority and may be preempted mid-write for tens of
    milliseconds, and a real-time reader spinning on it would stop the stream that long."""
    for _ in range(attempts):
        version = shared[_VERSION]
        values = shared.copy()
        if version % 2 == 0 and shared[_VERSION] == version:
            return values
    return previous


def stream(lcm_url: str, channel: str, joints: int, period_s: float, memory_name: str, parent: int):
    """The streamer process's loop: publishes lcmt_iiwa_command on `channel` every period_s."""
    from drake import lcmt_iiwa_command
    from pydrake.lcm import DrakeLcm

    _prepare_real_time()
    memory = shared_memory.SharedMemory(name=memory_name)
    # (Python < 3.13 registers an attached segment too, and would unlink it when this process ends: the owner,
    # CommandStream, unlinks it.)
    resource_tracker.unregister(memory._name, "shared_memory")
    shared = np.ndarray((_Q + joints,), np.float64, buffer=memory.buf)
    lcm = DrakeLcm(lcm_url)
    message = lcmt_iiwa_command()
    message.num_joints, message.num_torques, message.joint_torque = joints, 0, []
    deadline, last_send, values = time.monotonic(), None, None
    while shared[_STOP] == 0 and os.getppid() == parent:
        deadline += period_s
        delay = deadline - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        else:  # late (the machine is loaded): send now and keep the period from here
            deadline = time.monotonic()
        values = _read(shared, values)
        if values is None or values[_VERSION] == 0:
            continue  # no command yet: the guard has had no status from the robot
        message.utime = int(values[_UTIME])
        message.joint_position = list(values[_Q : _Q + joints])
        lcm.Publish(channel, message.encode())
        now = time.monotonic()
        if last_send is not None:
            shared[_MAX_GAP] = max(shared[_MAX_GAP], now - last_send)
            shared[_LATE] += now - last_send > 2 * period_s
        shared[_SENDS] += 1
        last_send = now
    del shared
    memory.close()


class CommandStream:
    """Owns the streamer process. Not started until start(); stop() ends it (so does this process ending)."""

    def __init__(self, lcm_url: str, channel: str, joints: int, period_s: float):
        self.lcm_url, self.channel, self.joints, self.period_s = lcm_url, channel, joints, period_s
        self._memory = shared_memory.SharedMemory(create=True, size=8 * (_Q + joints))
        self._shared = np.ndarray((_Q + joints,), np.float64, buffer=self._memory.buf)
        self._shared[:] = 0.0
        self._process: subprocess.Popen | None = None
        # Ends the streamer and frees the shared memory when this object goes, or at exit at the latest.
        self._processes: list[subprocess.Popen] = []
        weakref.finalize(self, _release, self._memory, self._processes)

    def start(self):
        if self._process is not None:
            return
        command = [sys.executable, "-m", "systems.robot_io.command_stream", self.lcm_url, self.channel,
                   str(self.joints), str(self.period_s), self._memory.name, str(os.getpid())]  # fmt: skip
        self._process = subprocess.Popen(command)
        self._processes.append(self._process)
        logging.info("%s: commands stream from process %d every %.1f ms", self.channel, self._process.pid,
                     1000 * self.period_s)  # fmt: skip

    @property
    def running(self) -> bool:
        return self._process is not None and self._process.poll() is None

    def stop(self):
        """Ends the streamer (waits for it); the figures stay readable."""
        self._shared[_STOP] = 1.0
        if self._process is not None:
            try:
                self._process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self._process.kill()

    def set(self, utime: int, positions: np.ndarray):
        """The command to send from now on (positions in rad)."""
        shared = self._shared
        shared[_VERSION] += 1  # odd: writing
        shared[_UTIME] = utime
        shared[_Q : _Q + self.joints] = positions
        shared[_VERSION] += 1

    @property
    def sends(self) -> int:
        return int(self._shared[_SENDS])

    @property
    def late_sends(self) -> int:
        """How many sends came more than two periods after the one before."""
        return int(self._shared[_LATE])

    @property
    def max_gap_s(self) -> float:
        """The largest time between two consecutive sends so far, s (0 before the second)."""
        return float(self._shared[_MAX_GAP])


def _release(memory: shared_memory.SharedMemory, processes: list[subprocess.Popen]):
    np.ndarray((_Q,), np.float64, buffer=memory.buf)[_STOP] = 1.0
    for process in processes:
        try:
            process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            process.kill()
    with contextlib.suppress(BufferError):  # (at exit, the stream's own view of it may still be alive)
        memory.close()
    memory.unlink()


class CommandStreamSender(LeafSystem):
    """Hands the guard's command to a CommandStream every period (nothing before the guard has one).

    .. pydrake_system::

        name: CommandStreamSender
        input_ports:
        - position

    ``position`` (n, rad): the command; its evaluation may raise while the guard has no status from the
    robot, and then nothing is handed on.
    """

    def __init__(self, stream: CommandStream, period_s: float, offset_s: float):
        super().__init__()
        self.stream = stream
        self.DeclareVectorInputPort("position", stream.joints)
        self.DeclarePeriodicPublishEvent(period_s, offset_s, self._send)
        self.DeclareForcedPublishEvent(self._send)

    def _send(self, context) -> EventStatus:
        try:
            positions = self.get_input_port().Eval(context)
        except RuntimeError:  # the guard: no status yet, nothing to send
            return EventStatus.DidNothing()
        self.stream.start()
        self.stream.set(int(context.get_time() * 1e6), positions)
        return EventStatus.Succeeded()


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="the arm command streamer (started by CommandStream)")
    for name in ("lcm_url", "channel", "joints", "period_s", "memory", "parent"):
        parser.add_argument(name)
    args = parser.parse_args()
    stream(args.lcm_url, args.channel, int(args.joints), float(args.period_s), args.memory, int(args.parent))
