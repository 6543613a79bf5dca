"""The pick sequencer: perceive once, plan once, then play the plan phase by phase.

Its mode lives in the Context (abstract state). At the first update at or after
`perceive_at_s` it pulls the perception chain through its inputs, one stage at a
time so that each stage's wall time is measured (camera, segmentation, pose,
registration), then asks `plan_pick` for a JointPlan and plays it. The plan starts
after the wall time that perceiving and planning took, as it would on the real
robot, which holds its position while the computer thinks. A failure at any stage
holds the arms where they are, keeps the hands as they were, and names the stage.

Modes: waiting -> (reach -> approach -> close -> lift -> hold: the plan's phases) -> done,
or failed.
"""

import dataclasses
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U
from pydrake.trajectories import PiecewisePolynomial

from systems.joint_plan import JointPlan
from systems.pose_estimator import ObjectEstimate
from systems.segmenter import Segmentation
from systems.shape_registrar import GraspPoses

# plan_pick(grasp poses in W, reconstructed cloud in W (N x 3), measured arm joints (14)) -> JointPlan.
PlanPick = Callable[[GraspPoses, np.ndarray, np.ndarray], JointPlan]
STAGES = ("camera", "segmentation", "pose", "registration", "planning")


@dataclass
class PickStatus:
    """Where the pick stands. Times are context (simulation or robot) seconds."""

    mode: str = "waiting"
    failed_stage: str = ""  # one of STAGES when mode == "failed"
    message: str = ""
    # Wall seconds of each stage, and "image_to_trajectory": segmentation to plan, the camera excluded.
    stage_seconds: dict[str, float] = field(default_factory=dict)
    plan: JointPlan | None = None
    plan_start_s: float = math.inf
    # What the plan was made from, for the viewer: the camera's object points and the
    # reconstructed whole shape, N x 3 in W, m.
    seen_points_W: np.ndarray | None = None
    reconstruction_W: np.ndarray | None = None
    # The plan's trajectories, built once: arm joints (14, rad) and hand opening (1, m) over plan time.
    arm_trajectory: PiecewisePolynomial | None = None
    hand_trajectory: PiecewisePolynomial | None = None

    @property
    def end_s(self) -> float:
        """When the plan has been played out (inf until there is one)."""
        return self.plan_start_s + self.plan.duration if self.plan is not None else math.inf


@dataclass
class _State:
    status: PickStatus = field(default_factory=PickStatus)
    hold_q: np.ndarray | None = None  # 14 arm joints held before and instead of a plan


