"""The messages that pass between the pick's systems, and the names they use.

Every abstract port value of the pick lives here, so that a system knows another's message without
importing that system (and its dependencies: torch, the planner). Frames: W is the world (z up),
O the object, G a hand's grasp frame (z_G its approach axis). Lengths in metres, angles in radians,
times in seconds (context time unless a field says wall time).
"""

import enum
import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RigidTransform
from pydrake.trajectories import PiecewisePolynomial

from systems.perception.depth_view import DepthView
from systems.planning.drop_zone import DropZone
from systems.shape_space.tool_frame import ToolFrame

SIDES = ("left", "right")
OPEN_WIDTH = 0.1  # m: the hands' opening while reaching (and the hand command's default)
CLOSED_WIDTH = 0.0  # m: the fingers stop on the handle; the joint effort limit sets the squeeze


class MoveKind(enum.StrEnum):
    """How a PlanRequest moves the hands."""

    FREE = "free"  # both hands to their targets around the obstacles (STOMP when the straight move collides)
    STRAIGHT = "straight"  # each hand on a line to its target
    HELD = "held"  # both hands hold the object and move it by a rigid motion (closure constraint)


class Targets(enum.StrEnum):
    """Where a free or straight move takes the hands."""

    PREGRASP = "pregrasp"  # the grasp poses' <side>_pregrasp
    GRASP = "grasp"  # the grasp poses' <side>_grasp
    RETREAT = "retreat"  # each hand back along its approach axis from where it is
    HOME = "home"  # (free moves) back to the joint configuration PlanRequest.q_goal, where the pick started
    MEASURED = "measured"  # (straight moves) the command to PlanRequest.q_goal, where the arms are measured now


class PlaceGoal(enum.StrEnum):
    """The held moves towards a goal: a place target's (systems/planning/place_goals.py), a board's target's
    (systems/planning/aim_goals.py) or a container's opening's (systems/planning/pour_goals.py)."""

    CARRY = "carry"  # over the place target, turned to its yaw, at the height the object is carried at
    SET_DOWN = "set_down"  # straight down onto the place target
    AIM_APPROACH = "aim_approach"  # the tool aimed at the board's target, AIM_APPROACH_M short of the aim
    AIM = "aim"  # on along the board's normal to the aim: the tool's tip its standoff off the target
    AIM_BACK = "aim_back"  # back along the board's normal by AIM_APPROACH_M
    POUR_APPROACH = "pour_approach"  # upright, turned and moved so that the tilt puts the spout over the opening
    POUR = "pour"  # tilted about the grasps' midpoint until the outflow points the pour's tilt down
    POUR_BACK = "pour_back"  # upright again: the tilt undone about the same pivot


class Mode(enum.StrEnum):
    """Where a pick stands: before perceiving, one of the task's phases, or the end."""

    WAITING = "waiting"
    PERCEIVING = "perceiving"
    REACH = "reach"
    CHECK = "check"  # a look at the object on the table before the approach: did it move?
    BACK_OFF = "back_off"  # it moved: the hands back off before they reach for it again
    APPROACH = "approach"
    CLOSE = "close"
    LOOK = "look"
    LIFT = "lift"
    HOLD = "hold"
    CARRY = "carry"
    LOOK_AGAIN = "look_again"
    SET_DOWN = "set_down"
    RELAX = "relax"  # the arms' command brought to where they are: what a held move left pressing is let go
    RELEASE = "release"
    RETREAT = "retreat"
    CONFIRM = "confirm"  # a look at the object set down: does it stand where it was to go?
    # Aiming a held tool at a board's target: in front of it, onto it, hold, back off.
    AIM_APPROACH = "aim_approach"
    AIM = "aim"
    AIM_HOLD = "aim_hold"
    AIM_BACK = "aim_back"
    # Pouring from a held can into a container: over it, tilted, hold, upright again.
    POUR_APPROACH = "pour_approach"
    # A look at the held object before its use: the can over the container, the drill in front of the board.
    LOOK_OVER = "look_over"
    POUR = "pour"
    POUR_HOLD = "pour_hold"
    POUR_BACK = "pour_back"
    # Recovering from a failed attempt: open the hands, back off, go back to where the pick started.
    RECOVER_OPEN = "recover_open"
    RECOVER_RETREAT = "recover_retreat"
    RECOVER_HOME = "recover_home"
    # A clear task's object given up: let go, back off; and between two objects, home (out of the camera's way).
    NEXT_OBJECT_OPEN = "next_object_open"
    NEXT_OBJECT_RETREAT = "next_object_retreat"
    NEXT_OBJECT_HOME = "next_object_home"
    DONE = "done"
    FAILED = "failed"


