"""Runs a pick in simulation and judges it against the simulator's ground truth.

Success: at the end, the object's origin is at least LIFT_SUCCESS_M above where it
rested, it stayed that high for the last HOLD_CHECK_S seconds, and both hands
touch it.
"""

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import Context, Diagram, EventStatus

from diagrams.scenario import Scenario
from diagrams.station import CLUTTER_INSTANCE, HAND_INSTANCES, OBJECT_INSTANCE
from systems.messages import Mode
from systems.planning.closure import relative_deviations

LIFT_SUCCESS_M = 0.10
# The place task: the object rests within these of the target (m; rad for its yaw and its tilt), and never
# moved more than DROP_SLIP_M in the hands while they held it.
PLACE_TOLERANCE_M = 0.02
PLACE_TOLERANCE_RAD = np.radians(5.0)
DROP_SLIP_M = 0.03
HOLD_CHECK_S = 2.0
SAMPLE_S = 0.05
# The executed closure: sampled this often during the held moves (the supervisor's modes HELD_MOVES), s.
CLOSURE_SAMPLE_S = 0.01
HELD_MOVES = (Mode.LIFT, Mode.CARRY, Mode.SET_DOWN, Mode.AIM_APPROACH, Mode.AIM, Mode.AIM_BACK, Mode.POUR_APPROACH,
              Mode.POUR, Mode.POUR_BACK)  # fmt: skip
# The modes in which both hands hold the object (a place's, an aim's).
HELD_MODES = (*HELD_MOVES, Mode.LOOK, Mode.LOOK_AGAIN, Mode.LOOK_OVER, Mode.AIM_HOLD, Mode.POUR_HOLD)
# The modes that begin to let go of a set-down object (an aim's relax, then the opening).
LETTING_GO = (Mode.RELAX, Mode.RELEASE)
# The modes of a failed attempt's recovery (systems/pick_tasks.py's recovery_task).
RECOVERY_MODES = (Mode.RECOVER_OPEN, Mode.RECOVER_RETREAT, Mode.RECOVER_HOME)


@dataclass
class PickOutcome:
    """What happened, measured on the simulator's ground truth."""

    success: bool
    # Height of the object's origin above its resting height at the end, m.
    lift_height_m: float
    # Lowest lift height over the final HOLD_CHECK_S seconds, m.
    min_hold_height_m: float
    # Which hands touch the object at the end.
    hands_in_contact: list[str] = field(default_factory=list)
    sim_time_s: float = 0.0
    wall_time_s: float = 0.0
    message: str = ""
    planning_s: float = 0.0
    # The autonomous pick's stage wall times, s, and the stage that stopped it, if one did.
    stages: dict[str, float] = field(default_factory=dict)
    failed_stage: str = ""
    # Attempts at the task (a failed check starts another), and each failed one's {"stage", "message"}.
    attempts_made: int = 1
    attempt_failures: list[dict[str, str]] = field(default_factory=list)
    # The largest deviations of the hands' relative pose along the played held moves (lift, carry, ...):
    # {"max_translation_dev_m": m, "max_orientation_dev_rad": rad}, NaN without a held move.
    closure: dict[str, float] = field(default_factory=dict)
    # The same as executed, measured on the simulated plant every CLOSURE_SAMPLE_S (ExecutedClosure), with
    # "samples": how many were taken.
    closure_executed: dict[str, float] = field(default_factory=dict)
    # On a real LCM bus: the arm commands sent ("sent"), the largest wall-time gap between two ("max_gap_s"),
    # and how many came more than two control periods after the one before ("late").
    commands: dict = field(default_factory=dict)
    # The place task's judgement: {"error_m": xy distance to the target, "yaw_error_rad", "tilt_rad": of the
    # object's z axis from vertical, "max_slip_m": how far it moved in the hands while held, "dropped", and
    # "set_down_error_m", "set_down_yaw_error_rad": the same when the hands began to let go; "release_turn_rad",
    # "release_shift_m": how far letting go and backing off turned it about the vertical and moved it (the last
    # time), "corrections": how often the object was taken again and set down again after a look found it off}.
    place: dict = field(default_factory=dict)
    # Using the held object (the aim task, diagrams/aim_judge.py): {"task": "aim", the measured figures}.
    use: dict = field(default_factory=dict)
    # The clear task's judgement (diagrams/clear_judge.py): every familiar object's record ("objects": where it started
    # and ended, its true footprints there, and why it is or is not cleared), how many were cleared ("objects_cleared",
    # "objects_cleared_share"), "others_moved_m_max" (the distractors') and the drop "zone"; and the supervisor's own
    # record of each object it took on ("taken_on").
    clear: dict = field(default_factory=dict)
    # What the pick waited on, s: the arms held, their moves paused, while the robot's status was stale
    # ("status_held_s"); perception's frames came this long after asking, all together ("frames_waited_s": a few
    # control periods a frame, more while the camera's images had stopped).
    waits: dict = field(default_factory=dict)
    # How far the perceived object pose was from the true one when the camera saw it: {"position_error_m": xy
    # distance, "yaw_error_rad"}, the "category" perception took and, where the user named it, the
    # "network_category" the segmenter's network gave (empty when the pick did not perceive), the "grasps" message
    # (where each grasp came from, or why there were none) and, where the object's true grasps are known,
    # "grasp_errors_m": {hand: how far its perceived grasp frame lay from the true one} (the last attempt's frame)
    # and, where its true parts are known, "grasps_on_handles": {hand: whether that frame lay on the hand's handle};
    # where a tool frame was perceived and the true one is known, "tool_errors": {"tip_m", "axis_rad"}.
    perception: dict = field(default_factory=dict)
    # How far each other object on the table (scenario.clutter, in order) ever was from where it had settled, m.
    others_moved_m: list[float] = field(default_factory=list)
    # The object's true pose once it had settled (t >= 0.4 s), for the above (None without an object).
    object_rest_W: object = None
    # The simulator's final context (for further inspection).
    context: object = None


