"""A fault for tests: the perceived grasps moved, on one object's first attempts only (simulation only)."""

import dataclasses

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem

from systems.messages import GraspPoses, PickStatus


class GraspOffset(LeafSystem):
    """Moves every grasp pose by a fixed offset in its own grasp frame G on the first `attempts` attempts at one
    object: X_WG -> X_WG X_G,offset.

    .. pydrake_system::

        name: GraspOffset
        input_ports:
        - grasp_poses
        - status
        output_ports:
        - grasp_poses

    ``grasp_poses`` (GraspPoses) in and out; ``status`` (PickStatus): the pick's, for the attempt under way and, in a
    clear, how many objects were taken on before this one.

    Args:
        offset_G: x, y, z of the offset in G, m.
        attempts: the attempts whose grasps are moved (the first ones).
        object_index: the object whose grasps are moved, counted in the order taken on (0: the first; a single pick's
            object is the first).
    """

    def __init__(self, offset_G, attempts: int, object_index: int = 0):
        super().__init__()
        self.offset, self.attempts, self.object_index = RigidTransform(list(offset_G)), attempts, object_index
        model = AbstractValue.Make(GraspPoses(False))
        self.grasps_port = self.DeclareAbstractInputPort("grasp_poses", model)
        self.status_port = self.DeclareAbstractInputPort("status", AbstractValue.Make(PickStatus()))
        self.DeclareAbstractOutputPort("grasp_poses", model.Clone, self._calc, {self.all_input_ports_ticket()})

    def _calc(self, context, output):
        grasps, status = self.grasps_port.Eval(context), self.status_port.Eval(context)
        if grasps.found and status.attempt <= self.attempts and len(status.objects) == self.object_index:
            moved = {name: X_WG @ self.offset for name, X_WG in grasps.poses_W.items()}
            grasps = dataclasses.replace(grasps, poses_W=moved, message=f"{grasps.message} (offset injected)")
        output.set_value(grasps)
