"""The pick supervisor: runs the pick's tasks (systems/pick_tasks.py), one phase at a time.

It asks perception for a camera frame and reads perception's one result, then runs the pick's task: a move
phase sends a PlanRequest to the planner stage and waits for its PlanResult and for the trajectory to be
played; a close or open phase sends a HandCommand and, after closing, checks the measured hand openings; a look
asks the object tracker where the object is. What comes after each task, and which task a failed check or a
look switches to, is the tasks' data. A failure at any point leaves the arms holding where they are (the
trajectory source holds the last played trajectory's end) and names the stage.

Modes: waiting -> perceiving -> (the task's phases: reach, approach, close, lift, then hold; or close,
look, lift, carry, look_again, set_down, release, retreat, confirm) -> done, or failed.

Checks and retries (systems/pick_checks.py): after closing, each hand must hold something, and after the lift and
the carry it must still do. A failed check is one failed attempt: the
recovery task opens the hands, backs off along their approach axes and goes back to where the pick started,
and the pick starts again from a new camera frame, up to max_attempts. Failures that another attempt would
repeat (perception found nothing, no plan) end the pick at once.

A place moves the object from where it is in the hands, not from where it was seen before the hands touched
it (closing turned cans by up to 21 degrees, the lift a few more): the object belief and the place goals are
systems/planning/place_goals.py's. After a place, a look confirms where the object stands; clearly off its
target, the hands take it again and set it down again (at most MAX_PLACE_CORRECTIONS times per attempt).

An aim (a pour) reads the board (the container) perceived in the same frame and uses the perceived tool frame
(systems/pick_goals.py); without either it fails before it moves. It sets the object down where it was taken.

A clear (the tasks' after_given_up set; a drop_zone given) places one object after another: each perceived object gets a
spot in the drop zone where it touches nothing already set down there (systems/planning/drop_zone.py). Once it is
placed, the table is looked at from where the arms backed off it for the scene alone (the placed object in it), the
tasks' home goes to the clear's home (q_home) in that scene, and the next object is looked for from there; where
anything fails on it, it is given up: after_given_up lets go and backs off, and the same follows (where the robot has
not moved, the next object is looked for at once). Perception leaves out the zone and the objects given up
(``left_out``). The clear is done when perception finds no object left, the zone has no room for the next one, or
max_objects were taken on; each object's record is in the status (``objects``).
"""

import dataclasses
import logging

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from systems import clear_progress as clearing
from systems.messages import (
    OPEN_WIDTH,
    SIDES,
    BoardSeen,
    ContainerSeen,
    HandCommand,
    LeftOut,
    LookRequest,
    Mode,
    ObjectBelief,
    ObjectEstimate,
    PerceptionResult,
    PhaseKind,
    PickStatus,
    PlaceGoal,
    PlanRequest,
    PlanResult,
    Playback,
    Stage,
    Targets,
    TaskName,
)
from systems.pick_checks import camera_silence, fail, not_holding, played_s, stage_message, status_silence
from systems.pick_goals import AIM_GOALS, POUR_GOALS, move_request, read_use_targets
from systems.pick_looks import MAX_CORRECTIONS, placed_off_target, read_look
from systems.pick_tasks import Phase, PickTasks, Task, Then
from systems.planning.drop_zone import DropZone
from systems.planning.place_goals import nudged_targets

CLOSE_S = 1.0  # s: the hands close over this long
# A failed check that another attempt can put right: a hand closed on nothing, or lost the object.
RETRIED_STAGES = (Stage.GRASP,)