def pose_error(X_estimate, X_true) -> dict[str, float]:
    """{"position_error_m": xy distance, "yaw_error_rad": |yaw| of the rotation between them} of two poses in W."""
    R = X_true.rotation().inverse() @ X_estimate.rotation()
    return {
        "position_error_m": float(np.linalg.norm(X_estimate.translation()[:2] - X_true.translation()[:2])),
        "yaw_error_rad": abs(float(RollPitchYaw(R).yaw_angle())),
    }


def station_plant(diagram: Diagram) -> MultibodyPlant:
    return diagram.GetSubsystemByName("station").GetSubsystemByName("plant")


def object_body(plant: MultibodyPlant):
    return plant.get_body(plant.GetBodyIndices(plant.GetModelInstanceByName(OBJECT_INSTANCE))[0])


def hands_touching_object(plant: MultibodyPlant, plant_context) -> list[str]:
    """Names of the hands ("left", "right") with a contact against the object."""
    return hands_touching(plant, plant_context, object_body(plant))


def hands_touching(plant: MultibodyPlant, plant_context, body) -> list[str]:
    """Names of the hands ("left", "right") with a contact against `body`."""
    results = plant.get_contact_results_output_port().Eval(plant_context)
    object_index = body.index()
    hand_bodies = {
        side: set(plant.GetBodyIndices(plant.GetModelInstanceByName(name))) for side, name in HAND_INSTANCES.items()
    }
    touching = set()
    for i in range(results.num_point_pair_contacts()):
        info = results.point_pair_contact_info(i)
        pair = {info.bodyA_index(), info.bodyB_index()}
        if object_index in pair:
            for side, bodies in hand_bodies.items():
                if pair & bodies:
                    touching.add(side)
    return sorted(touching)


def grasp_frames(plant: MultibodyPlant) -> list:
    """The left and right hands' grasp frames G on the station's plant."""
    return [plant.GetFrameByName("grasp_frame", plant.GetModelInstanceByName(n)) for n in HAND_INSTANCES.values()]