class PickSequencer(LeafSystem):
    """Perceive -> plan -> reach -> approach -> close hands -> lift -> hold.

    Input ports:
        color_image, depth_image: the camera's images (pulled first, to time the camera alone).
        segmentation: from the Segmenter. estimate: ObjectEstimate from the PoseEstimator.
        grasp_poses: GraspPoses from the ShapeRegistrar. reconstructed_cloud_W: N x 3, m.
        position_measured: the arms' 14 measured joint positions, rad.
    Output ports:
        arm_position: 14 commanded joint positions, rad.
        hand_width: commanded opening of both hands, m.
        status: PickStatus.
    """

    def __init__(self, plan_pick: PlanPick, hand_width: float, perceive_at_s: float = 0.5, period_s: float = 0.01):
        super().__init__()
        self.plan_pick, self.hand_width, self.perceive_at_s = plan_pick, hand_width, perceive_at_s
        self._inputs = {
            "color_image": self.DeclareAbstractInputPort("color_image", AbstractValue.Make(ImageRgba8U())),
            "depth_image": self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F())),
            "segmentation": self.DeclareAbstractInputPort("segmentation", AbstractValue.Make(Segmentation(False))),
            "estimate": self.DeclareAbstractInputPort("estimate", AbstractValue.Make(ObjectEstimate(False))),
            "grasp_poses": self.DeclareAbstractInputPort("grasp_poses", AbstractValue.Make(GraspPoses(False))),
            "reconstructed_cloud_W": self.DeclareAbstractInputPort(
                "reconstructed_cloud_W", AbstractValue.Make(np.zeros((0, 3)))
            ),
        }
        self._measured = self.DeclareVectorInputPort("position_measured", 14)
        self._state = self.DeclareAbstractState(AbstractValue.Make(_State()))
        self.DeclareVectorOutputPort("arm_position", BasicVector(14), self._calc_arm)
        self.DeclareVectorOutputPort("hand_width", BasicVector(1), self._calc_hand)
        self.DeclareAbstractOutputPort("status", lambda: AbstractValue.Make(PickStatus()), self._calc_status)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._update)

    def _update(self, context, state) -> EventStatus:
        current = context.get_abstract_state(self._state).get_value()
        if current.status.mode != "waiting":
            return EventStatus.DidNothing()
        hold_q = current.hold_q
        if hold_q is None:  # latch where the robot is, once its status has arrived (the hardware station's NaN)
            hold_q = self._measured.Eval(context).copy()
            if not np.all(np.isfinite(hold_q)):
                return EventStatus.DidNothing()
        elif context.get_time() < self.perceive_at_s:
            return EventStatus.DidNothing()
        status = (
            self._perceive_and_plan(context, hold_q) if context.get_time() >= self.perceive_at_s else current.status
        )
        state.get_mutable_abstract_state(self._state).set_value(_State(status, hold_q))
        return EventStatus.Succeeded()

    def _perceive_and_plan(self, context, q_now: np.ndarray) -> PickStatus:
        event_start = time.perf_counter()
        self._inputs["color_image"].Eval(context)
        self._inputs["depth_image"].Eval(context)
        seconds = {"camera": time.perf_counter() - event_start}

        def timed(stage, port):
            start = time.perf_counter()
            value = self._inputs[port].Eval(context)
            seconds[stage] = time.perf_counter() - start
            return value

        def failed(stage, message):
            logging.warning("pick stopped at %s: %s", stage, message)
            return PickStatus("failed", stage, f"{stage}: {message}", seconds)

        segmentation = timed("segmentation", "segmentation")
        logging.info("segmentation: %s (%.3f s)", segmentation.message, seconds["segmentation"])
        if not segmentation.found:
            return failed("segmentation", segmentation.message)
        estimate = timed("pose", "estimate")
        logging.info("pose: %s (%.3f s)", estimate.message, seconds["pose"])
        if not estimate.found:
            return failed("pose", estimate.message)
        grasps = timed("registration", "grasp_poses")
        logging.info("registration: %s (%.3f s)", grasps.message, seconds["registration"])
        if not grasps.found:
            return failed("registration", grasps.message)
        cloud = self._inputs["reconstructed_cloud_W"].Eval(context)
        start = time.perf_counter()
        try:
            plan = self.plan_pick(grasps, cloud, q_now)
        except RuntimeError as error:  # PlanningError and IK/solver failures
            seconds["planning"] = time.perf_counter() - start
            return failed("planning", str(error))
        seconds["planning"] = time.perf_counter() - start
        seconds["image_to_trajectory"] = sum(seconds[s] for s in STAGES[1:])
        logging.info("planning: %.1f s of motion (%.3f s)", plan.duration, seconds["planning"])
        # The robot holds while the computer thinks: the plan starts once it exists.
        start_s = context.get_time() + time.perf_counter() - event_start
        return PickStatus(
            "planned", "", "planned", seconds, plan, start_s, estimate.points_W, cloud,
            plan.arm_trajectory(), plan.hand_trajectory(),
        )  # fmt: skip

    def _held(self, context) -> _State:
        return context.get_abstract_state(self._state).get_value()

    def _calc_arm(self, context, output):
        state = self._held(context)
        t = _plan_time(state.status, context.get_time())
        if t is not None:
            output.SetFromVector(state.status.arm_trajectory.value(t).ravel())
        elif state.hold_q is not None:
            output.SetFromVector(state.hold_q)
        else:  # before the first update: stay where the robot is (the guard of a hardware station
            # sends nothing until it has a status)
            output.SetFromVector(self._measured.Eval(context))

    def _calc_hand(self, context, output):
        status = self._held(context).status
        t = _plan_time(status, context.get_time())
        if t is not None:
            output.SetFromVector(status.hand_trajectory.value(t).ravel())
        else:
            output.SetFromVector([self.hand_width])

    def _calc_status(self, context, output):
        status = self._held(context).status
        if status.plan is not None:
            status = dataclasses.replace(status, mode=_phase(status, context.get_time()))
        output.set_value(status)


def _plan_time(status: PickStatus, t: float) -> float | None:
    """Seconds into the plan at context time t (held at its end), or None before it starts."""
    if status.plan is None or t < status.plan_start_s:
        return None
    return min(t - status.plan_start_s, status.plan.duration)


def _phase(status: PickStatus, t: float) -> str:
    """The plan's phase at context time t: the first named phase that has not ended yet."""
    if t < status.plan_start_s:
        return "planned"
    elapsed = t - status.plan_start_s
    for name, end in sorted(status.plan.phases.items(), key=lambda item: item[1]):
        if elapsed < end:
            return name
    return "done"
