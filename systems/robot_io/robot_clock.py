"""The robot's own clock, read off its arm status time stamps, so that a pick never runs ahead of its robot.

A real robot's clock runs in real time, and a pick that keeps real time never waits for it. A simulated robot behind
LCM (scripts/robot_driver.py) may run slower than real time on a busy computer (10 simulated seconds in 24-28 s,
its start included, on the project's 2-core VM, the camera's sensor model on): a pick on wall-clock time would then
play its trajectories faster than the robot lives them, every move squeezed into less of the robot's time. Like a
ROS node on a simulator's /clock, the pick's simulator waits after each of its steps until the robot's clock has
reached it (diagrams/lcm_pick.py: a simulator monitor), so each command goes out when the robot is at its time.

It waits only on a robot that speaks: once no status has arrived for `quiet_after_s` (wall time), the pick goes on
in real time and its watchdog handles the silence. When the status is back from a silence (a driver restarted,
its clock where it last wrote its state), the two clocks are lined up again.
"""

import contextlib
import math
import time

from pydrake.lcm import DrakeLcmInterface

from systems.robot_io.lcm_messages import MalformedMessage, RawMessage, decode_arm_status

# The pick's clock more than this ahead of the robot's: the robot was away; the clocks are lined up again, s.
RESYNC_AHEAD_S = 1.0


class RobotClock:
    """Follows the robot's clock (s) on the arm status channel of `lcm` (which the caller's loop also handles)."""

    def __init__(self, lcm: DrakeLcmInterface, channel: str, joints: int, quiet_after_s: float):
        self.lcm, self.joints, self.quiet_after_s = lcm, joints, quiet_after_s
        self.robot_s = -math.inf  # the last valid status's time stamp, s
        self.received_at = -math.inf  # when it arrived (time.monotonic()), s
        self.offset_s = math.nan  # the robot's clock minus the pick's, set by line_up
        self.waited_s = 0.0  # wall time spent waiting for the robot, all together
        lcm.Subscribe(channel, self._receive)

    def _receive(self, data: bytes):
        with contextlib.suppress(MalformedMessage):
            utime, _ = decode_arm_status(RawMessage(data, 0), self.joints)
            self.robot_s, self.received_at = utime / 1e6, time.monotonic()

    def line_up(self, pick_s: float):
        """The robot's clock now corresponds to pick time pick_s."""
        self.offset_s = self.robot_s - pick_s

    def wait_for(self, pick_s: float):
        """Returns once the robot's clock has reached pick time pick_s, or at once while the robot is silent."""
        if math.isnan(self.offset_s):
            raise RuntimeError("RobotClock.wait_for before line_up")
        if pick_s + self.offset_s - self.robot_s > RESYNC_AHEAD_S and self._speaking():
            self.line_up(pick_s)  # back from a silence
        started = time.monotonic()
        while self.robot_s < pick_s + self.offset_s and self._speaking():
            self.lcm.HandleSubscriptions(1)
        self.waited_s += time.monotonic() - started

    def _speaking(self) -> bool:
        return time.monotonic() - self.received_at < self.quiet_after_s
