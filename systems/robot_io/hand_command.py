"""The hands' command source: the opening width at context time, ramped between commanded widths."""

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem

from systems.messages import HandCommand


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