class PhaseKind(enum.StrEnum):
    """What a phase of a task does (systems/pick_tasks.py)."""

    MOVE = "move"  # plan a motion (a MoveKind) and play it out
    CLOSE = "close"  # close both hands, let the grip settle, then check that each holds something
    OPEN = "open"  # open both hands (to a width, or beyond the widest grasp) and let them settle
    LOOK = "look"  # find the held object again: the moves that follow start from there
    CHECK_MOVED = "check_moved"  # look at the object on the table: where it moved, reach for it again
    CONFIRM_PLACED = "confirm_placed"  # look at the object set down: where it stands off its target, take it again
    WAIT = "wait"  # hold still


class TaskName(enum.StrEnum):
    """The pick's named phase lists (systems/pick_tasks.py)."""

    LIFT = "lift"  # the paper's task: grasp the object, lift it, hold it
    PLACE = "place"  # grasp it, lift it, carry it to the place target, set it down, let go
    REPLACE = "replace"  # set down off its target: take it again where it stands, set it down on the target
    BACK_OFF = "back_off"  # it moved before the approach: back off before reaching for it again
    RECOVER = "recover"  # a failed attempt: open the hands, back off, go back to where the pick started
    AIM = "aim"  # grasp a drill, lift it, aim its bit at a board's target, hold, back off, set it down where it stood
    POUR = "pour"  # grasp a can, lift it, pour into a container, hold, bring it upright, set it down where it stood
    SET_BACK = "set_back"  # the held object's goal is out of reach: set it down where it was taken, let go
    GIVE_UP = "give_up"  # a clear task's object given up: open the hands, back off
    HOME = "home"  # between a clear task's objects: back to the start, in the scene as seen after the last one


class Stage(enum.StrEnum):
    """The stage a failed pick stopped at."""

    CAMERA = "camera"  # no image came from the camera
    STATUS = "status"  # the robot's status stopped while it moved
    SEGMENTATION = "segmentation"
    POSE = "pose"
    REGISTRATION = "registration"
    PLANNING = "planning"
    GRASP = "grasp"  # a hand closed on nothing
    BOARD = "board"  # the aim task's board or its target was not seen
    CONTAINER = "container"  # the pour task's container (its opening) was not seen


# Perception's stages, in the order they run.
PERCEPTION_STAGES = (Stage.SEGMENTATION, Stage.POSE, Stage.REGISTRATION)


@dataclass
class Segmentation:
    """The dominant object in view, or an explicit "nothing found"."""

    found: bool
    category: str = ""
    # H x W bool at the camera's resolution; all False when nothing was found.
    mask: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), bool))
    pixel_count: int = 0
    message: str = ""
    compute_s: float = 0.0  # wall time of the segmentation alone
    # Where the user named the category: the class the network gave most of the region (reported, not obeyed).
    network_category: str = ""
    # H x W uint8: each of the object's pixels' functional part (systems/perception/parts.py's PartRole values; 0
    # off the mask); None where there is no part network.
    parts: np.ndarray | None = None


class PartRole(enum.IntEnum):
    """What a part of an object is for; the value is its id in a part image (uint8)."""

    # Not the object (a part image's background).
    NONE = 0
    # The rest of the object: what no hand holds and no tool is.
    BODY = 1
    # The part the left hand's grasp lies on.
    LEFT_HANDLE = 2
    # The part the right hand's grasp lies on.
    RIGHT_HANDLE = 3
    # What the object works with: a can's spout (with its rose), a drill's chuck.
    TOOL = 4


@dataclass(frozen=True)
class SeenPart:
    """A functional part as the camera saw it: its points (N x 3, m, W), and whether the image's border cut it."""

    points_W: np.ndarray
    cut_off: bool = False


@dataclass
class ObjectEstimate:
    """The object's point cloud and initial pose, or why there is none."""

    found: bool
    category: str = ""
    X_WO: RigidTransform = field(default_factory=RigidTransform)
    points_W: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # N x 3, metres
    message: str = ""
    viewpoint_W: np.ndarray | None = None  # where the points were seen from: the camera's position in W, m
    compute_s: float = 0.0  # wall time of the estimate alone (its inputs' stages excluded)
    view: DepthView | None = None  # the depth image the points came from (None: unknown)
    # The object's functional parts as seen (a part not seen has none); empty without a part network.
    parts: dict[PartRole, SeenPart] = field(default_factory=dict)


