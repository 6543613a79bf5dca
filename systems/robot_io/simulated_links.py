"""The health of the simulated station's links, reported as an LCM MessageMonitor reports a robot's (LinkHealth):
always fresh (FreshLink), or, to test the pick through silent links, silent for a while (the faults, simulation
only: the robot's status, or the camera's images, stop and then come back).

A fault passes its link through; while the link is silent, the last values are repeated and the health goes stale
`stale_after_s` after the last one.
"""

import math

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from systems.messages import Mode, PickStatus
from systems.robot_io.lcm_safety import LinkHealth


class FreshLink(LeafSystem):
    """A simulated link's health: always fresh, its last message received now.

    .. pydrake_system::

        name: FreshLink
        output_ports:
        - health
    """

    def __init__(self, channel: str):
        super().__init__()
        self.channel = channel
        self.DeclareAbstractOutputPort("health", lambda: AbstractValue.Make(LinkHealth()), self._calc)

    def _calc(self, context, output):
        output.set_value(LinkHealth(self.channel, 1, received_at=context.get_time()))


class _LinkGap(LeafSystem):
    """A link silent for `duration_s` from a start its subclass chooses (_starts); outputs `health`."""

    def __init__(self, channel: str, duration_s: float, stale_after_s: float, period_s: float):
        super().__init__()
        if duration_s <= 0 or stale_after_s < 0:
            raise ValueError(f"a gap lasts duration_s > 0 and goes stale after stale_after_s >= 0, not "
                             f"{duration_s}, {stale_after_s}")  # fmt: skip
        self.channel, self.duration_s, self.stale_after_s = channel, duration_s, stale_after_s
        self._start_s = self.DeclareDiscreteState([math.nan])  # when the link went silent (NaN: not yet), s
        self.DeclareAbstractOutputPort("health", lambda: AbstractValue.Make(LinkHealth()), self._calc_health)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._update)

    def _update(self, context, state) -> EventStatus:
        if not math.isnan(self.start_s(context)) or not self._starts(context):
            return EventStatus.DidNothing()
        state.get_mutable_discrete_state(self._start_s).set_value([context.get_time()])
        self._hold(context, state)
        return EventStatus.Succeeded()

    def start_s(self, context) -> float:
        return context.get_discrete_state(self._start_s).get_value()[0]

    def silent(self, context) -> bool:
        """Whether the link is silent now."""
        start_s = self.start_s(context)
        return start_s <= context.get_time() < start_s + self.duration_s  # (False while start_s is NaN)

    def _calc_health(self, context, output):
        t = context.get_time()
        received_at = self.start_s(context) if self.silent(context) else t
        stale = t - received_at > self.stale_after_s
        output.set_value(LinkHealth(self.channel, 1, received_at=received_at, stale=stale))

    def _starts(self, context) -> bool:
        raise NotImplementedError

    def _hold(self, context, state):
        """Keeps the link's last values in `state`, to repeat while it is silent."""
        raise NotImplementedError


class StatusGapFault(_LinkGap):
    """The robot's status stops for `duration_s`, `after_s` into the first carry of the first attempt at the first
    object.

    .. pydrake_system::

        name: StatusGapFault
        input_ports:
        - position_measured
        - status
        output_ports:
        - position_measured
        - health

    ``position_measured`` (n, rad) in and out (the last one before the gap repeated during it); ``status``
    (PickStatus, the supervisor's); ``health`` (LinkHealth).
    """

    def __init__(self, after_s: float, duration_s: float, stale_after_s: float, num_joints: int = 14,
                 period_s: float = 0.01):  # fmt: skip
        super().__init__("robot status", duration_s, stale_after_s, period_s)
        self.after_s = after_s
        self.measured_port = self.DeclareVectorInputPort("position_measured", num_joints)
        self.status_port = self.DeclareAbstractInputPort("status", AbstractValue.Make(PickStatus()))
        self._held = self.DeclareDiscreteState(num_joints)
        self.DeclareVectorOutputPort("position_measured", BasicVector(num_joints), self._calc_measured)

    def _starts(self, context) -> bool:
        status = self.status_port.Eval(context)
        carrying = status.mode == Mode.CARRY and status.attempt == 1 and not status.objects
        return carrying and context.get_time() >= status.phase_start_s + self.after_s

    def _hold(self, context, state):
        state.get_mutable_discrete_state(self._held).set_value(self.measured_port.Eval(context))

    def _calc_measured(self, context, output):
        if self.silent(context):
            output.SetFromVector(context.get_discrete_state(self._held).get_value())
        else:
            output.SetFromVector(self.measured_port.Eval(context))


class CameraGapFault(_LinkGap):
    """The camera's images stop for `duration_s` from context time `at_s`.

    .. pydrake_system::

        name: CameraGapFault
        input_ports:
        - color_image
        - depth_image
        output_ports:
        - color_image
        - depth_image
        - health

    The images in and out (the last ones before the gap repeated during it); ``health`` (LinkHealth).
    """

    def __init__(self, at_s: float, duration_s: float, stale_after_s: float, period_s: float = 0.01):
        super().__init__("camera images", duration_s, stale_after_s, period_s)
        self.at_s = at_s
        self._held = []  # (separate states: Drake copies its own image types natively)
        for index, (name, model) in enumerate((("color_image", ImageRgba8U()), ("depth_image", ImageDepth32F()))):
            self.DeclareAbstractInputPort(name, AbstractValue.Make(model))
            self._held.append(self.DeclareAbstractState(AbstractValue.Make(model)))
            self.DeclareAbstractOutputPort(name, lambda model=model: AbstractValue.Make(model), self._image_calc(index))

    def _starts(self, context) -> bool:
        return context.get_time() >= self.at_s

    def _hold(self, context, state):
        for index, held in enumerate(self._held):
            state.get_mutable_abstract_state(held).SetFrom(AbstractValue.Make(self.get_input_port(index).Eval(context)))

    def _image_calc(self, index: int):
        """The calc of image output `index` (0 colour, 1 depth)."""

        def calc(context, output):
            if self.silent(context):
                output.set_value(context.get_abstract_state(self._held[index]).get_value())
            else:
                output.set_value(self.get_input_port(index).Eval(context))

        return calc
