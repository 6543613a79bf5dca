"""Safety between a diagram and a robot on LCM: checked reception, watchdog, and a command guard.

MessageMonitor takes a subscriber's RawMessage, decodes it with checks (systems/robot_io/lcm_messages.py),
keeps the last valid values, counts the rejected messages, and reports the link's health:
whether anything valid has arrived and whether it has gone stale (nothing valid for longer
than `stale_after_s`).

CommandGuard stands between a controller and the command publisher: it sends nothing
before the robot's status has arrived, clamps every command to the joint position limits
and its change to the velocity limits, rejects non-finite commands (holding the last good
one), and while the status is stale it holds the position measured last; once the status
returns it goes on from there (velocity-limited), unless the status stayed away longer than
`lost_after_s`: then it trips, and holds for good.
"""

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from systems.robot_io.lcm_messages import MalformedMessage, RawMessage

# How many rejected messages of one link are logged (all are counted).
LOGGED_REJECTIONS = 5


@dataclass
class LinkHealth:
    """What a MessageMonitor knows about its channel. Times are context seconds."""

    channel: str = ""
    received: int = 0  # valid messages taken in
    rejected: int = 0  # malformed messages dropped
    last_error: str = ""
    received_at: float = -math.inf  # when the last valid message was taken in
    utime: int = 0  # the sender's timestamp of the last valid message, microseconds
    stale: bool = False  # something arrived once, but nothing valid for longer than stale_after_s


@dataclass
class _Reception:
    health: LinkHealth
    sequence: int = 0  # of the last RawMessage looked at
    values: object = None  # the last valid decoded values


class MessageMonitor(LeafSystem):
    """Decodes a channel's latest message and watches the link.

    .. pydrake_system::

        name: MessageMonitor
        input_ports:
        - raw
        output_ports:
        - values
        - health

    Input ``raw`` (RawMessage from an LcmSubscriberSystem); outputs ``values`` (the decoded vector; absent
    where ``default`` is None) and ``health`` (LinkHealth).

    Args:
        channel: for messages and the health report.
        decode: RawMessage -> (utime, values); raises MalformedMessage.
        default: the `values` output before any valid message (a vector of the output's size),
            or None for a monitor whose subclass declares its own outputs.
        stale_after_s: the watchdog period.
        period_s: how often the subscriber's latest message is looked at.
    """

    def __init__(
        self,
        channel: str,
        decode: Callable[[RawMessage], tuple[int, object]],
        default: np.ndarray | None,
        stale_after_s: float,
        period_s: float,
    ):
        super().__init__()
        self.channel, self.decode, self.stale_after_s = channel, decode, stale_after_s
        self.raw_port = self.DeclareAbstractInputPort("raw", AbstractValue.Make(RawMessage()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(_Reception(LinkHealth(channel), 0, default)))
        if default is not None:
            self.DeclareVectorOutputPort("values", BasicVector(len(default)), self._calc_values)
        self.DeclareAbstractOutputPort("health", lambda: AbstractValue.Make(LinkHealth()), self._calc_health)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._take_in)

    def _take_in(self, context, state) -> EventStatus:
        raw = self.raw_port.Eval(context)
        reception = context.get_abstract_state(self._state).get_value()
        if raw.sequence == reception.sequence:
            return EventStatus.DidNothing()
        health = reception.health
        try:
            utime, values = self.decode(raw)
        except MalformedMessage as error:
            if health.rejected < LOGGED_REJECTIONS:
                logging.warning("%s: rejected a message: %s", self.channel, error)
            health = replace(health, rejected=health.rejected + 1, last_error=str(error))
            values = reception.values
        else:
            health = replace(health, received=health.received + 1, received_at=context.get_time(), utime=utime)
        state.get_mutable_abstract_state(self._state).set_value(_Reception(health, raw.sequence, values))
        return EventStatus.Succeeded()

    def reception(self, context) -> _Reception:
        return context.get_abstract_state(self._state).get_value()

    def _calc_values(self, context, output):
        output.SetFromVector(self.reception(context).values)

    def _calc_health(self, context, output):
        health = self.reception(context).health
        stale = health.received > 0 and context.get_time() - health.received_at > self.stale_after_s
        output.set_value(replace(health, stale=stale))


class ImageMonitor(MessageMonitor):
    """A MessageMonitor of an lcmt_image_array: outputs `color_image` (ImageRgba8U) and
    `depth_image` (ImageDepth32F, m), empty before the first valid message."""

    def __init__(self, channel: str, decode, stale_after_s: float, period_s: float):
        super().__init__(channel, decode, None, stale_after_s, period_s)
        self.DeclareAbstractOutputPort("color_image", lambda: AbstractValue.Make(ImageRgba8U()), self._calc_color)
        self.DeclareAbstractOutputPort("depth_image", lambda: AbstractValue.Make(ImageDepth32F()), self._calc_depth)

    def _calc_color(self, context, output):
        output.set_value(_image(ImageRgba8U, self.reception(context).values, "color"))

    def _calc_depth(self, context, output):
        output.set_value(_image(ImageDepth32F, self.reception(context).values, "depth"))