class ExecutedClosure:
    """The closure as executed: during each held move (the modes HELD_MOVES, told by mode_of(context)), the
    relative pose X_G1G2 of the two grasp frames on the simulated plant every CLOSURE_SAMPLE_S, against its
    value when that move began. Deviations as the planner's (closure.relative_deviations): the largest
    translation component (m) and the rotation angle (rad). sample() runs after every simulator step."""

    def __init__(self, plant: MultibodyPlant, mode_of: Callable):
        self.plant, self.mode_of = plant, mode_of
        self.frames = grasp_frames(plant)
        self.next_s, self.mode, self.X_start = 0.0, "", None
        self.t_dev, self.o_dev = [], []

    def sample(self, context) -> None:
        t = context.get_time()
        if t + 1e-9 < self.next_s:
            return
        self.next_s = (np.floor(t / CLOSURE_SAMPLE_S + 1e-6) + 1) * CLOSURE_SAMPLE_S
        mode = str(self.mode_of(context))
        if mode not in HELD_MOVES:
            self.mode = mode
            return
        plant_context = self.plant.GetMyContextFromRoot(context)
        left, right = (frame.CalcPoseInWorld(plant_context) for frame in self.frames)
        X_G1G2 = (left.inverse() @ right).GetAsMatrix4()
        if mode != self.mode:  # a held move begins: its relative pose is the reference
            self.mode, self.X_start = mode, X_G1G2
        t_dev, o_dev = relative_deviations(X_G1G2[None], self.X_start)
        self.t_dev.append(float(t_dev[0]))
        self.o_dev.append(float(o_dev[0]))

    def report(self) -> dict[str, float]:
        """{"max_translation_dev_m", "max_orientation_dev_rad", "samples"} (NaN without a held move)."""
        return {
            "max_translation_dev_m": max(self.t_dev, default=float("nan")),
            "max_orientation_dev_rad": max(self.o_dev, default=float("nan")),
            "samples": len(self.t_dev),
        }


class _Nudge:
    """The injected fault faults.nudge_xy: the object moved on the table (simulation only)."""

    def __init__(self, plant: MultibodyPlant, context, scenario: Scenario):
        self.plant, self.plant_context = plant, plant.GetMyMutableContextFromRoot(context)
        self.xy, self.at_s, self.done = scenario.faults.nudge_xy, scenario.faults.nudge_at_s, False

    def at(self, t: float):
        if self.done or t + 1e-9 < self.at_s:
            return
        body = object_body(self.plant)
        X_WO = body.EvalPoseInWorld(self.plant_context)
        moved = RigidTransform(X_WO.rotation(), X_WO.translation() + [*self.xy, 0.0])
        self.plant.SetFreeBodyPose(self.plant_context, body, moved)
        self.plant.SetFreeBodySpatialVelocity(self.plant_context, body, SpatialVelocity.Zero())
        logging.info("fault: the object nudged by %s m at t = %.2f s", self.xy, t)
        self.done = True


def clutter_bodies(plant: MultibodyPlant) -> list:
    """The bodies of the other objects on the table (scenario.clutter), in order."""
    bodies, index = [], 0
    while plant.HasModelInstanceNamed(name := CLUTTER_INSTANCE.format(index)):
        bodies.append(plant.get_body(plant.GetBodyIndices(plant.GetModelInstanceByName(name))[0]))
        index += 1
    return bodies


SETTLED_S = 0.4  # s: the objects have settled on the table by then


class LiftJudge:
    """Judges a pick on the simulator's ground truth: sample() every SAMPLE_S, then outcome(). Also records how far
    every other object on the table moved from where it had settled."""

    def __init__(self, plant: MultibodyPlant, context):
        self.plant, self.plant_context = plant, plant.GetMyContextFromRoot(context)
        self.body = object_body(plant) if plant.HasModelInstanceNamed(OBJECT_INSTANCE) else None
        self.X_rest = None  # the object's pose once it has settled
        self.heights = []
        self.others = clutter_bodies(plant)
        self.others_rest, self.others_moved = None, np.zeros(len(self.others))

    def sample(self, t: float) -> float:
        """Records and returns the object origin's height at context time t (NaN without an object), m."""
        z = self.body.EvalPoseInWorld(self.plant_context).translation()[2] if self.body is not None else np.nan
        if self.X_rest is None and self.body is not None and t >= SETTLED_S:
            self.X_rest = self.body.EvalPoseInWorld(self.plant_context)
        if self.others and t >= SETTLED_S:
            where = np.array([body.EvalPoseInWorld(self.plant_context).translation() for body in self.others])
            if self.others_rest is None:
                self.others_rest = where
            self.others_moved = np.maximum(self.others_moved, np.linalg.norm(where - self.others_rest, axis=1))
        self.heights.append((t, z))
        return z

    def outcome(self) -> PickOutcome:
        times, z = np.array(self.heights).T if self.heights else (np.zeros(1), np.full(1, np.nan))
        lift = np.nan_to_num(z - (self.X_rest.translation()[2] if self.X_rest is not None else z[0]))
        duration = float(times[-1])
        final_window = times >= duration - HOLD_CHECK_S
        touching = hands_touching_object(self.plant, self.plant_context) if self.body is not None else []
        min_hold = float(lift[final_window].min())
        success = bool(min_hold >= LIFT_SUCCESS_M and touching == ["left", "right"])
        if success:
            message = "lifted and held by both hands"
        elif min_hold < LIFT_SUCCESS_M:
            message = f"not lifted: lowest height over the last {HOLD_CHECK_S} s was {min_hold:.3f} m"
        else:
            message = f"lifted but touched only by {touching or 'no hand'}"
        outcome = PickOutcome(success, float(lift[-1]), min_hold, touching, duration, 0.0, message)
        outcome.object_rest_W = self.X_rest
        outcome.others_moved_m = [float(m) for m in self.others_moved]
        return outcome


