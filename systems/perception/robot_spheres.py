"""The robot's own body as spheres in W, for perception to leave out of what it sees (self-filtering)."""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from systems.planning.kinematics import BatchedKinematics
from systems.planning.sphere_model import SphereModel


class RobotSpheres(LeafSystem):
    """The planner's sphere model of both arms and hands at a joint configuration.

    .. pydrake_system::

        name: RobotSpheres
        input_ports:
        - position
        output_ports:
        - spheres_W

    ``position`` (n, rad: the planned joints, e.g. the camera latch's ``robot_position``); ``spheres_W``
    (S x 4: each sphere's centre in W and its radius, m; no rows where a position is not finite).
    """

    def __init__(self, kinematics: BatchedKinematics, spheres: SphereModel):
        """Args:
        kinematics, spheres: the planner's batched kinematics and sphere model (e.g. a PlanningWorld's).
        """
        super().__init__()
        self.kinematics, self.spheres = kinematics, spheres
        self.DeclareVectorInputPort("position", kinematics.dof)
        self.DeclareAbstractOutputPort("spheres_W", lambda: AbstractValue.Make(np.zeros((0, 4))), self._calc)

    def spheres_W(self, q: np.ndarray) -> np.ndarray:
        """S x 4 spheres (centre in W, radius; m) of the robot at q (n, rad)."""
        if not np.all(np.isfinite(q)):
            return np.zeros((0, 4))
        centres = self.spheres.centres_W(self.kinematics.body_poses(np.asarray(q)[None]))[0]
        return np.column_stack([centres, self.spheres.radius])

    def _calc(self, context, output):
        output.set_value(self.spheres_W(self.get_input_port().Eval(context)))
