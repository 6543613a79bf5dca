"""Whether a STOMP trajectory is a solution: the sphere model clear (by the required clearance) at its keyframes and
densely between them, and the hand constraints kept densely (closure within t_max and o_max, orientation within
o_max)."""

from dataclasses import dataclass

import numpy as np

from systems.planning.closure import hand_orientation_deviations, relative_deviations
from systems.planning.kinematics import relative_pose
from systems.planning.obstacles import Obstacles
from systems.planning.stomp_config import CostConfig
from systems.planning.stomp_costs import SphereCosts, StompProblem


@dataclass
class Checked:
    """A trajectory and the check's verdict on it."""

    trajectory: np.ndarray  # N x n
    solution: bool
    clearance: np.ndarray | None  # m, the sphere model's at each keyframe (N); None where not computed


@dataclass
class SegmentStates:
    """The states strictly between keyframes that the dense check looks at."""

    states: np.ndarray  # S x n
    segment: np.ndarray  # S: the transition each lies on
    share: np.ndarray  # S: its share of the way along it
    middle: np.ndarray  # S: whether it is its transition's middle one


@dataclass
class ClosureCheck:
    """Whether the hands' relative pose stays within the closure's thresholds densely, and its largest deviations."""

    within: bool
    translation_m: float
    orientation_rad: float


def interpolate_segments(keyframes: np.ndarray, steps: int) -> np.ndarray:
    """States along each segment between consecutive keyframes, `steps` per segment (both ends included), S x n."""
    s = np.linspace(0, 1, steps + 1)[:, None, None]
    return ((1 - s) * keyframes[None, :-1] + s * keyframes[None, 1:]).reshape(-1, keyframes.shape[1])


class SolutionChecks:
    """Judges trajectories in a problem by the sphere model (SphereCosts) and the hands' poses."""

    def __init__(self, costs: SphereCosts, config: CostConfig):
        self.costs, self.config = costs, config
        self.end_effectors = costs.end_effectors

    def check(
        self, theta: np.ndarray, problem: StompProblem, clearance: np.ndarray | None = None, at_once: bool = False
    ) -> Checked:
        """Whether the trajectory (N x n) is a solution (clear of collision at and between its keyframes, within the
        hand constraints densely), with its keyframes' clearances (`clearance` if already computed). With `at_once`,
        the keyframes and the states between them are checked in one batch (a likely solution: one sphere-model call
        instead of three)."""
        obstacles, held = problem.obstacles, problem.held
        closure, orientation = problem.closure, problem.orientation
        between = None
        if clearance is None and at_once:
            both = self.costs.clearance(np.concatenate([theta, self.segment_states(theta).states]), obstacles, held)
            clearance, between = both[: len(theta)], both[len(theta) :]
        elif clearance is None:
            clearance = self.costs.clearance(theta, obstacles, held)
        ok = clearance.min() > self.config.required_clearance
        if ok and (closure is not None or orientation is not None):  # both from one batch of hand poses
            hands = self.dense_hand_poses(theta)
            ok = closure is None or self.closure_within_limits(theta, closure, hands=hands).within
            ok = ok and (orientation is None or self.orientation_within_limits(theta, orientation, hands=hands)[0])
        if between is not None:
            return Checked(theta, bool(ok and between.min() > self.config.required_clearance), clearance)
        return Checked(theta, bool(ok and self.segments_clear(theta, obstacles, held)), clearance)

    def segment_states(self, theta: np.ndarray) -> SegmentStates:
        """The states strictly between keyframes that segments_clear checks: no joint turns more than
        segment_step_rad between two (at least 4 steps per segment, each as many as its largest joint change needs)."""
        steps = np.maximum(4, np.ceil(np.abs(np.diff(theta, axis=0)).max(axis=1) / self.config.segment_step_rad))
        steps = steps.astype(int)
        segment = np.repeat(np.arange(len(steps)), steps - 1)
        along = np.concatenate([np.arange(1, k) for k in steps])
        share = along / steps[segment]
        states = (1 - share)[:, None] * theta[segment] + share[:, None] * theta[segment + 1]
        return SegmentStates(states, segment, share, along == steps[segment] // 2)

    def segments_clear(self, theta: np.ndarray, obstacles: Obstacles, held: bool) -> bool:
        """The sphere model stays clear between keyframes too (the keyframes themselves checked by the caller), at
        segment_states. The states at each segment's middle are checked first: a trajectory that collides is mostly
        found there."""
        between = self.segment_states(theta)
        states, middle = between.states, between.middle
        return all(
            self.costs.clearance(subset, obstacles, held).min() > self.config.required_clearance
            for subset in (states[middle], states[~middle])
        )

    def least_clear_along(self, theta: np.ndarray, obstacles: Obstacles) -> np.ndarray:
        """Where along each transition of a held move (its share of the way, N - 1) the sphere model is least clear,
        checked as densely as segments_clear checks it."""
        between = self.segment_states(theta)
        segment = between.segment
        clearance = self.costs.clearance(between.states, obstacles, held=True)
        order = np.lexsort((clearance, segment))  # by segment, then clearance: each segment's least clear first
        first = np.searchsorted(segment[order], np.arange(len(theta) - 1))
        return between.share[order[first]]

    def dense_hand_poses(self, theta: np.ndarray, steps: int = 10) -> tuple[np.ndarray, np.ndarray]:
        """Both hands' poses (X_WE1, X_WE2, each S x 4 x 4) at `steps` states per segment of the trajectory."""
        return self.end_effectors.poses(interpolate_segments(theta, steps))

    def orientation_within_limits(
        self, theta: np.ndarray, orientation, steps: int = 10, hands=None
    ) -> tuple[bool, float]:
        """Whether both hands stay within o_max of their desired orientations densely; also the largest deviation
        (rad). `orientation`: (OrientationConstraint, [R_WE1, R_WE2] desired); `hands`: dense_hand_poses(theta, steps)
        if already computed."""
        constraint, R_desired = orientation
        hands = self.dense_hand_poses(theta, steps) if hands is None else hands
        worst = float(hand_orientation_deviations(hands, R_desired, constraint.upright_only).max())
        return worst < constraint.o_max, worst

    def closure_within_limits(self, theta: np.ndarray, closure, steps: int = 10, hands=None) -> ClosureCheck:
        """Whether the deviations stay below t_max and o_max densely along the trajectory, and the largest ones.
        `closure`: (ClosureConstraint, X_E1E2 desired); `hands`: dense_hand_poses(theta, steps) if already computed."""
        constraint, X_desired = closure
        hands = self.dense_hand_poses(theta, steps) if hands is None else hands
        t_dev, o_dev = relative_deviations(relative_pose(*hands), X_desired)
        ok = t_dev.max() < constraint.t_max and o_dev.max() < constraint.o_max
        return ClosureCheck(bool(ok), float(t_dev.max()), float(o_dev.max()))
