"""A category's tool frame: the point an object acts through and the direction it acts along, carried to a novel
instance as its grasps are.

The watering can's is the spout's tip, where the water leaves, and its outflow direction; the drill's is the tip of a
bit of BIT_LENGTH_M in its chuck, and the bit's axis pointing out of the chuck. The frame is a point and a direction
only: turning about the axis changes nothing a can or a drill does.
"""

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform

# m: the length of the bit a drill's tool frame assumes in its chuck, measured from the chuck's front face.
BIT_LENGTH_M = 0.06


@dataclass(frozen=True)
class ToolFrame:
    """A tool's tip (3,) and unit axis (3,), in the frame named where it is used (O of the object, or W)."""

    tip: np.ndarray  # m
    axis: np.ndarray  # unit: the outflow direction, or the bit's axis out of the chuck

    def __post_init__(self):
        tip, axis = np.asarray(self.tip, dtype=float), np.asarray(self.axis, dtype=float)
        length = np.linalg.norm(axis) if axis.shape == (3,) else 0.0
        if tip.shape != (3,) or not np.all(np.isfinite(tip)) or not np.isfinite(length) or length < 1e-9:
            raise ValueError(f"a tool frame needs a tip of 3 finite numbers and a non-zero axis, got {tip}, {axis}")
        object.__setattr__(self, "tip", tip)
        object.__setattr__(self, "axis", axis / length)

    def moved(self, X_AB: RigidTransform) -> "ToolFrame":
        """The frame given in B, expressed in A."""
        return ToolFrame(X_AB.multiply(self.tip), X_AB.rotation().multiply(self.axis))

    def scaled(self, scale: np.ndarray) -> "ToolFrame":
        """The frame of the shape scaled by `scale` (3,) along its frame's axes about the origin (a registrar's
        scaled fit): the tip scaled, the axis as the scaled shape's direction."""
        scale = np.asarray(scale, dtype=float)
        return ToolFrame(scale * self.tip, scale * self.axis)

    def errors(self, truth: "ToolFrame") -> tuple[float, float]:
        """How far this frame is from the true one: the tip's distance (m) and the angle between the axes (rad)."""
        tip = float(np.linalg.norm(self.tip - truth.tip))
        return tip, float(np.arccos(np.clip(self.axis @ truth.axis, -1.0, 1.0)))

    def entries(self) -> dict[str, list[float]]:
        """As a poses file or an info.yaml holds it: {tip: [x, y, z], axis: [x, y, z]}."""
        return {"tip": self.tip.tolist(), "axis": self.axis.tolist()}
