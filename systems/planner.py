"""The STOMP planner and the trajectory source as Drake systems.

StompPlanner is event-driven: each new PlanRequest (a new `id`) on its input is
planned once, in a discrete update, and the PlanResult is kept in abstract state.
JointTrajectorySource plays a successful plan at context time to the arm
controllers; before a plan arrives, and after a failed one, it holds the
configuration it was told to hold. A failed plan is reported, never executed.
"""

import itertools
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem
from pydrake.trajectories import PiecewisePolynomial

from systems.joint_plan import move_duration
from systems.planning.closure import ClosureConstraint
from systems.planning.stomp import Obstacles, Stomp

MIN_SEGMENT_S = 0.1  # s: STOMP's keyframes are close together


@dataclass
class PlanRequest:
    id: int = -1  # a new id asks for a new plan
    q_start: np.ndarray = field(default_factory=lambda: np.zeros(14))
    q_goal: np.ndarray = field(default_factory=lambda: np.zeros(14))
    closure: ClosureConstraint | None = None
    start_time: float = 0.0  # s, when the trajectory should begin


@dataclass
class PlanResult:
    id: int = -1
    success: bool = False
    trajectory: PiecewisePolynomial | None = None  # 14 joints over time, starting at start_time
    message: str = "no plan requested"
    planning_s: float = 0.0


def time_parameterise(keyframes: np.ndarray, velocity_limits: np.ndarray, start_time: float) -> PiecewisePolynomial:
    """A shape-preserving cubic through the keyframes (no overshoot: it stays within their range),
    each segment long enough to move at SPEED_FRACTION of the velocity limits, at rest at both ends."""
    durations = [move_duration(a, b, velocity_limits, MIN_SEGMENT_S) for a, b in itertools.pairwise(keyframes)]
    times = start_time + np.concatenate([[0.0], np.cumsum(durations)])
    return PiecewisePolynomial.CubicShapePreserving(times, keyframes.T, zero_end_point_derivatives=True)


class StompPlanner(LeafSystem):
    """Input `request` (PlanRequest); output `plan` (PlanResult), kept in abstract state."""

    def __init__(self, stomp: Stomp, obstacles: Obstacles, velocity_limits: np.ndarray, period_s: float = 0.01):
        super().__init__()
        self.stomp, self.obstacles, self.velocity_limits = stomp, obstacles, np.asarray(velocity_limits)
        self.DeclareAbstractInputPort("request", AbstractValue.Make(PlanRequest()))
        self._result = self.DeclareAbstractState(AbstractValue.Make(PlanResult()))
        self.DeclareStateOutputPort("plan", self._result)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._maybe_plan)

    def _maybe_plan(self, context, state) -> EventStatus:
        request = self.get_input_port(0).Eval(context)
        current = context.get_abstract_state(self._result).get_value()
        if request.id == current.id:
            return EventStatus.DidNothing()
        result = self.stomp.plan(request.q_start, request.q_goal, self.obstacles, request.closure)
        trajectory = None
        if result.success:
            trajectory = time_parameterise(result.trajectory, self.velocity_limits, request.start_time)
        state.get_mutable_abstract_state(self._result).set_value(
            PlanResult(request.id, result.success, trajectory, result.message, result.seconds)
        )
        return EventStatus.Succeeded()


class JointTrajectorySource(LeafSystem):
    """Input `plan` (PlanResult); output `position` (14): the plan at context time, else `hold`."""

    def __init__(self, hold: np.ndarray):
        super().__init__()
        self.hold = np.asarray(hold, dtype=float)
        self.DeclareAbstractInputPort("plan", AbstractValue.Make(PlanResult()))
        self.DeclareVectorOutputPort("position", BasicVector(len(self.hold)), self._calc)

    def _calc(self, context, output):
        plan = self.get_input_port(0).Eval(context)
        if not plan.success or plan.trajectory is None:
            output.SetFromVector(self.hold)
            return
        t = np.clip(context.get_time(), plan.trajectory.start_time(), plan.trajectory.end_time())
        output.SetFromVector(plan.trajectory.value(t).ravel())
