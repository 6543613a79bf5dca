"""Perturbs the yaw of an object pose estimate: the paper's misalignment experiment (§V-B)."""

import dataclasses

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import LeafSystem

from systems.messages import ObjectEstimate


def draw_yaw_offset(amplitude_rad: float, seed: int) -> float:
    """A yaw offset uniform in [-amplitude, +amplitude] rad, from the run's seed (0 if the amplitude is 0)."""
    if amplitude_rad < 0 or not np.isfinite(amplitude_rad):
        raise ValueError(f"yaw noise amplitude must be finite and >= 0 rad, got {amplitude_rad}")
    if amplitude_rad == 0:
        return 0.0
    stream = np.random.default_rng([seed, 0x9A3])  # its own stream: other draws from the seed stay independent
    return float(stream.uniform(-amplitude_rad, amplitude_rad))


def rotate_yaw(X_WO: RigidTransform, yaw_rad: float) -> RigidTransform:
    """X_WO turned by `yaw_rad` about the world z axis through the object frame's origin."""
    return RigidTransform(RotationMatrix.MakeZRotation(yaw_rad) @ X_WO.rotation(), X_WO.translation())


class PoseYawOffset(LeafSystem):
    """Passes an ObjectEstimate through with its X_WO turned by a fixed yaw (points untouched).

    .. pydrake_system::

        name: PoseYawOffset
        input_ports:
        - estimate
        output_ports:
        - estimate

    Input ``estimate`` (ObjectEstimate); output ``estimate`` (ObjectEstimate), X_WO = Rz(yaw_offset_rad) about
    the object origin.
    """

    def __init__(self, yaw_offset_rad: float):
        super().__init__()
        self.yaw_offset_rad = float(yaw_offset_rad)
        model = AbstractValue.Make(ObjectEstimate(False))
        self.estimate_port = self.DeclareAbstractInputPort("estimate", model)
        self.DeclareAbstractOutputPort("estimate", model.Clone, self._calc, {self.all_input_ports_ticket()})

    def _calc(self, context, output):
        estimate = self.estimate_port.Eval(context)
        if estimate.found:
            estimate = dataclasses.replace(estimate, X_WO=rotate_yaw(estimate.X_WO, self.yaw_offset_rad))
        output.set_value(estimate)
