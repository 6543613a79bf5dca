"""The hands' command source: the opening width at context time, ramped between commanded widths."""

from dataclasses import dataclass

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem


@dataclass
class HandCommand:
    """Move both hands' opening from `from_width` to `width` (m) linearly over [start_s, start_s + duration_s]."""

    width: float = 0.1
    from_width: float = 0.1
    start_s: float = 0.0
    duration_s: float = 0.0

    def at(self, t: float) -> float:
        if self.duration_s <= 0 or t >= self.start_s + self.duration_s:
            return self.width if t >= self.start_s else self.from_width
        s = max(0.0, (t - self.start_s) / self.duration_s)
        return (1 - s) * self.from_width + s * self.width

    @property
    def end_s(self) -> float:
        return self.start_s + self.duration_s


class HandCommandSource(LeafSystem):
    """Input ``command`` (HandCommand); output ``width`` (1, m) at context time.

    .. pydrake_system::

        name: HandCommandSource
        input_ports:
        - command
        output_ports:
        - width
    """

    def __init__(self):
        super().__init__()
        self.DeclareAbstractInputPort("command", AbstractValue.Make(HandCommand()))
        self.DeclareVectorOutputPort("width", BasicVector(1), self._calc)

    def _calc(self, context, output):
        output.SetFromVector([self.GetInputPort("command").Eval(context).at(context.get_time())])
