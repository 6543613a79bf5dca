"""What the pick's plans cost and how well the held moves kept the closure: telemetry for the outcome."""

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import EventStatus, LeafSystem

from systems.messages import PlanResult


@dataclass(frozen=True)
class PlanTelemetry:
    """Over the pick's successful plans: wall seconds of the first and of all, and the largest closure
    deviations of the held moves' played trajectories (m, rad; NaN: no held move yet). Over every plan, failed
    ones too: when each was done (the process's time.perf_counter(), s) and whether it succeeded."""

    last_id: int = -1  # the last plan seen, successful or not
    first_planning_s: float = math.nan
    planning_total_s: float = 0.0
    closure_translation_dev_m: float = math.nan
    closure_orientation_dev_rad: float = math.nan
    finished: tuple[tuple[float, bool], ...] = ()  # (finished_wall_s, success) of every plan, in order

    @property
    def plans(self) -> int:
        """How many plans succeeded."""
        return sum(success for _, success in self.finished)

    @property
    def closure(self) -> dict[str, float]:
        """The closure deviations for a report: {"max_translation_dev_m", "max_orientation_dev_rad"}."""
        return {
            "max_translation_dev_m": float(self.closure_translation_dev_m),
            "max_orientation_dev_rad": float(self.closure_orientation_dev_rad),
        }

    def with_plan(self, plan: PlanResult) -> "PlanTelemetry":
        seen = dataclasses.replace(
            self, last_id=plan.id, finished=(*self.finished, (plan.finished_wall_s, plan.success))
        )
        if not plan.success:
            return seen
        t_dev, o_dev = self.closure_translation_dev_m, self.closure_orientation_dev_rad
        if math.isfinite(plan.closure_translation_dev_m):
            t_dev = float(np.nanmax([t_dev, plan.closure_translation_dev_m]))
            o_dev = float(np.nanmax([o_dev, plan.closure_orientation_dev_rad]))
        first = plan.planning_s if self.plans == 0 else self.first_planning_s
        return dataclasses.replace(
            seen,
            first_planning_s=first,
            planning_total_s=self.planning_total_s + plan.planning_s,
            closure_translation_dev_m=t_dev,
            closure_orientation_dev_rad=o_dev,
        )

    def latency_after(self, latched_wall_s: float) -> float:
        """Wall seconds from latched_wall_s (a frame's latch, time.perf_counter()) to the first successful plan
        done after it; without one, to the last plan done after it (the pick failed there); NaN: no plan after."""
        after = [(wall, success) for wall, success in self.finished if wall >= latched_wall_s]
        done = next((wall for wall, success in after if success), after[-1][0] if after else math.nan)
        return done - latched_wall_s


class PlanTelemetryRecorder(LeafSystem):
    """Records every plan once (it changes nothing the pick does).

    .. pydrake_system::

        name: PlanTelemetryRecorder
        input_ports:
        - plan
        output_ports:
        - telemetry

    ``plan`` (PlanResult: the planner's current plan); ``telemetry`` (PlanTelemetry).
    """

    def __init__(self, period_s: float = 0.01):
        super().__init__()
        self.plan_port = self.DeclareAbstractInputPort("plan", AbstractValue.Make(PlanResult()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(PlanTelemetry()))
        self.DeclareAbstractOutputPort(
            "telemetry",
            lambda: AbstractValue.Make(PlanTelemetry()),
            lambda c, o: o.set_value(c.get_abstract_state(self._state).get_value()),
            {self.abstract_state_ticket(self._state)},
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._update)

    def _update(self, context, state) -> EventStatus:
        telemetry = context.get_abstract_state(self._state).get_value()
        plan = self.plan_port.Eval(context)
        if plan.id < 0 or plan.id == telemetry.last_id:
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._state).set_value(telemetry.with_plan(plan))
        return EventStatus.Succeeded()