class PlaceJudge(LiftJudge):
    """Judges the place task on ground truth: the object ends resting upright within PLACE_TOLERANCE_M and
    PLACE_TOLERANCE_RAD of the target (X_W_target; None: where it had settled before the pick), let go by both
    hands, and never slipped more than DROP_SLIP_M in the hands (its origin against the grasp frames' midpoint, in
    the left grasp frame) while they held it (the modes `held_modes`, told by mode_of(context); each stretch of
    them is one grasp: a grasp taken again, after a retry or a set-down off the target, is not a slip, and a failed
    attempt's slips do not count). The release measured is the last one."""

    def __init__(
        self,
        plant,
        context,
        X_W_target,
        mode_of: Callable,
        held_modes=HELD_MODES,
    ):
        super().__init__(plant, context)
        self.context, self.X_W_target, self.mode_of, self.held_modes = context, X_W_target, mode_of, held_modes
        self.frames = grasp_frames(plant)
        self.held_offset, self.max_slip = None, 0.0
        self.X_set_down = None  # the object's pose when the hands last began to let go
        self.last_mode = None

    def sample(self, t: float) -> float:
        z = super().sample(t)
        mode, last = self.mode_of(self.context), self.last_mode
        self.last_mode = mode
        if self.body is not None and mode in LETTING_GO and last not in LETTING_GO:  # (an aim relaxes first)
            self.X_set_down = self.body.EvalPoseInWorld(self.plant_context)
        if last not in self.held_modes:
            self.held_offset = None  # a new grasp
        if mode in RECOVERY_MODES:
            self.max_slip = 0.0  # a failed attempt's grasp is not the place's (the object may have slipped out)
        if self.body is not None and mode in self.held_modes:
            X_WG = [f.CalcPoseInWorld(self.plant_context) for f in self.frames]
            between = np.mean([X.translation() for X in X_WG], axis=0)
            # In the left grasp frame's axes: the hands tilting or turning with the object is not a slip.
            offset = X_WG[0].rotation().inverse() @ (
                self.body.EvalPoseInWorld(self.plant_context).translation() - between
            )
            if self.held_offset is None:
                self.held_offset = offset
            self.max_slip = max(self.max_slip, float(np.linalg.norm(offset - self.held_offset)))
        return z

    @staticmethod
    def judged_use(outcome: PickOutcome, use: dict, checks: dict[str, bool], done: str) -> PickOutcome:
        """The outcome of a task that uses the object, then sets it down where it stood: `use` (its figures) with
        use[done] whether every check ({what: passed}) passed; a success where it was set down and they all passed;
        the message says which failed (a use task's judge: aim_judge.py, pour_judge.py)."""
        failed = [what for what, ok in checks.items() if not ok]
        use[done] = not failed
        set_down = outcome.message.replace("placed upright on the target", "set down where it stood")
        outcome.use, outcome.success = use, outcome.success and not failed
        outcome.message = f"{done if not failed else f'not {done}: ' + '; '.join(failed)}; {set_down}"
        return outcome

    def target(self) -> RigidTransform:
        """Where the object is to end: the target, or where it had settled."""
        return self.X_rest if self.X_W_target is None else self.X_W_target

    def outcome(self) -> PickOutcome:
        outcome = super().outcome()
        if self.body is None or self.target() is None:
            return outcome
        X_WO = self.body.EvalPoseInWorld(self.plant_context)
        off = pose_error(X_WO, self.target())
        error, yaw_error = off["position_error_m"], off["yaw_error_rad"]
        tilt = float(np.arccos(np.clip(X_WO.rotation().matrix()[2, 2], -1.0, 1.0)))
        resting = abs(X_WO.translation()[2] - self.target().translation()[2]) < 0.01
        dropped = self.max_slip > DROP_SLIP_M
        outcome.place = {"error_m": error, "yaw_error_rad": yaw_error, "tilt_rad": tilt,
                         "max_slip_m": self.max_slip, "dropped": dropped}  # fmt: skip
        if self.X_set_down is not None:  # where the set-down left it, before letting go and backing off
            set_down = pose_error(self.X_set_down, self.target())
            outcome.place["set_down_error_m"] = set_down["position_error_m"]
            outcome.place["set_down_yaw_error_rad"] = set_down["yaw_error_rad"]
            released = pose_error(X_WO, self.X_set_down)
            outcome.place["release_turn_rad"] = released["yaw_error_rad"]
            outcome.place["release_shift_m"] = released["position_error_m"]
        checks = {
            f"{error * 100:.1f} cm from the target": error <= PLACE_TOLERANCE_M,
            f"turned {np.degrees(yaw_error):.1f} deg from it": yaw_error <= PLACE_TOLERANCE_RAD,
            f"tilted {np.degrees(tilt):.1f} deg": tilt <= PLACE_TOLERANCE_RAD,
            "not resting on the table": resting,
            f"slipped {self.max_slip * 100:.1f} cm in the hands (dropped)": not dropped,
            f"still touched by {outcome.hands_in_contact}": not outcome.hands_in_contact,
        }
        failed = [what for what, ok in checks.items() if not ok]
        outcome.success = not failed
        outcome.message = "placed upright on the target" if not failed else "not placed: " + "; ".join(failed)
        return outcome


