"""The chest camera's pose from the robot's measured joints (the hardware backend: the camera rides on the
torso, and a real robot reports joints, not poses)."""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import LeafSystem


class CameraPoseFromJoints(LeafSystem):
    """X_WB of the camera body from the planned joints' measured positions, by the robot model's kinematics.

    .. pydrake_system::

        name: CameraPoseFromJoints
        input_ports:
        - position_measured
        output_ports:
        - camera_pose

    ``position_measured`` (n, rad, the planned joints' order); ``camera_pose`` (RigidTransform). Where a
    measurement is not finite (no status yet), the pose at the model's default positions.

    Args:
        plant: a finalized plant of the robot alone (a context of its own is the scratch of each evaluation).
        joints: the planned joints of `plant`, in the order of position_measured.
        frame: the frame the camera is mounted on (e.g. the robot's camera_mount).
        X_FB: the camera body's pose in that frame.
    """

    def __init__(self, plant: MultibodyPlant, joints: list, frame, X_FB: RigidTransform):
        super().__init__()
        self._plant, self._frame, self._X_FB = plant, frame, X_FB
        self._context = plant.CreateDefaultContext()
        self._default = plant.GetPositions(self._context)
        self._indices = np.array([joint.position_start() for joint in joints])
        self._input = self.DeclareVectorInputPort("position_measured", len(joints))
        self.DeclareAbstractOutputPort("camera_pose", lambda: AbstractValue.Make(RigidTransform()), self._calc_pose)

    def _calc_pose(self, context, output):
        q = self._input.Eval(context)
        positions = self._default.copy()
        if np.all(np.isfinite(q)):
            positions[self._indices] = q
        self._plant.SetPositions(self._context, positions)
        output.set_value(self._frame.CalcPoseInWorld(self._context) @ self._X_FB)
