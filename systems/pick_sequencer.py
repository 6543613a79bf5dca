"""The pick sequencer: a state machine over the pick's phases. It only sequences.

It asks the camera latch for a frame, reads each perception stage's result once (timing it and
naming the stage that found nothing), then walks through the task's phases: a motion phase sends
a PlanRequest to the planner stage and waits for its PlanResult and for the trajectory to be
played; a hand phase sends a HandCommand and, after closing, checks the measured hand openings.
A failure at any point leaves the arms holding where they are (the trajectory source holds the
last played trajectory's end) and names the stage.

Modes: waiting -> perceiving -> (the task's phases: reach, approach, close, lift, then hold; or close,
look, lift, carry, look_again, set_down, release, retreat) -> done, or failed. A look finds the held
object again (the object tracker): a place moves the object from where it is in the hands, not from where
it was seen before the hands touched it (closing turned cans by up to 21 degrees, the lift a few more).
"""

import dataclasses
import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from systems.messages import (
    CLOSED_WIDTH,
    OPEN_WIDTH,
    GraspPoses,
    HandCommand,
    ObjectEstimate,
    PlanRequest,
    PlanResult,
    Segmentation,
)

STAGES = ("camera", "segmentation", "pose", "registration", "planning")
CLOSE_S = 1.0  # s: the hands close over this long
SETTLE_S = 0.5  # s: then the grip settles before it is checked
# A hand whose measured opening is below this after closing holds nothing, m.
MIN_GRASPED_WIDTH = 0.004
LIFT_HEIGHT = 0.15  # m: aimed for
MIN_LIFT_FRACTION = 0.8  # of it: near the edge of the arms' reach a lower lift will do (0.12 m)
HOLD_S = 2.5  # s
# The place task carries the object this high (its bottom clears the 6 cm boxes of the place_over_box layouts;
# over an 8 cm box STOMP found no upright carry for a can); higher, the arms are near the edge of their reach
# and cannot move it sideways, m.
PLACE_LIFT_HEIGHT = 0.10
# Letting go of a set-down object, the hands open this much wider than the widest handle they closed on, m:
# enough to back off it, no wider. In one can pick, set down within 1.1 deg: + 10 cm (fully open), the
# fingers turned it by 7.9 deg; + 2.5 cm, hand and retreat by 4.2 deg; + 1.2 cm, by 1.2 deg. (A fixed 5 cm
# opening left a hand that had closed on a 48 mm handle dragging the can away.)
RELEASE_MARGIN = 0.012
# The place task sets the object down to this height above the table: a little into it, so that the object
# rests on the table before the hands open (held 2 mm above it, the object dropped and turned by 2-4 degrees
# when let go, and a hand still on its handle then dragged it; three drill picks), m.
PLACE_CLEARANCE = -0.003


@dataclass(frozen=True)
class Phase:
    """One step of a task: a motion (path set), a hand command (hand_width set), or a wait."""

    name: str
    path: str = ""  # a PlanRequest path: "free", "straight" or "held"
    targets: str = ""  # "free"/"straight": the grasp poses named so
    X_motion_W: RigidTransform | None = None  # "held": the object's motion in W
    min_fraction: float = 1.0  # "held": the shortest share of the motion's translation that will do
    # "held" moves to the place target (the sequencer's place_target_W): "carry" (over it, turned to its yaw, at
    # the object's height, the object kept clear of the scene) or "set_down" (straight down onto it).
    goal: str = ""
    hand_width: float | None = None  # m
    beyond_grasp: bool = False  # hand_width is an opening beyond the widest measured grasp (letting go)
    wait_s: float = 0.0
    perceive: bool = False  # find the held object again (the object tracker; skipped with ground truth)


def lift_task(lift_height: float = LIFT_HEIGHT) -> tuple[Phase, ...]:
    """The paper's task: reach the pre-grasps, approach, close both hands, lift the object, hold it."""
    return (
        Phase("reach", path="free", targets="pregrasp"),
        Phase("approach", path="straight", targets="grasp"),
        Phase("close", hand_width=CLOSED_WIDTH, wait_s=SETTLE_S),
        Phase("lift", path="held", X_motion_W=RigidTransform([0.0, 0.0, lift_height]), min_fraction=MIN_LIFT_FRACTION),
        Phase("hold", wait_s=HOLD_S),
    )