@dataclass
class GraspPoses:
    """Per-arm control poses in the world, or why there are none."""

    found: bool
    poses_W: dict[str, RigidTransform] = field(default_factory=dict)  # left/right pregrasp/grasp -> X_WG
    message: str = ""
    compute_s: float = 0.0  # wall time of the registration alone
    tool_W: ToolFrame | None = None  # the object's tool frame (the spout's tip, a bit's), where a sound fit gave one


@dataclass
class PerceptionResult:
    """What perception made of one camera frame, or the stage that found nothing and why.

    The ground-truth source fills the same fields from the simulator (no stage seconds)."""

    found: bool = False
    failed_stage: Stage | None = None
    message: str = ""
    category: str = ""
    X_WO_seen: RigidTransform | None = None  # the object's pose as perceived (registered)
    grasps: GraspPoses = field(default_factory=lambda: GraspPoses(False))
    points_W: np.ndarray | None = None  # the camera's object points, N x 3 (None: not seen by a camera)
    reconstruction_W: np.ndarray | None = None  # the whole inferred shape, N x 3
    # Wall seconds of each stage that ran, by stage name (segmentation, pose, registration).
    stage_seconds: dict[str, float] = field(default_factory=dict)
    # Where the user named the category: what the segmenter's network made of the object (Segmentation's).
    network_category: str = ""
    # The process's time.perf_counter() when the frame was latched and when this result was complete, s (NaN:
    # no camera). Reported only: perception's latency as the pick saw it, the simulator's work between included.
    latched_wall_s: float = math.nan
    finished_wall_s: float = math.nan


@dataclass
class BoardSeen:
    """The aim task's board as perceived (systems/perception/board_finder.py), or why it was not."""

    found: bool = False
    normal_W: np.ndarray | None = None  # (3,) unit: out of the board's face, towards the camera
    target_W: np.ndarray | None = None  # (3,) m: the target's centre, on the face
    message: str = ""


@dataclass
class ContainerSeen:
    """The pour task's container as perceived (systems/perception/container_finder.py), or why it was not."""

    found: bool = False
    centre_W: np.ndarray | None = None  # (3,) m: its opening's centre, at the rim's height
    radius: float = 0.0  # m: the opening's
    message: str = ""


@dataclass(frozen=True)
class PourTarget:
    """What the pour task pours: the held can's tool frame (the spout's tip, the outflow) and the tilt's pivot (the
    grasps' midpoint), in O; the container's opening in W; how far below the horizontal the outflow must point."""

    tool_O: ToolFrame
    pivot_O: np.ndarray  # (3,) m
    centre_W: np.ndarray  # (3,) m: the opening's centre, at its rim's height
    radius: float  # m
    tilt_below_rad: float


@dataclass(frozen=True)
class AimTarget:
    """What the aim task aims: the held object's tool frame and the turn's pivot (the grasps' midpoint), in O; the
    board's target and outward normal, in W."""

    tool_O: ToolFrame
    pivot_O: np.ndarray  # (3,) m
    target_W: np.ndarray  # (3,) m
    normal_W: np.ndarray  # (3,) unit


@dataclass
class PlanRequest:
    """What to plan. Goals are Cartesian: hand poses named in the grasp_poses input, or a held move."""

    id: int = -1  # a new id asks for a new plan
    phase: str = ""  # the pick's phase it serves ("reach", "approach", "lift", ...), for messages
    q_start: np.ndarray = field(default_factory=lambda: np.zeros(14))  # rad; the robot holds here meanwhile
    path: MoveKind = MoveKind.FREE
    targets: Targets = Targets.PREGRASP  # free and straight moves
    X_motion_W: RigidTransform = field(default_factory=RigidTransform)  # held moves: X_WG -> X_motion_W X_WG
    # Held moves: where the whole translation is out of reach, shorter ones down to this fraction will do.
    min_fraction: float = 1.0
    # Held moves: keep the held object (the obstacle cloud moved by this, its motion since it was seen)
    # clear of the scene; None: the robot only.
    carried_motion_W: RigidTransform | None = None
    q_goal: np.ndarray | None = None  # Targets.HOME: the planned joints to go back to, rad
    # Pre-grasp and grasp targets (and the obstacle cloud): the object's motion in W since perception saw it,
    # as a look before the approach found it (None: it has not moved).
    object_motion_W: RigidTransform | None = None
    # Grasp targets: per side, the grasp the hand goes to as a transform of the perceived one on the right (X_GG':
    # rolled about or slid along the handle), as the reach to the pre-grasps chose it (None: as perceived).
    grasp_offsets_G: dict[str, RigidTransform] | None = None
    # Held moves: a container's inside, left out of the scene (the pour's spout goes over it): the scene's points
    # within the radius (m) of the vertical line through the point (3, W: the opening's centre) and below it.
    inside_left_out: tuple[np.ndarray, float] | None = None
    # Held moves: plan them only where the hands can then back off the whole way from the move's end (the retreat,
    # straight along their approach axes; a clear's set-down, whose next spot in the zone can be tried instead).
    full_back_off: bool = False
    # More of the scene (N x 3 points in W, m), planned around as the camera's: a clear's objects set down in the
    # drop zone, on all its moves (the arms that have just backed off one, or the object carried, hide it from the
    # camera; None: no more).
    set_down_W: np.ndarray | None = None
    # Held moves: the goal solved onto the hands' targets within 0.1 mm and 1 mrad, not the path's 1 mm and 10-40 mrad
    # (a tool's precise move: an aim).
    exact_goal: bool = False
    # Held moves: other motions (X_motion_W each) to try in turn where X_motion_W is out of reach or finds no plan (a
    # pour's tilt, rolled about the outflow: systems/planning/pour_goals.py, pour_rolls).
    alternatives: tuple[RigidTransform, ...] = ()


