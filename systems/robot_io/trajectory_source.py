"""The trajectory source stage: plays the current plan to the arm controllers, holds otherwise.

While the robot's status is stale (``status_health``), the source pauses: it holds the point of the trajectory it
had reached, and plays on from there once the status returns. The trajectory's time then runs behind the context's
by the pauses (``playback``). Behind a command guard (a robot on LCM: systems/robot_io/lcm_safety.py), which holds
the position the robot last reported, the pause holds the point the plan was at when that report arrived: the
status goes stale only a watchdog period later, and the plan played meanwhile reached no robot that had stopped (a
driver killed, frozen), so, resumed from where the guard held, nothing is caught up at the velocity limit off the
planned path (a restarted driver's move home swept a can off the table that way, 2026-12-06). Asked to stop a plan
(``stop``: the supervisor found the held object dropped), it holds the plan's point at the time given until the
next plan.
"""

import math
from dataclasses import dataclass, replace

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem
from pydrake.trajectories import PiecewisePolynomial

from systems.messages import PlanResult, Playback
from systems.robot_io.lcm_safety import LinkHealth


@dataclass(frozen=True)
class _Playing:
    plan_id: int = -1  # of the trajectory being played
    trajectory: PiecewisePolynomial | None = None
    hold_q: np.ndarray | None = None  # where the robot was first measured (held until a plan arrives)
    delay_s: float = 0.0  # this trajectory's pauses that have ended, s
    paused_at_s: float = math.nan  # when the current pause began (context s; NaN: playing)
    paused_done_s: float = 0.0  # every pause that has ended, every plan's, s
    stopped: bool = False  # the plan was stopped: paused until the next one

    @property
    def paused(self) -> bool:
        return not math.isnan(self.paused_at_s)

    def time_s(self, t: float) -> float:
        """The trajectory's time played at context time t, s."""
        return (self.paused_at_s if self.paused else t) - self.delay_s

    def pause_ended(self, t: float) -> "_Playing":
        """The current pause ended at t."""
        return replace(self, delay_s=self.delay_s + t - self.paused_at_s, paused_at_s=math.nan,
                       paused_done_s=self.paused_done_s + t - self.paused_at_s)  # fmt: skip


class JointTrajectorySource(LeafSystem):
    """Plays the latest successful plan; a failed plan is never executed.

    .. pydrake_system::

        name: JointTrajectorySource
        input_ports:
        - plan
        - position_measured
        - status_health (optional)
        - stop (optional)
        output_ports:
        - position
        - playback

    ``plan`` (PlanResult): its trajectory is taken up once it succeeds, and played at context time less the pauses,
    held at its end afterwards. ``position_measured`` (num_joints, rad): latched once finite (the hardware
    station's status is NaN until the robot has answered) and held until a plan arrives. ``status_health``
    (LinkHealth): while stale, the playing pauses (unconnected: never); with `pause_at_last_status`, at the plan's
    time when the last status arrived (no earlier than the plan's start), else where it has got to. ``stop`` (2: a
    plan's id, a time of its trajectory, s): that plan is held at that time until the next one. ``position``
    (num_joints, rad): the command. ``playback`` (Playback): the plan played and the time reached.
    """

    def __init__(self, num_joints: int = 14, period_s: float = 0.01, pause_at_last_status: bool = False):
        super().__init__()
        self.pause_at_last_status = pause_at_last_status
        self.DeclareAbstractInputPort("plan", AbstractValue.Make(PlanResult()))
        self.DeclareVectorInputPort("position_measured", num_joints)
        self.health_port = self.DeclareAbstractInputPort("status_health", AbstractValue.Make(LinkHealth()))
        self.stop_port = self.DeclareVectorInputPort("stop", 2)
        self._state = self.DeclareAbstractState(AbstractValue.Make(_Playing()))
        self.DeclareVectorOutputPort("position", BasicVector(num_joints), self._calc)
        self.DeclareAbstractOutputPort("playback", lambda: AbstractValue.Make(Playback()), self._calc_playback)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._update)

    def _update(self, context, state) -> EventStatus:
        before = playing = context.get_abstract_state(self._state).get_value()
        t = context.get_time()
        if playing.hold_q is None:
            measured = self.GetInputPort("position_measured").Eval(context)
            if np.all(np.isfinite(measured)):
                playing = replace(playing, hold_q=measured.copy())
        plan = self.GetInputPort("plan").Eval(context)
        health = self.health_port.Eval(context) if self.health_port.HasValue(context) else None
        stale = health is not None and health.stale
        if plan.success and plan.id != playing.plan_id:  # (taken up paused: its own pause starts now)
            if playing.stopped:  # (a stop's hold is no pause)
                playing = replace(playing, paused_at_s=math.nan)
            elif playing.paused:
                playing = playing.pause_ended(t)
            playing = replace(playing, plan_id=plan.id, trajectory=plan.trajectory, delay_s=0.0, stopped=False)
        stop = self.stop_port.Eval(context) if self.stop_port.HasValue(context) else (-1, 0.0)
        if stop[0] == playing.plan_id >= 0 and not playing.stopped:  # (held at the stop's time, for good)
            if playing.paused:
                playing = playing.pause_ended(t)
            playing = replace(playing, paused_at_s=t, delay_s=t - stop[1], stopped=True)
        elif stale and not playing.paused:
            playing = replace(playing, paused_at_s=self._pause_time(playing, health, t))
        elif not stale and playing.paused and not playing.stopped:
            playing = playing.pause_ended(t)
        if playing is before:
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._state).set_value(playing)
        return EventStatus.Succeeded()

    def _pause_time(self, playing: _Playing, health: LinkHealth, t: float) -> float:
        """The context time whose point of the plan a pause seen at t holds (module docstring), s."""
        if not self.pause_at_last_status or playing.trajectory is None:
            return t
        started_s = playing.trajectory.start_time() + playing.delay_s  # (context time)
        return min(t, max(health.received_at, started_s))

    def _calc(self, context, output):
        playing = context.get_abstract_state(self._state).get_value()
        if playing.trajectory is not None:
            trajectory = playing.trajectory
            t = min(max(playing.time_s(context.get_time()), trajectory.start_time()), trajectory.end_time())
            output.SetFromVector(trajectory.value(t).ravel())
        elif playing.hold_q is not None:
            output.SetFromVector(playing.hold_q)
        else:  # before the first update: where the robot is (a hardware station's guard sends nothing yet)
            output.SetFromVector(self.GetInputPort("position_measured").Eval(context))

    def _calc_playback(self, context, output):
        playing = context.get_abstract_state(self._state).get_value()
        t = context.get_time()
        paused_for_s = t - playing.paused_at_s if playing.paused and not playing.stopped else 0.0
        output.set_value(
            Playback(playing.plan_id, playing.time_s(t), paused_for_s, playing.paused_done_s + paused_for_s)
        )