def _image(image_type, images: dict | None, name: str):
    if not images:
        return image_type()
    pixels = images[name]
    image = image_type(pixels.shape[1], pixels.shape[0])
    image.mutable_data[:] = pixels
    return image


@dataclass
class GuardReport:
    armed: bool = False  # a status has arrived and commands flow
    holding: bool = False  # the status is stale: holding the position measured last
    holds: int = 0  # how often it held (each a stale status that returned, or the last one)
    tripped: bool = False  # the status stayed stale longer than lost_after_s: holding, for good
    rejected_commands: int = 0  # non-finite commands dropped
    message: str = "waiting for the robot's status"
    command: np.ndarray | None = field(default=None, repr=False)  # what is sent; None before a status


class CommandGuard(LeafSystem):
    """Passes on only safe commands (see the module docstring).

    .. pydrake_system::

        name: CommandGuard
        input_ports:
        - desired
        - measured
        - status_health
        output_ports:
        - command
        - report

    Inputs ``desired`` (n), ``measured`` (n, the robot's status), ``status_health`` (LinkHealth). Outputs
    ``command`` (n): safe; ``report`` (GuardReport).

    The `command` output raises (so nothing is published) while no status has arrived:
    publish it with an offset of a few periods after the status wait.

    Args:
        lower, upper: position limits (n). velocity_limits: (n) per second.
        period_s: the guard's update period; each update moves the command by at most
            velocity_limits * period_s.
        lost_after_s: a status stale for longer (since its last valid message) trips the guard, s.
    """

    def __init__(
        self, lower, upper, velocity_limits, period_s: float, name: str = "robot", lost_after_s: float = math.inf
    ):
        super().__init__()
        self.lost_after_s = lost_after_s
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        self.max_step = np.asarray(velocity_limits, float) * period_s
        self.name = name
        n = len(self.lower)
        self._desired = self.DeclareVectorInputPort("desired", n)
        self._measured = self.DeclareVectorInputPort("measured", n)
        self._health = self.DeclareAbstractInputPort("status_health", AbstractValue.Make(LinkHealth()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(GuardReport()))
        self.DeclareVectorOutputPort("command", BasicVector(n), self._calc_command)
        self.DeclareAbstractOutputPort("report", lambda: AbstractValue.Make(GuardReport()), self._calc_report)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._update)

    def _update(self, context, state) -> EventStatus:
        report = context.get_abstract_state(self._state).get_value()
        health = self._health.Eval(context)
        if report.tripped or health.received == 0:
            return EventStatus.DidNothing()
        measured = np.clip(self._measured.Eval(context), self.lower, self.upper)
        if health.stale:
            age = context.get_time() - health.received_at
            message = f"{self.name}: no valid status on {health.channel} for {age:.3f} s: holding position"
            if age > self.lost_after_s:
                logging.error("%s, for good", message)
                held = report.command if report.holding else measured
                report = replace(report, tripped=True, message=f"{message}, for good", command=held)
            elif not report.holding:
                logging.warning(message)
                report = replace(report, holding=True, holds=report.holds + 1, message=message, command=measured)
            else:
                return EventStatus.DidNothing()
        else:
            if report.holding:
                logging.warning("%s: the status on %s is back: commanding again", self.name, health.channel)
                report = replace(report, holding=False)
            last = report.command if report.armed else measured
            desired = self._desired.Eval(context)
            if not np.all(np.isfinite(desired)):
                if report.armed:  # (before, the controller has had no status to start from either)
                    if report.rejected_commands < LOGGED_REJECTIONS:
                        logging.warning("%s: rejected a non-finite command", self.name)
                    report = replace(report, rejected_commands=report.rejected_commands + 1)
                desired = last
            step = np.clip(np.clip(desired, self.lower, self.upper) - last, -self.max_step, self.max_step)
            report = replace(report, armed=True, message="commanding", command=last + step)
        state.get_mutable_abstract_state(self._state).set_value(report)
        return EventStatus.Succeeded()

    def _calc_command(self, context, output):
        report = context.get_abstract_state(self._state).get_value()
        if report.command is None:
            raise RuntimeError(f"{self.name}: no status from the robot yet, so no command is sent")
        output.SetFromVector(report.command)

    def _calc_report(self, context, output):
        output.set_value(context.get_abstract_state(self._state).get_value())