@dataclass(frozen=True)
class Playback:
    """How far the trajectory source has played the current plan (systems/robot_io/trajectory_source.py)."""

    plan_id: int = -1  # the plan being played (-1: none yet)
    time_s: float = 0.0  # the trajectory's time reached, s (the context time less the pauses)
    paused_for_s: float = 0.0  # how long the current pause has lasted, s (0: playing)
    paused_total_s: float = 0.0  # every pause so far, every plan's, the current one included, s


@dataclass
class PlanResult:
    """A plan, or why there is none. Times are context seconds."""

    id: int = -1
    phase: str = ""
    success: bool = False
    trajectory: PiecewisePolynomial | None = None  # the planned joints over context time
    message: str = "no plan requested"
    planning_s: float = 0.0  # wall time the planning took (reported, never simulated)
    finished_wall_s: float = math.nan  # the process's time.perf_counter() when it was done, s (reported only)
    # Held moves: the largest deviation of the hands' relative pose along the played trajectory
    # (every 10 ms), m and rad; NaN for other motions.
    closure_translation_dev_m: float = math.nan
    closure_orientation_dev_rad: float = math.nan
    # Held moves: the motion the hands (and the object) made, X_WG(end) X_WG(start)^-1 of the left hand.
    achieved_motion_W: RigidTransform | None = None
    # Each hand's grasp frame origin along the trajectory, samples x 3 in W (for the viewer).
    grasp_paths_W: dict[str, np.ndarray] = field(default_factory=dict)
    # Reaches to the pre-grasps: per side, the grasp the pre-grasp leads to, X_GG' of the perceived grasp G (the
    # identity, or another grasp of the same handle where the perceived one was out of that hand's reach).
    grasp_offsets_G: dict[str, RigidTransform] | None = None

    @property
    def end_s(self) -> float:
        return self.trajectory.end_time() if self.trajectory is not None else math.inf


@dataclass
class HandCommand:
    """Move both hands' opening from `from_width` to `width` (m) linearly over [start_s, start_s + duration_s]."""

    width: float = OPEN_WIDTH
    from_width: float = OPEN_WIDTH
    start_s: float = 0.0
    duration_s: float = 0.0

    def at(self, t: float) -> float:
        if self.duration_s <= 0 or t >= self.start_s + self.duration_s:
            return self.width if t >= self.start_s else self.from_width
        s = max(0.0, (t - self.start_s) / self.duration_s)
        return (1 - s) * self.from_width + s * self.width

    @property
    def end_s(self) -> float:
        return self.start_s + self.duration_s


@dataclass(frozen=True)
class ObjectBelief:
    """X_WO as perceived (`seen_W`) and where the pick's held moves and looks put it since (`now_W`)."""

    seen_W: RigidTransform
    now_W: RigidTransform

    @staticmethod
    def seen(X_WO: RigidTransform) -> "ObjectBelief":
        return ObjectBelief(X_WO, X_WO)

    def moved(self, X_motion_W: RigidTransform) -> "ObjectBelief":
        """The object moved by X_motion_W in W (a held move's achieved motion)."""
        return ObjectBelief(self.seen_W, X_motion_W @ self.now_W)

    def looked(self, X_WO: RigidTransform) -> "ObjectBelief":
        """A look found the object at X_WO."""
        return ObjectBelief(self.seen_W, X_WO)


