"""A fault injected to test the drop check (simulation only): both hands open in the middle of a carry."""

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem

from systems.messages import OPEN_WIDTH, Mode, PickStatus


class HandDropFault(LeafSystem):
    """Passes the hands' commanded width through, except during the first carry of the first attempt at the first
    object, from ``after_s`` into it on: then the hands open (OPEN_WIDTH) and the object drops.

    .. pydrake_system::

        name: HandDropFault
        input_ports:
        - width
        - status
        output_ports:
        - width

    ``width`` (1, m) in and out; ``status`` (PickStatus, the supervisor's).
    """

    def __init__(self, after_s: float):
        super().__init__()
        if after_s < 0:
            raise ValueError(f"the drop comes after_s >= 0 into the carry, not {after_s}")
        self.after_s = after_s
        self.width_port = self.DeclareVectorInputPort("width", 1)
        self.status_port = self.DeclareAbstractInputPort("status", AbstractValue.Make(PickStatus()))
        self.DeclareVectorOutputPort("width", BasicVector(1), self._calc)

    def _calc(self, context, output):
        status = self.status_port.Eval(context)
        dropping = status.mode == Mode.CARRY and status.attempt == 1 and not status.objects
        if dropping and context.get_time() >= status.phase_start_s + self.after_s:
            output.SetFromVector([OPEN_WIDTH])
        else:
            output.SetFromVector(self.width_port.Eval(context))
