"""A pick plan: keyframes of the 14 arm joints and the hands' opening, with named phases."""

from dataclasses import dataclass, field

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

# Fraction of each joint's velocity limit that a move between keyframes peaks at.
SPEED_FRACTION = 0.25


def move_duration(q_from, q_to, velocity_limits, min_s: float) -> float:
    """Seconds for a rest-to-rest cubic from q_from to q_to that peaks at SPEED_FRACTION of the limits
    (a cubic Hermite segment with zero end velocities peaks at 1.5 |dq| / T); at least min_s."""
    dq = np.abs(np.asarray(q_to) - np.asarray(q_from))
    return max(min_s, float(np.max(1.5 * dq / (SPEED_FRACTION * np.asarray(velocity_limits)))))


@dataclass
class JointPlan:
    """Keyframes for the 14 arm joints and the hands' opening width."""

    times: list[float] = field(default_factory=list)
    arm_q: list[np.ndarray] = field(default_factory=list)
    hand_width: list[float] = field(default_factory=list)
    # Time (s) at which each named phase ends.
    phases: dict[str, float] = field(default_factory=dict)
    # For the viewer: each hand's grasp frame origin along the plan, samples x 3 in W (may stay empty).
    grasp_paths_W: dict[str, np.ndarray] = field(default_factory=dict)

    def append(self, q: np.ndarray, width: float, duration: float):
        self.times.append((self.times[-1] if self.times else 0.0) + duration)
        self.arm_q.append(np.asarray(q, dtype=float))
        self.hand_width.append(width)

    def arm_trajectory(self) -> PiecewisePolynomial:
        """Cubic through the keyframes with zero velocity at each one (no overshoot)."""
        knots = np.column_stack(self.arm_q)
        return PiecewisePolynomial.CubicHermite(self.times, knots, np.zeros_like(knots))

    def hand_trajectory(self) -> PiecewisePolynomial:
        return PiecewisePolynomial.FirstOrderHold(self.times, np.array([self.hand_width]))

    def configuration_at(self, phase: str) -> np.ndarray:
        """The 14 arm joints at the end of a named phase (e.g. "close": grasping, "lift": lifted)."""
        return self.arm_trajectory().value(self.phases[phase]).ravel()

    @property
    def duration(self) -> float:
        return self.times[-1]