def place_task(lift_height: float = PLACE_LIFT_HEIGHT) -> tuple[Phase, ...]:
    """Beyond the paper: lift the object, carry it to the place target, set it down upright, let go, back off."""
    reach, approach, close, lift = lift_task(lift_height)[:4]
    return (reach, approach, close, Phase("look", perceive=True), lift) + (
        Phase("carry", path="held", goal="carry"),
        Phase("look_again", perceive=True),  # the object turns a few degrees in the hands as they move it
        Phase("set_down", path="held", goal="set_down"),
        Phase("release", hand_width=RELEASE_MARGIN, beyond_grasp=True, wait_s=SETTLE_S),
        Phase("retreat", path="straight", targets="retreat"),
    )


@dataclass
class PickStatus:
    """Where the pick stands. Times are context (simulation or robot) seconds."""

    mode: str = "waiting"
    failed_stage: str = ""  # one of STAGES, or "grasp", when mode == "failed"
    message: str = ""
    # Wall seconds of each perception stage and of the first plan ("planning"); "image_to_trajectory":
    # segmentation to the first trajectory, the camera excluded; "planning_total": every plan of the pick.
    stage_seconds: dict[str, float] = field(default_factory=dict)
    phase_index: int = -1  # into the task's phases
    phase_start_s: float = 0.0
    perceive_id: int = 0  # the camera frame asked for
    request: PlanRequest = field(default_factory=PlanRequest)
    accounted_plan_id: int = -1  # the last plan whose times and deviations are recorded here
    hand: HandCommand = field(default_factory=lambda: HandCommand(OPEN_WIDTH, OPEN_WIDTH))
    grasp_widths: tuple[float, ...] = ()  # each hand's measured opening once closed, m
    # Where the robot stands still: first measured, then where each played trajectory ends (14 joints, rad).
    plan_end_q: np.ndarray | None = None
    # The object's pose as perceived (X_WO input), and where the held moves planned so far (and a look) put it.
    object_seen_W: RigidTransform | None = None
    object_pose_W: RigidTransform | None = None
    # A look at the object in the hands: the frame asked for, and where the object was believed to be then.
    look_id: int = 0
    look_from_W: RigidTransform = field(default_factory=RigidTransform)
    # Largest closure deviations over the held moves' played trajectories, m and rad (NaN: none yet).
    closure_translation_dev_m: float = math.nan
    closure_orientation_dev_rad: float = math.nan
    # For the viewer: the camera's object points and the reconstructed shape (N x 3 in W), and each
    # plan's grasp-frame paths.
    seen_points_W: np.ndarray | None = None
    reconstruction_W: np.ndarray | None = None
    grasp_paths_W: list[dict[str, np.ndarray]] = field(default_factory=list)

    @property
    def closure(self) -> dict[str, float]:
        """The closure deviations for a report: {"max_translation_dev_m", "max_orientation_dev_rad"}."""
        return {
            "max_translation_dev_m": float(self.closure_translation_dev_m),
            "max_orientation_dev_rad": float(self.closure_orientation_dev_rad),
        }


