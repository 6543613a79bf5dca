"""The trajectory source stage: plays the current plan to the arm controllers, holds otherwise."""

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem
from pydrake.trajectories import PiecewisePolynomial

from systems.messages import PlanResult


@dataclass
class _Playing:
    plan_id: int = -1  # of the trajectory being played
    trajectory: PiecewisePolynomial | None = None
    hold_q: np.ndarray | None = None  # where the robot was first measured (held until a plan arrives)


class JointTrajectorySource(LeafSystem):
    """Plays the latest successful plan at context time; a failed plan is never executed.

    .. pydrake_system::

        name: JointTrajectorySource
        input_ports:
        - plan
        - position_measured
        output_ports:
        - position

    ``plan`` (PlanResult): its trajectory is taken up once it succeeds, and played at context time,
    held at its end afterwards. ``position_measured`` (num_joints, rad): latched once finite (the hardware
    station's status is NaN until the robot has answered) and held until a plan arrives.
    ``position`` (num_joints, rad): the command.
    """

    def __init__(self, num_joints: int = 14, period_s: float = 0.01):
        super().__init__()
        self.DeclareAbstractInputPort("plan", AbstractValue.Make(PlanResult()))
        self.DeclareVectorInputPort("position_measured", num_joints)
        self._state = self.DeclareAbstractState(AbstractValue.Make(_Playing()))
        self.DeclareVectorOutputPort("position", BasicVector(num_joints), self._calc)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._update)

    def _update(self, context, state) -> EventStatus:
        playing = context.get_abstract_state(self._state).get_value()
        plan = self.GetInputPort("plan").Eval(context)
        hold_q, trajectory, plan_id = playing.hold_q, playing.trajectory, playing.plan_id
        if hold_q is None:
            measured = self.GetInputPort("position_measured").Eval(context)
            if np.all(np.isfinite(measured)):
                hold_q = measured.copy()
        if plan.success and plan.id != plan_id:
            trajectory, plan_id = plan.trajectory, plan.id
        if plan_id == playing.plan_id and hold_q is playing.hold_q:
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._state).set_value(_Playing(plan_id, trajectory, hold_q))
        return EventStatus.Succeeded()

    def _calc(self, context, output):
        playing = context.get_abstract_state(self._state).get_value()
        if playing.trajectory is not None:
            trajectory = playing.trajectory
            t = min(max(context.get_time(), trajectory.start_time()), trajectory.end_time())
            output.SetFromVector(trajectory.value(t).ravel())
        elif playing.hold_q is not None:
            output.SetFromVector(playing.hold_q)
        else:  # before the first update: where the robot is (a hardware station's guard sends nothing yet)
            output.SetFromVector(self.GetInputPort("position_measured").Eval(context))