def simulate_pick(
    diagram: Diagram,
    scenario: Scenario,
    duration: float | Callable[[Context], float],
    meshcat: Meshcat | None = None,
    record: Path | None = None,
    plant: MultibodyPlant | None = None,
    make_judge: Callable | None = None,
    mode_of: Callable | None = None,
) -> PickOutcome:
    """Simulates until `duration` (s, or a function of the context giving the end time) and judges
    the pick on ground truth: `plant`'s (default: the plant of the diagram's "station"), with
    make_judge(plant, context) (default: a LiftJudge). With mode_of(context) (the pick's mode), the
    closure as executed too (ExecutedClosure: it only reads the plant, after every step)."""
    end_time = duration if callable(duration) else (lambda context: duration)
    simulator = Simulator(diagram)
    ApplySimulatorConfig(scenario.simulator_config, simulator)
    context = simulator.get_mutable_context()
    plant = plant or station_plant(diagram)
    judge = (make_judge or LiftJudge)(plant, context)
    closure = ExecutedClosure(plant, mode_of) if mode_of is not None else None
    if closure is not None:

        def monitor(root_context):
            closure.sample(root_context)
            return EventStatus.Succeeded()

        simulator.set_monitor(monitor)
    if meshcat is not None and record is not None:
        meshcat.StartRecording(set_visualizations_while_recording=False)
    start = time.perf_counter()
    simulator.Initialize()
    nudge = _Nudge(plant, context, scenario) if any(scenario.faults.nudge_xy) else None
    step = 0
    while (t := (step + 1) * SAMPLE_S) <= end_time(context) + 1e-9:
        step += 1
        simulator.AdvanceTo(t)
        if nudge is not None:
            nudge.at(t)
        z = judge.sample(t)
        if step % 40 == 0:
            logging.info("t = %4.1f s  object z = %.3f m", t, z)
    wall = time.perf_counter() - start
    if meshcat is not None and record is not None:
        meshcat.StopRecording()
        meshcat.PublishRecording()
        record.write_text(meshcat.StaticHtml())
        logging.info("wrote %s", record)
    outcome = judge.outcome()
    outcome.wall_time_s, outcome.context = wall, context
    if closure is not None:
        outcome.closure_executed = closure.report()
    return outcome