class PickSequencer(LeafSystem):
    """Sequences a pick: camera frame, perception results, plan requests, hand commands.

    .. pydrake_system::

        name: PickSequencer
        input_ports:
        - position_measured
        - left_hand_state
        - right_hand_state
        - plan
        - frame_id (optional)
        - segmentation (optional)
        - estimate (optional)
        - grasp_poses
        - reconstructed_cloud_W (optional)
        - X_WO (optional)
        - look_frame_id (optional)
        - look (optional)
        output_ports:
        - trigger
        - plan_request
        - hand_command
        - look_trigger
        - expected_X_WO
        - status

    ``position_measured`` (14, rad); ``<side>_hand_state`` (2: opening m, rate m/s); ``plan`` (PlanResult);
    ``frame_id`` (1) from the camera latch; the perception stages' results (Segmentation, ObjectEstimate,
    GraspPoses, N x 3 cloud); ``X_WO`` (RigidTransform: the object's estimated pose, which a place task's
    carry starts from). Without ``frame_id`` (a ground-truth source in place of perception) the
    sequencer starts planning at once. ``trigger`` (1): the camera frame wanted; ``plan_request``
    (PlanRequest); ``hand_command`` (HandCommand); ``status`` (PickStatus). A "look" phase asks for a
    second frame (``look_trigger`` (1), answered by ``look_frame_id`` (1)) and reads ``look`` (ObjectEstimate:
    the object tracker's, told where to look by ``expected_X_WO`` (RigidTransform)); without them it is
    skipped.

    Args:
        phases: the task (lift_task() or place_task()).
        perceive_at_s: when to take the camera frame (the object has settled), s.
        place_target_W: where a place task leaves the object (X_WO on the table).
    """

    def __init__(
        self,
        phases: tuple[Phase, ...],
        perceive_at_s: float = 0.5,
        place_target_W: RigidTransform | None = None,
        period_s: float = 0.01,
    ):
        super().__init__()
        self.phases, self.perceive_at_s, self.place_target_W = phases, perceive_at_s, place_target_W
        if any(phase.goal for phase in phases) and place_target_W is None:
            raise ValueError("a task with carry or set_down phases needs place_target_W")
        self.DeclareVectorInputPort("position_measured", 14)
        for side in ("left", "right"):
            self.DeclareVectorInputPort(f"{side}_hand_state", 2)
        self.DeclareAbstractInputPort("plan", AbstractValue.Make(PlanResult()))
        self.DeclareVectorInputPort("frame_id", 1)
        for name, model in (
            ("segmentation", Segmentation(False)),
            ("estimate", ObjectEstimate(False)),
            ("grasp_poses", GraspPoses(False)),
            ("reconstructed_cloud_W", np.zeros((0, 3))),
            ("X_WO", RigidTransform()),
            ("look", ObjectEstimate(False)),
        ):
            self.DeclareAbstractInputPort(name, AbstractValue.Make(model))
        self.DeclareVectorInputPort("look_frame_id", 1)
        self._state = self.DeclareAbstractState(AbstractValue.Make(PickStatus()))
        status = {self.abstract_state_ticket(self._state)}
        self.DeclareVectorOutputPort("trigger", BasicVector(1), self._calc_trigger, status)
        self.DeclareVectorOutputPort(
            "look_trigger", BasicVector(1), lambda c, o: o.SetFromVector([self._status(c).look_id]), status
        )
        for name, model, attribute in (
            ("plan_request", PlanRequest(), "request"),
            ("hand_command", HandCommand(), "hand"),
            ("expected_X_WO", RigidTransform(), "look_from_W"),
        ):
            self.DeclareAbstractOutputPort(
                name,
                lambda model=model: AbstractValue.Make(model),
                lambda c, o, attribute=attribute: o.set_value(getattr(self._status(c), attribute)),
                status,
            )
        self.DeclareAbstractOutputPort(
            "status", lambda: AbstractValue.Make(PickStatus()), lambda c, o: o.set_value(self._status(c)), status
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._update)

    def _calc_trigger(self, context, output):
        output.SetFromVector([self._status(context).perceive_id])

    def _status(self, context) -> PickStatus:
        return context.get_abstract_state(self._state).get_value()

    def _update(self, context, state) -> EventStatus:
        before = self._status(context)
        if before.mode in ("done", "failed"):
            return EventStatus.DidNothing()
        status = dataclasses.replace(before, stage_seconds=dict(before.stage_seconds))
        t = context.get_time()
        if before.mode == "waiting":
            changed = self._wait(context, status, t)
        elif before.mode == "perceiving":
            changed = self.GetInputPort("frame_id").Eval(context)[0] >= status.perceive_id
            if changed:
                self._perceive(context, status, t)
        else:
            changed = self._follow_phase(context, status, t)
        if not changed:  # (most updates: nothing to copy into the state)
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._state).set_value(status)
        return EventStatus.Succeeded()

    def _wait(self, context, status: PickStatus, t: float) -> bool:
        """Latches where the robot stands, then at perceive_at_s asks for a frame; whether it changed anything."""
        changed = False
        if status.plan_end_q is None:
            measured = self.GetInputPort("position_measured").Eval(context)
            if not np.all(np.isfinite(measured)):  # (the hardware station's NaN before the robot's status)
                return False
            status.plan_end_q, changed = measured.copy(), True
        if t < self.perceive_at_s:
            return changed
        if self.GetInputPort("frame_id").HasValue(context):
            status.mode, status.perceive_id = "perceiving", status.perceive_id + 1
        else:  # a ground-truth source in place of perception
            self._start_phase(context, status, 0, t)
        return True

    def _perceive(self, context, status: PickStatus, t: float):
        """Reads each perception stage's result once, in order, timing it; the first that found nothing
        ends the pick."""
        seconds = status.stage_seconds
        for stage, port in (("segmentation", "segmentation"), ("pose", "estimate"), ("registration", "grasp_poses")):
            started = time.perf_counter()
            result = self.GetInputPort(port).Eval(context)
            seconds[stage] = time.perf_counter() - started
            logging.info("%s: %s (%.3f s)", stage, result.message, seconds[stage])
            if not result.found:
                self._fail(status, stage, result.message)
                return
            if port == "estimate":
                status.seen_points_W = result.points_W
        status.reconstruction_W = self.GetInputPort("reconstructed_cloud_W").Eval(context)
        self._start_phase(context, status, 0, t)

    def _look(self, context, status: PickStatus) -> bool:
        """The "look" phase: once the asked-for frame is latched, reads where the tracker found the object in
        the hands; the held moves start from there. If it did not, the pick goes on from where the object was
        believed to be. Whether the look is over."""
        if self.GetInputPort("look_frame_id").Eval(context)[0] < status.look_id:
            return False
        started = time.perf_counter()
        look = self.GetInputPort("look").Eval(context)
        status.stage_seconds["look"] = time.perf_counter() - started
        logging.info("look: %s (%.3f s)", look.message, status.stage_seconds["look"])
        if look.found:
            status.object_pose_W = look.X_WO
        else:
            logging.warning("look: %s; going on from where the object was believed to be", look.message)
        return True

    def _can_look(self, context, status: PickStatus) -> bool:
        return self.GetInputPort("look_frame_id").HasValue(context) and status.object_pose_W is not None

    def _object_seen(self, context, status: PickStatus):
        """A ground-truth source is never perceived: its X_WO is read when the first motion is planned."""
        if status.object_seen_W is None and self.GetInputPort("X_WO").HasValue(context):
            status.object_seen_W = status.object_pose_W = self.GetInputPort("X_WO").Eval(context)

    def _start_phase(self, context, status: PickStatus, index: int, t: float):
        status.phase_index, status.phase_start_s = index, t
        if index >= len(self.phases):
            status.mode = "done"
            return
        phase = self.phases[index]
        status.mode = phase.name
        if phase.path:
            self._object_seen(context, status)
            X_motion_W, carried = phase.X_motion_W or RigidTransform(), None
            if phase.goal:
                X_motion_W, carried = self._motion_to_place(phase.goal, status)
            status.request = PlanRequest(
                status.request.id + 1 if status.request.id >= 0 else 1,
                phase.name,
                status.plan_end_q,
                phase.path,
                phase.targets,
                X_motion_W,
                phase.min_fraction,
                carried,
            )
        elif phase.hand_width is not None:
            width = phase.hand_width + (max(status.grasp_widths, default=OPEN_WIDTH) if phase.beyond_grasp else 0.0)
            status.hand = HandCommand(min(width, OPEN_WIDTH), status.hand.at(t), t, CLOSE_S)
        elif phase.perceive and self._can_look(context, status):
            status.look_id, status.look_from_W = status.look_id + 1, status.object_pose_W

    def _motion_to_place(self, goal: str, status: PickStatus) -> tuple[RigidTransform, RigidTransform | None]:
        """The held move of a "carry" or "set_down" phase from where the object is planned to be, and the
        object's motion since it was seen (the carry keeps it clear of the scene)."""
        now, target = status.object_pose_W, self.place_target_W
        if goal == "carry":  # over the target, turned about the vertical to its yaw, at the height it is carried at
            turn = RollPitchYaw(target.rotation()).yaw_angle() - RollPitchYaw(now.rotation()).yaw_angle()
            over = RigidTransform(
                RotationMatrix.MakeZRotation(turn) @ now.rotation(), [*target.translation()[:2], now.translation()[2]]
            )
            return over @ now.inverse(), now @ status.object_seen_W.inverse()
        # set_down: onto the target, PLACE_CLEARANCE above the table (down, and what a look found still to turn)
        down = RigidTransform(target.rotation(), target.translation() + [0.0, 0.0, PLACE_CLEARANCE])
        return down @ now.inverse(), None

    def _follow_phase(self, context, status: PickStatus, t: float) -> bool:
        """Moves on when the phase is over (or fails it). Returns whether it changed anything."""
        phase = self.phases[status.phase_index]
        if phase.path:
            plan = self.GetInputPort("plan").Eval(context)
            if plan.id != status.request.id:
                return False  # not planned yet
            if not plan.success:
                self._fail(status, "planning", plan.message)
                return True
            accounted = status.accounted_plan_id != plan.id
            if accounted:
                self._account(status, plan)
            if t + 1e-9 < plan.end_s:
                return accounted
            status.plan_end_q = plan.trajectory.value(plan.end_s).ravel()
        elif phase.hand_width is not None:
            if t + 1e-9 < status.hand.end_s + phase.wait_s:
                return False
            if phase.hand_width == CLOSED_WIDTH and not self._holding(context, status):
                return True
        elif phase.perceive and self._can_look(context, status):
            if not self._look(context, status):
                return False
        elif t + 1e-9 < status.phase_start_s + phase.wait_s:
            return False
        self._start_phase(context, status, status.phase_index + 1, t)
        return True

    def _account(self, status: PickStatus, plan: PlanResult):
        """Records a plan's wall time and, for a held move, its closure deviations."""
        status.accounted_plan_id = plan.id
        seconds = status.stage_seconds
        if "planning" not in seconds:  # the first plan: image to trajectory
            seconds["planning"] = plan.planning_s
            perception = [seconds[s] for s in ("segmentation", "pose", "registration") if s in seconds]
            seconds["image_to_trajectory"] = sum(perception) + plan.planning_s
            logging.info("planning: %s (%.3f s)", plan.message, plan.planning_s)
        seconds["planning_total"] = seconds.get("planning_total", 0.0) + plan.planning_s
        if plan.achieved_motion_W is not None and status.object_pose_W is not None:
            status.object_pose_W = plan.achieved_motion_W @ status.object_pose_W
        status.grasp_paths_W = [*status.grasp_paths_W, plan.grasp_paths_W]
        if math.isfinite(plan.closure_translation_dev_m):
            status.closure_translation_dev_m = np.nanmax(
                [status.closure_translation_dev_m, plan.closure_translation_dev_m]
            )
            status.closure_orientation_dev_rad = np.nanmax(
                [status.closure_orientation_dev_rad, plan.closure_orientation_dev_rad]
            )

    def _holding(self, context, status: PickStatus) -> bool:
        status.grasp_widths = tuple(self.GetInputPort(f"{s}_hand_state").Eval(context)[0] for s in ("left", "right"))
        for side, width in zip(("left", "right"), status.grasp_widths, strict=True):
            logging.info("%s hand closed to %.1f mm", side, width * 1000)
            if width < MIN_GRASPED_WIDTH:
                self._fail(status, "grasp", f"the {side} hand closed on nothing (opening {width * 1000:.1f} mm)")
                return False
        return True

    def _fail(self, status: PickStatus, stage: str, message: str):
        logging.warning("pick stopped at %s: %s", stage, message)
        status.mode, status.failed_stage = "failed", stage
        status.message = message if message.startswith(stage) else f"{stage}: {message}"
