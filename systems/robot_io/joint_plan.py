"""How long a joint-space move between two keyframes takes."""

import numpy as np

# Fraction of each joint's velocity limit that a move between keyframes peaks at.
SPEED_FRACTION = 0.25


def move_duration(q_from, q_to, velocity_limits, min_s: float) -> float:
    """Seconds for a rest-to-rest cubic from q_from to q_to that peaks at SPEED_FRACTION of the limits
    (a cubic Hermite segment with zero end velocities peaks at 1.5 |dq| / T); at least min_s."""
    dq = np.abs(np.asarray(q_to) - np.asarray(q_from))
    return max(min_s, float(np.max(1.5 * dq / (SPEED_FRACTION * np.asarray(velocity_limits)))))