class PickSupervisor(LeafSystem):
    """Supervises a pick: asks perception for a frame, the planner for plans, the hands for widths.

    .. pydrake_system::

        name: PickSupervisor
        input_ports:
        - position_measured
        - left_hand_state
        - right_hand_state
        - plan
        - frame_id
        - perception
        - look_frame_id (optional)
        - look (optional)
        - board (optional)
        - container (optional)
        - playback (optional)
        output_ports:
        - trigger
        - plan_request
        - hand_command
        - look_trigger
        - expected_X_WO
        - attempt
        - status
        - left_out

    ``position_measured`` (num_joints, rad); ``<side>_hand_state`` (2: opening m, rate m/s); ``plan`` (PlanResult);
    ``frame_id`` (1): the frame perception has latched; ``perception`` (PerceptionResult). ``trigger`` (1):
    the camera frame wanted; ``plan_request`` (PlanRequest); ``hand_command`` (HandCommand); ``status``
    (PickStatus); ``attempt`` (1): the attempt under way. With looks, a look phase asks for a frame of the
    held object (``look_trigger`` (1), answered by ``look_frame_id`` (1)) and reads ``look`` (ObjectEstimate:
    the object tracker's, told where to look by ``expected_X_WO`` (RigidTransform)); without looks it is
    skipped. An aim task reads ``board`` (BoardSeen, of the frame perceived), a pour task ``container``
    (ContainerSeen, of that frame). A clear tells perception what to leave out (``left_out``: LeftOut). A move ends
    when the trajectory source's ``playback`` (Playback) reaches the plan's end (unconnected: at the plan's end in
    context time); a frame or a move waited on too long ends the pick (systems/pick_checks.py).

    Args:
        tasks: the pick's tasks (lift_pick() or place_pick()).
        perceive_at_s: when to ask for the camera frame (the object has settled), s.
        place_target_W: where a place task leaves the object (X_WO on the table); None: where it was seen (the aim
            task's set-down).
        from_camera: perception needs a camera frame (False: a ground-truth source, read at once).
        looks: the look phases ask the object tracker (False: they are skipped).
        max_attempts: attempts at the task, the first included (a failed check starts the next).
        num_joints: the planned joints (14: the arms; 15: with the torso).
        drop_zone, max_objects: a clear's zone (its tasks clear_pick()) and the most objects it takes on.
        status_lost_s: a move paused this long for the robot's status ends the pick, s (None: STATUS_LOST_S).
        pour_tilt_rad: a pour's outflow this far below the horizontal, rad.
    """

    def __init__(
        self,
        tasks: PickTasks,
        perceive_at_s: float = 0.5,
        place_target_W: RigidTransform | None = None,
        from_camera: bool = True,
        looks: bool = False,
        max_attempts: int = 1,
        period_s: float = 0.01,
        num_joints: int = 14,
        drop_zone: DropZone | None = None,
        max_objects: int = 1,
        status_lost_s: float | None = None,
        pour_tilt_rad: float = 0.0,
        home_q: np.ndarray | None = None,
    ):
        super().__init__()
        self.clears, self.drop_zone, self.max_objects = tasks.after_given_up is not None, drop_zone, max_objects
        if self.clears != (drop_zone is not None):
            raise ValueError("a clear's tasks and a drop zone come together")
        self.tasks, self.perceive_at_s, self.place_target_W = tasks, perceive_at_s, place_target_W
        self.from_camera, self.looks, self.status_lost_s = from_camera, looks, status_lost_s
        if max_attempts < 1:
            raise ValueError(f"max_attempts must be at least 1, not {max_attempts}")
        self.max_attempts, self.pour_tilt_rad = max_attempts, pour_tilt_rad
        self.home_q = None if home_q is None else np.asarray(home_q, float)
        self.position_port = self.DeclareVectorInputPort("position_measured", num_joints)
        self.hand_state_ports = {side: self.DeclareVectorInputPort(f"{side}_hand_state", 2) for side in SIDES}
        self.plan_port = self.DeclareAbstractInputPort("plan", AbstractValue.Make(PlanResult()))
        self.frame_id_port = self.DeclareVectorInputPort("frame_id", 1)
        self.perception_port = self.DeclareAbstractInputPort("perception", AbstractValue.Make(PerceptionResult()))
        self.look_frame_id_port = self.DeclareVectorInputPort("look_frame_id", 1)
        self.look_port = self.DeclareAbstractInputPort("look", AbstractValue.Make(ObjectEstimate(False)))
        self.board_port = self.DeclareAbstractInputPort("board", AbstractValue.Make(BoardSeen()))
        self.playback_port = self.DeclareAbstractInputPort("playback", AbstractValue.Make(Playback()))
        self.container_port = self.DeclareAbstractInputPort("container", AbstractValue.Make(ContainerSeen()))
        goals = {phase.goal for phase in tasks.phases()}
        self.aims, self.pours = not goals.isdisjoint(AIM_GOALS), not goals.isdisjoint(POUR_GOALS)
        self._state = self.DeclareAbstractState(AbstractValue.Make(PickStatus()))
        # A look request is state of its own: the tracker's inputs change only when a new look is asked for.
        self._look_state = self.DeclareAbstractState(AbstractValue.Make(LookRequest()))
        status = {self.abstract_state_ticket(self._state)}
        looking = {self.abstract_state_ticket(self._look_state)}
        self.DeclareVectorOutputPort(
            "trigger", BasicVector(1), lambda c, o: o.SetFromVector([self._status(c).perceive_id]), status
        )
        for name, model, attribute in (
            ("plan_request", PlanRequest(), "request"),
            ("hand_command", HandCommand(), "hand"),
        ):
            self.DeclareAbstractOutputPort(
                name,
                lambda model=model: AbstractValue.Make(model),
                lambda c, o, attribute=attribute: o.set_value(getattr(self._status(c), attribute)),
                status,
            )
        self.DeclareVectorOutputPort(
            "look_trigger", BasicVector(1), lambda c, o: o.SetFromVector([self._look_request(c).id]), looking
        )
        self.DeclareAbstractOutputPort(
            "expected_X_WO",
            lambda: AbstractValue.Make(RigidTransform()),
            lambda c, o: o.set_value(self._look_request(c).expected_X_WO),
            looking,
        )
        self.DeclareVectorOutputPort(
            "attempt", BasicVector(1), lambda c, o: o.SetFromVector([self._status(c).attempt]), status
        )
        self.DeclareVectorOutputPort("stop", BasicVector(2), lambda c, o: o.SetFromVector(self._status(c).stop), status)
        self.DeclareAbstractOutputPort(
            "status", lambda: AbstractValue.Make(PickStatus()), lambda c, o: o.set_value(self._status(c)), status
        )
        self.DeclareAbstractOutputPort(
            "left_out",
            lambda: AbstractValue.Make(LeftOut()),
            lambda c, o: o.set_value(clearing.left_out(self.drop_zone, self._status(c))),
            status,
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._update)

    def _status(self, context) -> PickStatus:
        return context.get_abstract_state(self._state).get_value()

    def _look_request(self, context) -> LookRequest:
        return context.get_abstract_state(self._look_state).get_value()

    def _update(self, context, state) -> EventStatus:
        before = self._status(context)
        if before.mode in (Mode.DONE, Mode.FAILED):
            return EventStatus.DidNothing()
        status = dataclasses.replace(before)
        look = self._look_request(context)
        t = context.get_time()
        if before.mode == Mode.WAITING:
            changed = self._wait(context, status, t)
        elif before.mode == Mode.PERCEIVING:
            changed = self.frame_id_port.Eval(context)[0] >= status.perceive_id
            if changed:
                status.frames_waited_s += t - status.asked_frame_s
                self._perceive(context, status, t)
            elif problem := camera_silence(t, status.asked_frame_s, "the table"):
                changed = True
                fail(status, Stage.CAMERA, problem)
        else:
            changed, look = self._follow_phase(context, status, look, t)
        if self.clears and status.mode == Mode.FAILED and status.current is not None:
            look = self._give_up(context, status, look, t)
        if look is not self._look_request(context):
            state.get_mutable_abstract_state(self._look_state).set_value(look)
        if not changed:  # (most updates: nothing to copy into the state)
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._state).set_value(status)
        return EventStatus.Succeeded()

    def _wait(self, context, status: PickStatus, t: float) -> bool:
        """Latches where the robot stands, then at perceive_at_s asks for a frame; whether it changed anything."""
        changed = False
        if status.plan_end_q is None:
            measured = self.position_port.Eval(context)
            if not np.all(np.isfinite(measured)):  # (the hardware station's NaN before the robot's status)
                return False
            status.plan_end_q, status.q_start, changed = measured.copy(), measured.copy(), True
            status.q_home = measured.copy() if self.home_q is None else self.home_q.copy()
        if t < self.perceive_at_s:
            return changed
        self._look_at_the_table(context, status, t)
        return True

    def _look_at_the_table(self, context, status: PickStatus, t: float):
        """Asks perception for a new frame (a ground-truth source needs none: it is read at once)."""
        if self.from_camera:
            status.mode, status.perceive_id, status.asked_frame_s = Mode.PERCEIVING, status.perceive_id + 1, t
        else:
            self._perceive(context, status, t)

    def _perceive(self, context, status: PickStatus, t: float):
        """Reads perception's result; a stage that found nothing ends the pick."""
        result = self.perception_port.Eval(context)
        status.perceived = True
        if status.homing:  # (the frame's scene is what the move home avoids; the arms hide the table in it)
            status.homing = False
            self._start_task(context, status, self.tasks.home, 0, t)
            return
        if self.clears and result.failed_stage == Stage.SEGMENTATION and status.current is None:  # nothing left
            if (pass_from := clearing.next_pass(status)) is not None:  # those given up before the table changed
                logging.info("%s; a new pass over the table for those given up before others left", result.message)
                status.pass_from = pass_from
                self._look_at_the_table(context, status, t)
                return
            status.mode, status.message, status.homing = Mode.DONE, clearing.summary(status, result.message), False
            return
        if not result.found:  # (a clear's object given up; one under way, retried and not seen again, keeps its record)
            if self.clears and status.current is None:
                status.current = clearing.seen_object(result, status.pass_from > 0)
            elif self.clears and result.failed_stage == Stage.SEGMENTATION:  # (it fell over, or off the table)
                result = clearing.not_seen_again(result, status.attempt - 1)
            fail(status, result.failed_stage, result.message)
            return
        status.belief = ObjectBelief.seen(result.X_WO_seen)
        if self.place_target_W is not None and not self.clears:  # set down beside the target if not on it
            status.spare_spots = tuple((X_WO, None) for X_WO in nudged_targets(self.place_target_W))
        if self.clears and not clearing.take_spot(self.drop_zone, status, result):  # (the zone is full: done)
            return
        board = self.board_port.Eval(context) if self.aims else None
        container = self.container_port.Eval(context) if self.pours else None
        if failure := read_use_targets(status, result, board, container, self.pour_tilt_rad):
            fail(status, *failure)
            return
        self._start_task(context, status, self.tasks.main, 0, t)

    def _start_task(
        self, context, status: PickStatus, name: TaskName, index: int, t: float, look: LookRequest | None = None
    ) -> LookRequest | None:
        """Starts task `name` at its phase `index`; returns the look request."""
        status.task = name
        return self._start_phase(context, status, index, t, look)

    def _start_phase(self, context, status: PickStatus, index: int, t: float, look: LookRequest | None = None):
        """Starts the task's phase `index` (what comes after the task, after its last); returns the look request (a
        new one for a look phase)."""
        status.phase_index, status.phase_start_s = index, t
        task = self.tasks[status.task]
        if index >= len(task.phases):
            return self._after(context, status, task, t, look)
        phase = task.phases[index]
        status.mode = phase.name
        if phase.kind == PhaseKind.MOVE:
            measured_q = self.position_port.Eval(context)
            place_target_W = self._place_target(status) if phase.goal is not None else None  # (no belief going home)
            # A clear's set-down with a spot left to try: only where the hands can back off from it the whole way
            # (a back-off cut short leaves the fingers about the handle, and the next move sweeps them past it).
            spot_left = self.clears and status.task == self.tasks.main and bool(status.spare_spots)
            full_back_off = spot_left and phase.goal == PlaceGoal.SET_DOWN
            # A clear's moves plan around what it set down in the zone: the arms backed off one hide it, and the
            # object carried hides it from the look before the set-down.
            set_down = clearing.set_down_shapes(status) if self.clears else None
            status.request = move_request(phase, status, place_target_W, measured_q, full_back_off, set_down)
        elif phase.kind in (PhaseKind.CLOSE, PhaseKind.OPEN):
            width = phase.hand_width + (max(status.grasp_widths, default=OPEN_WIDTH) if phase.beyond_grasp else 0.0)
            status.hand = HandCommand(min(width, OPEN_WIDTH), status.hand.at(t), t, CLOSE_S)
        elif self._looks_at(phase) and look is not None:
            look = LookRequest(look.id + 1, status.belief.now_W)
        return look

    def _after(self, context, status: PickStatus, task: Task, t: float, look: LookRequest | None):
        """What comes after the task's last phase; returns the look request."""
        if task.then == Then.NEXT_ATTEMPT:  # backed off and home: the next attempt starts from a new frame
            status.task, status.attempt, status.corrections, status.place_corrections = None, status.attempt + 1, 0, 0
            self._look_at_the_table(context, status, t)
        elif task.then == Then.FAIL:  # (set back down first) the failure that started the task
            fail(status, *status.pending_failure)
        elif task.then == Then.REACH_AGAIN:  # backed off: reach for the object where the look found it
            main = self.tasks.main
            return self._start_task(context, status, main, self.tasks[main].index(Mode.REACH), t, look)
        elif task.then == Then.NEXT_OBJECT:
            self._next_object(context, status, t, homing=task.name != self.tasks.home)
        elif self.clears:  # placed: a look for the scene, home, the next object
            status.objects += (clearing.placed(status.current, status.belief, status.attempt),)
            status.current = None
            self._next_object(context, status, t, homing=True)
        else:
            status.mode = Mode.DONE
        return look

    def _give_up(self, context, status: PickStatus, look: LookRequest, t: float) -> LookRequest:
        """A clear's object failed (status FAILED): it is recorded as given up (as placed where it failed while taken
        again off its spot in the zone), the hands let go and back off (where they moved), and the next object is
        looked for."""
        failed = clearing.given_up(status, in_zone=status.task == TaskName.REPLACE)
        status.objects, status.current = (*status.objects, failed), None
        status.failed_stage, status.message = "", ""
        logging.warning("giving up on the %s: %s", failed.category, failed.message)
        if clearing.nothing_moved(status):
            self._next_object(context, status, t)
            return look
        return self._start_task(context, status, self.tasks.after_given_up, 0, t, look)

    def _next_object(self, context, status: PickStatus, t: float, homing: bool = False):
        """A clear's next object: a new frame (after max_objects, the clear is done); `homing`: the frame is for the
        scene the move home avoids, the object is looked for after it."""
        clearing.forget_object(status)
        if len(status.objects) >= self.max_objects:
            ended = f"took on {self.max_objects} objects, the most"
            status.mode, status.message = Mode.DONE, clearing.summary(status, ended)
            return
        status.homing = homing
        logging.info("%s (%d taken on)", "looking at the table before going home" if homing else "looking for the next "
                     "object", len(status.objects))  # fmt: skip
        self._look_at_the_table(context, status, t)

    def _looks_at(self, phase: Phase) -> bool:
        """Whether the phase asks the object tracker (without looks, a look phase passes at once)."""
        return self.looks and phase.kind in (PhaseKind.LOOK, PhaseKind.CHECK_MOVED, PhaseKind.CONFIRM_PLACED)

    def _follow_phase(self, context, status: PickStatus, look: LookRequest, t: float) -> tuple[bool, LookRequest]:
        """Moves on when the phase is over (or fails it). Returns whether the status changed, and the look request."""
        phase = self.tasks[status.task].phases[status.phase_index]
        if phase.kind == PhaseKind.MOVE:
            plan = self.plan_port.Eval(context)
            if plan.id != status.request.id:
                return False, look  # not planned yet
            if not plan.success:
                if self.clears and status.task in (self.tasks.home, self.tasks.after_given_up):  # go on from here
                    logging.warning("%s; looking at the table from here", plan.message)
                    self._next_object(context, status, t, homing=status.task != self.tasks.home)
                    return True, look
                placing = phase.goal in (PlaceGoal.CARRY, PlaceGoal.SET_DOWN) and status.task == self.tasks.main
                if placing and status.spare_spots:
                    (X_WO, footprint), *rest = status.spare_spots  # no plan to this spot: carry it to the next one
                    where = "the next spot in the drop zone"
                    if not self.clears:  # a place's target moved (place_goals.nudged_targets)
                        where = "the target at ({:.3f}, {:.3f})".format(*X_WO.translation()[:2])
                    logging.warning("%s; trying %s", plan.message, where)
                    status.place_target_W, status.spare_spots = X_WO, tuple(rest)
                    if self.clears:
                        status.current = clearing.with_spot(status.current, X_WO, footprint)
                    carry = self.tasks[status.task].index(Mode.CARRY)
                    return True, self._start_phase(context, status, carry, t, look)
                if phase.if_unreachable is None:
                    fail(status, Stage.PLANNING, plan.message)
                    return True, look
                logging.warning("%s; setting the object back down", plan.message)
                status.pending_failure = (Stage.PLANNING, plan.message)
                status.place_target_W = None  # (a clear's set-back: where it was taken, not its spot in the zone)
                return True, self._start_task(context, status, phase.if_unreachable, 0, t, look)
            applied = status.applied_plan_id != plan.id
            if applied:  # the object moved with the hands; a reach chose the grasps
                status.applied_plan_id = plan.id
                if plan.achieved_motion_W is not None:
                    status.belief = status.belief.moved(plan.achieved_motion_W)
                if phase.targets == Targets.PREGRASP:
                    status.grasp_offsets_G = plan.grasp_offsets_G
            playback = self.playback_port.Eval(context) if self.playback_port.HasValue(context) else None
            if (played := played_s(playback, plan.id, t)) + 1e-9 < plan.end_s:
                if problem := status_silence(playback, phase.name, self.status_lost_s):
                    fail(status, Stage.STATUS, problem)
                    return True, look
                checked = phase.check_held and np.isfinite(played)  # (a held move, being played)
                if checked and (problem := not_holding(self._hand_widths(context), f"during the {phase.name}: ")):
                    played = max(played, plan.trajectory.start_time())  # (the arms stop where they are)
                    status.stop, status.plan_end_q = (plan.id, played), plan.trajectory.value(played).ravel()
                    return True, self._attempt_failed(context, status, Stage.GRASP, problem, look, t)
                return applied, look
            status.plan_end_q = plan.trajectory.value(plan.end_s).ravel()
            if phase.check_held and (problem := self._not_holding(context, status, f"after the {phase.name}: ")):
                return True, self._attempt_failed(context, status, Stage.GRASP, problem, look, t)
        elif phase.kind in (PhaseKind.CLOSE, PhaseKind.OPEN):
            if t + 1e-9 < status.hand.end_s + phase.wait_s:
                return False, look
            if phase.kind == PhaseKind.CLOSE and (problem := self._not_holding(context, status)):
                return True, self._attempt_failed(context, status, Stage.GRASP, problem, look, t)
        elif self._looks_at(phase):
            if self.look_frame_id_port.Eval(context)[0] < look.id:
                if problem := camera_silence(t, status.phase_start_s, f"the {phase.name}"):
                    fail(status, Stage.CAMERA, problem)
                    return True, look
                return False, look
            if phase.kind == PhaseKind.CONFIRM_PLACED:
                if placed_off_target(self.look_port.Eval(context), status, self._place_target(status)):
                    status.place_corrections += 1  # take it again from where it stands
                    return True, self._start_task(context, status, phase.if_off, 0, t, look)
            elif phase.kind == PhaseKind.CHECK_MOVED:
                if read_look(self.look_port.Eval(context), status, True) and status.corrections < MAX_CORRECTIONS:
                    status.corrections += 1  # it moved: back off, then reach for it where it is now
                    return True, self._start_task(context, status, phase.if_off, 0, t, look)
            else:
                read_look(self.look_port.Eval(context), status)
        elif t + 1e-9 < status.phase_start_s + phase.wait_s:
            return False, look
        return True, self._start_phase(context, status, status.phase_index + 1, t, look)

    def _place_target(self, status: PickStatus) -> RigidTransform:
        """Where the object is set down: a clear's spot in the drop zone, the place target, or where it was seen."""
        if status.place_target_W is not None:
            return status.place_target_W
        return status.belief.seen_W if self.place_target_W is None else self.place_target_W

    def _not_holding(self, context, status: PickStatus, when: str = "") -> str:
        """Measures both hands' openings (m); why they do not both hold something, or "" if they do."""
        status.grasp_widths = self._hand_widths(context)
        logging.info("hands closed to %s mm", ", ".join(f"{1000 * width:.1f}" for width in status.grasp_widths))
        return not_holding(status.grasp_widths, when)

    def _hand_widths(self, context) -> tuple[float, ...]:
        """Both hands' measured openings (m), in SIDES order."""
        return tuple(self.hand_state_ports[side].Eval(context)[0] for side in SIDES)

    def _attempt_failed(
        self, context, status: PickStatus, stage: Stage, message: str, look: LookRequest, t: float
    ) -> LookRequest:
        """A failed check: the task's if_check_fails (the recovery) runs before the next attempt, or, with none left,
        the pick fails."""
        recovery = self.tasks[status.task].if_check_fails
        if stage not in RETRIED_STAGES or status.attempt >= self.max_attempts or recovery is None:
            fail(status, stage, message)
            return look
        status.attempt_failures = (*status.attempt_failures, (str(stage), stage_message(stage, message)))
        logging.warning(
            "attempt %d of %d failed at %s: %s; recovering", status.attempt, self.max_attempts, stage, message
        )
        return self._start_task(context, status, recovery, 0, t, look)
