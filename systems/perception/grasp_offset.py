"""A fault for tests: the perceived grasps moved, on the first attempts only (simulation only)."""

import dataclasses

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem

from systems.messages import GraspPoses


class GraspOffset(LeafSystem):
    """Moves every grasp pose by a fixed offset in its own grasp frame G on the first `attempts` attempts:
    X_WG -> X_WG X_G,offset.

    .. pydrake_system::

        name: GraspOffset
        input_ports:
        - grasp_poses
        - attempt
        output_ports:
        - grasp_poses

    ``grasp_poses`` (GraspPoses) in and out; ``attempt`` (1): the pick's attempt under way (1 the first).
    """

    def __init__(self, offset_G, attempts: int):
        super().__init__()
        self.offset, self.attempts = RigidTransform(list(offset_G)), attempts
        model = AbstractValue.Make(GraspPoses(False))
        self.grasps_port = self.DeclareAbstractInputPort("grasp_poses", model)
        self.attempt_port = self.DeclareVectorInputPort("attempt", 1)
        self.DeclareAbstractOutputPort("grasp_poses", model.Clone, self._calc, {self.all_input_ports_ticket()})

    def _calc(self, context, output):
        grasps = self.grasps_port.Eval(context)
        if grasps.found and self.attempt_port.Eval(context)[0] <= self.attempts:
            moved = {name: X_WG @ self.offset for name, X_WG in grasps.poses_W.items()}
            grasps = dataclasses.replace(grasps, poses_W=moved, message=f"{grasps.message} (offset injected)")
        output.set_value(grasps)