@dataclass(frozen=True)
class LeftOut:
    """What the clear task's segmenter leaves out when it looks for the next object: the drop zone (objects there are
    cleared, and so are those near where it set objects down) and where the objects it gave up on stood."""

    zone: DropZone | None = None  # None: no zone
    given_up_W: tuple[np.ndarray, ...] = ()  # the outlines of the objects given up, as seen (M x 2, x, y in W, m)
    placed_W: tuple[np.ndarray, ...] = ()  # the footprints of the objects set down in the zone, at their spots (ditto)


@dataclass(frozen=True)
class ClearedObject:
    """One object a clear task took on: what it was, where it stood, where it went, and why not if it did not."""

    category: str
    seen_xy_W: tuple[float, float]  # where it was seen, m
    attempts: int
    cleared: bool = False
    target_xy_W: tuple[float, float] | None = None  # its spot in the drop zone, m (None: none was chosen)
    footprint_W: np.ndarray | None = None  # its footprint at that spot (M x 2 in W, m)
    seen_outline_W: np.ndarray | None = None  # the convex outline of its seen points where it stood (M x 2 in W, m)
    failed_stage: str = ""
    message: str = ""
    # Taken on in a later pass over the table (it may have been given up in an earlier one: a record of its own).
    later_pass: bool = False
    # Its inferred shape (N x 3 in W, m; the registrar's, thinned): where it was seen, and once cleared where it was
    # believed to stand after the set-down (None: no shape was inferred).
    shape_W: np.ndarray | None = None


@dataclass(frozen=True)
class LookRequest:
    """The supervisor asks for a look at the held object: frame `id`, the object expected at `expected_X_WO`."""

    id: int = 0
    expected_X_WO: RigidTransform = field(default_factory=RigidTransform)


@dataclass
class PickStatus:
    """Where the pick stands (the supervisor's state). Times are context (simulation or robot) seconds."""

    mode: Mode = Mode.WAITING
    failed_stage: Stage | str = ""  # when mode == FAILED
    message: str = ""
    phase_index: int = -1  # into the phases of `task`
    phase_start_s: float = 0.0
    perceive_id: int = 0  # the camera frame asked for
    asked_frame_s: float = 0.0  # when it was asked for, s
    frames_waited_s: float = 0.0  # how long perception's frames took to come after asking, all together, s
    pass_from: int = 0  # a clear's pass over the table began with this record of `objects` (see clear_progress.py)
    stop: tuple[int, float] = (-1, 0.0)  # a move stopped mid-way: its plan's id, and the trajectory's time there, s
    perceived: bool = False  # perception's result has been read
    request: PlanRequest = field(default_factory=PlanRequest)
    applied_plan_id: int = -1  # the last plan whose achieved motion the belief has taken
    hand: HandCommand = field(default_factory=HandCommand)
    grasp_widths: tuple[float, ...] = ()  # each hand's measured opening once closed, m
    # Where the robot stands still: first measured, then where each played trajectory ends (the planned joints, rad).
    plan_end_q: np.ndarray | None = None
    belief: ObjectBelief | None = None  # where the object is, once perceived
    # The grasps the last reach to the pre-grasps chose, X_GG' per side (PlanResult.grasp_offsets_G).
    grasp_offsets_G: dict | None = None
    looks_read: int = 0  # looks at the held object whose result was read
    q_start: np.ndarray | None = None  # where the robot stood when the pick began (planned joints, rad)
    q_home: np.ndarray | None = None  # where it goes home to: the start, or a clear's home between objects (rad)
    attempt: int = 1  # the attempt under way (a failed check starts the next, up to max_attempts)
    attempt_failures: tuple[tuple[str, str], ...] = ()  # (stage, message) of each failed attempt, in order
    task: TaskName | None = None  # the phase list under way (None: none yet, or perceiving for the next attempt)
    corrections: int = 0  # reaches planned again this attempt because a look found the object moved
    place_corrections: int = 0  # times the object was taken again after a set-down
    aim: AimTarget | None = None  # the aim task: what it aims at, once perceived
    pour: PourTarget | None = None  # the pour task: what it pours into, once perceived
    # A move out of reach whose task sets the object back down first: the pick's failure, told once it is down.
    pending_failure: tuple[str, str] | None = None
    # The clear task: the objects taken on so far, the one under way (where it was seen, its spot in the drop zone)
    # and its place target (a clear's spot, or a place target moved where no plan set the object down on it).
    objects: tuple[ClearedObject, ...] = ()
    current: ClearedObject | None = None
    place_target_W: RigidTransform | None = None
    homing: bool = False  # the frame asked for is the scene the move home avoids (no object is taken on from it)
    # The other spots the object may go to, best first ((X_WO, its footprint there or None) each): a clear's in the
    # zone, a place's beside its target (place_goals.nudged_targets); where no plan carries it to one, the next.
    spare_spots: tuple = ()
