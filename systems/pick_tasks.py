"""The pick's tasks as data: named lists of phases, each phase's kind said, and what comes after each list.

The supervisor (systems/pick_supervisor.py) runs one task at a time, its phases in order. A lift pick and a
place pick each set out on their own task after every camera frame; the other tasks are where the looks and
checks switch to:

  lift      reach, [check], approach, close, lift, hold                      -> done
  place     reach, [check], approach, close, look, lift, carry, look_again,
            set_down, release, retreat, confirm                              -> done
  replace   reach, approach, close, look, lift, set_down, release, retreat,
            confirm                                                          -> done
  aim       reach, [check], approach, close, look, lift, aim_approach,
            look_over, aim, aim_hold, aim_back, carry, look_again,
            set_down, relax, release, retreat, confirm                       -> done
  pour      reach, [check], approach, close, look, lift, pour_approach,
            look_over, pour, pour_hold, pour_back, carry, look_again,
            set_down, release, retreat, confirm                              -> done
  back_off  back_off                                                         -> the pick's task from its reach
  recover   recover_open, recover_retreat, recover_home                      -> the next attempt (a new frame)
  set_back  carry, set_down, release, retreat                                -> the pick fails
  give_up   next_object_open, next_object_retreat                            -> the next object (clear)
  home      next_object_home                                                 -> the next object (clear)

A failed grip check (after the close, the lift, the carry) in lift, place or replace -> recover, while attempts are
left (else the pick fails). A check that finds the object moved -> back_off; a confirm that finds it off its
place target -> replace. An aim out of the arms' reach (no plan for aim_approach or aim) -> set_back: the drill is set
down where it was taken, let go, and the pick then fails with the aim's failure; a pour out of reach (no plan for
pour_approach or pour) the same with the can. Any other failure (perception found
nothing, no plan) ends the pick.

A clear pick (clear_pick) runs the place task on one object after another. Once one is placed and the hands have
backed off it, the table is looked at for the scene alone (a move home planned in the scene seen before the object
stood in the drop zone swept it along), `home` goes back to the start in that scene, out of the camera's way, and the
next object is looked for. Where one fails (a carry out of reach sets it back down first), `give_up` lets go and backs
off, and the same follows. The supervisor ends the clear when perception finds no object left.
"""

import enum
from collections.abc import Iterator
from dataclasses import dataclass

from pydrake.math import RigidTransform

from systems.messages import CLOSED_WIDTH, OPEN_WIDTH, Mode, MoveKind, PhaseKind, PlaceGoal, Targets, TaskName

AIM_HOLD_S = 2.0  # s: the aim is held this long
POUR_HOLD_S = 2.0  # s: the pour is held this long
SETTLE_S = 0.5  # s: after the hands close or open, the grip settles before it is checked
LIFT_HEIGHT = 0.15  # m: aimed for
MIN_LIFT_FRACTION = 0.8  # of it: near the edge of the arms' reach a lower lift will do (0.12 m)
HOLD_S = 2.5  # s
# The place task carries the object this high (its bottom clears the 6 cm boxes of the place_over_box layouts);
# higher, the arms are near the edge of their reach and cannot move it sideways, m.
PLACE_LIFT_HEIGHT = 0.10
# Taken again after a set-down off its target, the object is lifted this high before it is set down again (clear
# of the table's friction), m; near the edge of reach this share of it will do.
REPLACE_LIFT_HEIGHT = 0.03
MIN_REPLACE_LIFT_FRACTION = 0.5
# Letting go of a set-down object, the hands open this much wider than the widest handle they closed on, m:
# enough to back off it, no wider (wider, the fingers turn it; docs/history/pick_parameters.md).
RELEASE_MARGIN = 0.012
# An aimed drill is let go this much wider: at +1.2 cm a finger still hooked the side handle as the hand backed off
# along its approach, or one the drill's body held shut sprang it round, and three set-down drills were dragged
# 2-3 cm or turned 7-22 deg (aim test_2 at -0.25, random extra_1036 and 1037); at +2.5 cm all three stood (0.2-3.1 deg).
AIM_RELEASE_MARGIN = 0.025

# What a phase needs set, by kind.
_MOVES, _HANDS = (PhaseKind.MOVE,), (PhaseKind.CLOSE, PhaseKind.OPEN)
_BRANCHES = (PhaseKind.CHECK_MOVED, PhaseKind.CONFIRM_PLACED)


@dataclass(frozen=True)
class Phase:
    """One step of a task: its name (the pick's mode while it runs), what it does, and how."""

    name: Mode
    kind: PhaseKind
    path: MoveKind | None = None  # moves
    targets: Targets | None = None  # free and straight moves: the grasp poses named so
    X_motion_W: RigidTransform | None = None  # held moves: the object's motion in W
    min_fraction: float = 1.0  # held moves: the shortest share of the motion's translation that will do
    goal: PlaceGoal | None = None  # held moves to the place target
    exact_goal: bool = False  # held moves: the goal solved onto the hands' targets (PlanRequest.exact_goal)
    check_held: bool = False  # moves: once played, both hands must still hold the object
    hand_width: float | None = None  # closing and opening, m
    beyond_grasp: bool = False  # opening: hand_width is beyond the widest measured grasp (letting go)
    wait_s: float = 0.0  # waits: how long; closing and opening: the settling after the hands' motion
    # Checks and confirms: where the look finds the object off (moved; off its target), the task run next.
    if_off: TaskName | None = None
    # Held moves: where no plan reaches the goal, the task run next (it ends the pick as failed); None: the pick fails.
    if_unreachable: TaskName | None = None

    def __post_init__(self):
        if (self.path is not None) != (self.kind in _MOVES):
            raise ValueError(f"phase {self.name}: a {self.kind} phase {'needs' if self.path is None else 'has'} a path")
        if (self.hand_width is not None) != (self.kind in _HANDS):
            raise ValueError(f"phase {self.name}: only closing and opening set a hand width, and they need one")
        if (self.if_off is not None) != (self.kind in _BRANCHES):
            raise ValueError(f"phase {self.name}: only checks and confirms name a task to switch to, and they must")
        if self.if_unreachable is not None and self.path != MoveKind.HELD:
            raise ValueError(f"phase {self.name}: only held moves name a task for a goal out of reach")
        if self.exact_goal and self.path != MoveKind.HELD:
            raise ValueError(f"phase {self.name}: only held moves solve their goal onto the hands' targets")


class Then(enum.StrEnum):
    """What comes after a task's last phase."""

    DONE = "done"  # the pick is done
    NEXT_ATTEMPT = "next_attempt"  # a new camera frame, then the pick's task from its start
    REACH_AGAIN = "reach_again"  # the pick's task again from its reach (where the look found the object)
    FAIL = "fail"  # the pick fails, with the failure that started the task
    NEXT_OBJECT = "next_object"  # the clear task: a new camera frame, then the pick's task on the next object


@dataclass(frozen=True)
class Task:
    """A named list of phases and what comes after it: when its last phase is over (`then`), and when a grip
    check fails in it (`if_check_fails`: that task, while attempts are left; None: the pick fails)."""

    name: TaskName
    phases: tuple[Phase, ...]
    then: Then
    if_check_fails: TaskName | None

    def index(self, mode: Mode) -> int:
        """The index of its phase of that name."""
        return [phase.name for phase in self.phases].index(mode)


@dataclass(frozen=True)
class PickTasks:
    """A pick's tasks by name: the one it sets out on after each camera frame (`main`) and those it may switch
    to."""

    main: TaskName
    tasks: dict[TaskName, Task]
    # A clear pick's: the task after an object is given up, and the move home between objects (None: a one-object
    # pick).
    after_given_up: TaskName | None = None
    home: TaskName | None = None

    def __post_init__(self):
        named = {self.main, self.after_given_up, self.home} | {task.if_check_fails for task in self.tasks.values()}
        named |= {phase.if_off for phase in self.phases()} | {phase.if_unreachable for phase in self.phases()}
        if missing := sorted(name for name in named - set(self.tasks) if name is not None):
            raise ValueError(f"the pick's tasks name tasks it lacks: {missing}")

    def __getitem__(self, name: TaskName) -> Task:
        return self.tasks[name]

    def phases(self) -> Iterator[Phase]:
        """Every task's phases."""
        return (phase for task in self.tasks.values() for phase in task.phases)


def _grasping(check: bool) -> tuple[Phase, ...]:
    """Reach the pre-grasps, [look whether the object moved,] approach, close both hands."""
    checking = (Phase(Mode.CHECK, PhaseKind.CHECK_MOVED, if_off=TaskName.BACK_OFF),) if check else ()
    return (
        Phase(Mode.REACH, PhaseKind.MOVE, MoveKind.FREE, Targets.PREGRASP),
        *checking,
        Phase(Mode.APPROACH, PhaseKind.MOVE, MoveKind.STRAIGHT, Targets.GRASP),
        Phase(Mode.CLOSE, PhaseKind.CLOSE, hand_width=CLOSED_WIDTH, wait_s=SETTLE_S),
    )


def _lift(height: float, min_fraction: float) -> Phase:
    """Lift the held object `height` (m), or at least min_fraction of it; then both hands must still hold it."""
    motion = RigidTransform([0, 0, height])
    return Phase(
        Mode.LIFT, PhaseKind.MOVE, MoveKind.HELD, X_motion_W=motion, min_fraction=min_fraction, check_held=True
    )


def _look(name: Mode, held_looks: bool) -> Phase:
    """A look at the held object (a pass without held looks)."""
    return Phase(name, PhaseKind.LOOK if held_looks else PhaseKind.WAIT)


def _letting_go(
    held_looks: bool, if_unreachable: TaskName | None = None, relax: bool = False, margin: float = RELEASE_MARGIN
) -> tuple[Phase, ...]:
    """Set the object down on the place target, [bring the arms' command to where they are,] let go, back off, and
    look whether it stands there. if_unreachable: the task run where no plan sets it down there (None: the pick fails
    holding it). relax: the two arms hold the object through their position errors, which press on it still after
    the set-down; an aimed drill, opened, kept a finger pressing its grip and the back-off dragged it over, and a
    relax first lets go of that (3 of the 5 such aims on random placements; docs/use.md). A can set down after a
    place turned further as the hands opened after a relax (test_0: 4.3 -> 5.1 deg), so only the aim relaxes.
    margin: the hands open this much wider than the widest handle they closed on, m (RELEASE_MARGIN; an aim's
    AIM_RELEASE_MARGIN)."""
    confirm = Phase(Mode.CONFIRM, PhaseKind.CONFIRM_PLACED, if_off=TaskName.REPLACE) if held_looks else None
    return (
        Phase(Mode.SET_DOWN, PhaseKind.MOVE, MoveKind.HELD, goal=PlaceGoal.SET_DOWN, if_unreachable=if_unreachable),
        *((Phase(Mode.RELAX, PhaseKind.MOVE, MoveKind.STRAIGHT, Targets.MEASURED),) if relax else ()),
        Phase(Mode.RELEASE, PhaseKind.OPEN, hand_width=margin, beyond_grasp=True, wait_s=SETTLE_S),
        Phase(Mode.RETREAT, PhaseKind.MOVE, MoveKind.STRAIGHT, Targets.RETREAT),
        confirm or Phase(Mode.CONFIRM, PhaseKind.WAIT),
    )


def lift_task(lift_height: float = LIFT_HEIGHT, check: bool = True) -> Task:
    """The paper's task: reach the pre-grasps, [look whether the object moved,] approach, close both hands, lift
    the object, hold it; then the pick is done."""
    phases = (*_grasping(check), _lift(lift_height, MIN_LIFT_FRACTION), Phase(Mode.HOLD, PhaseKind.WAIT, wait_s=HOLD_S))
    return Task(TaskName.LIFT, phases, Then.DONE, if_check_fails=TaskName.RECOVER)


def place_task(
    lift_height: float = PLACE_LIFT_HEIGHT,
    check: bool = True,
    held_looks: bool = True,
    if_unreachable: TaskName | None = None,
) -> Task:
    """Beyond the paper: lift the object, carry it to the place target, set it down upright, let go, back off,
    [look whether it stands there]; then the pick is done. held_looks: look at the held object before the lift
    and before the set-down, and at the object set down (else those phases pass); if_unreachable: the task run where
    no plan carries it to the target or sets it down there (None: the pick fails holding it)."""
    phases = (
        *_grasping(check),
        _look(Mode.LOOK, held_looks),
        _lift(lift_height, MIN_LIFT_FRACTION),
        # (then both hands must still hold it: an object dropped on the way is picked again from a new frame)
        Phase(
            Mode.CARRY,
            PhaseKind.MOVE,
            MoveKind.HELD,
            goal=PlaceGoal.CARRY,
            check_held=True,
            if_unreachable=if_unreachable,
        ),  # fmt: skip
        _look(Mode.LOOK_AGAIN, held_looks),  # the object turns a few degrees in the hands as they move it
        *_letting_go(held_looks, if_unreachable),
    )
    return Task(TaskName.PLACE, phases, Then.DONE, if_check_fails=TaskName.RECOVER)


def replace_task(held_looks: bool = True) -> Task:
    """After a set-down off the target: take the object where it stands, lift it a little, set it down on the
    target, let go, back off, and look again; then the pick is done."""
    phases = (
        *_grasping(check=False),
        _look(Mode.LOOK, held_looks),
        _lift(REPLACE_LIFT_HEIGHT, MIN_REPLACE_LIFT_FRACTION),
        *_letting_go(held_looks),
    )
    return Task(TaskName.REPLACE, phases, Then.DONE, if_check_fails=TaskName.RECOVER)


def aim_task(check: bool = True, held_looks: bool = True) -> Task:
    """Beyond the paper: lift a drill, aim its bit at the board's target (in front of it, [look at the drill in the
    hands,] onto it), hold AIM_HOLD_S, back off, carry it back over where it was taken, [look at it in the hands
    again: the turns turn it in them,] set it down there, let go, back off, [look whether it stands there]. An aim
    out of reach sets the drill back down (set_back_task)."""
    phases = (
        *_grasping(check),
        _look(Mode.LOOK, held_looks),
        _lift(PLACE_LIFT_HEIGHT, MIN_LIFT_FRACTION),
        # The aim's moves end on their goals: the path's tolerances left an aimed bit's tip ~2 mm short of its stop.
        _aim(Mode.AIM_APPROACH, PlaceGoal.AIM_APPROACH, exact_goal=True),
        _look(Mode.LOOK_OVER, held_looks),
        _aim(Mode.AIM, PlaceGoal.AIM, exact_goal=True),
        Phase(Mode.AIM_HOLD, PhaseKind.WAIT, wait_s=AIM_HOLD_S),
        Phase(Mode.AIM_BACK, PhaseKind.MOVE, MoveKind.HELD, goal=PlaceGoal.AIM_BACK),
        Phase(Mode.CARRY, PhaseKind.MOVE, MoveKind.HELD, goal=PlaceGoal.CARRY),
        _look(Mode.LOOK_AGAIN, held_looks),  # the turns turn the drill in the hands: its set-down goal from a look
        *_letting_go(held_looks, relax=True, margin=AIM_RELEASE_MARGIN),
    )
    return Task(TaskName.AIM, phases, Then.DONE, if_check_fails=TaskName.RECOVER)


def pour_task(check: bool = True, held_looks: bool = True) -> Task:
    """Beyond the paper: lift a can, carry it over the container (upright, its outflow turned to the robot's left),
    [look at the can in the hands,] tilt it until the outflow points the pour's tilt down, its spout's tip over the
    opening, hold POUR_HOLD_S, bring it upright, carry it back over where it was taken, [look at it in the hands
    again: the turns turn it in them,] set it down there, let go, back off, [look whether it stands there]. A pour
    out of reach sets the can back down (set_back_task)."""
    phases = (
        *_grasping(check),
        _look(Mode.LOOK, held_looks),
        _lift(PLACE_LIFT_HEIGHT, MIN_LIFT_FRACTION),
        _aim(Mode.POUR_APPROACH, PlaceGoal.POUR_APPROACH),
        _look(Mode.LOOK_OVER, held_looks),
        _aim(Mode.POUR, PlaceGoal.POUR),
        Phase(Mode.POUR_HOLD, PhaseKind.WAIT, wait_s=POUR_HOLD_S),
        Phase(Mode.POUR_BACK, PhaseKind.MOVE, MoveKind.HELD, goal=PlaceGoal.POUR_BACK),
        Phase(Mode.CARRY, PhaseKind.MOVE, MoveKind.HELD, goal=PlaceGoal.CARRY),
        _look(Mode.LOOK_AGAIN, held_looks),
        *_letting_go(held_looks),
    )
    return Task(TaskName.POUR, phases, Then.DONE, if_check_fails=TaskName.RECOVER)


def _aim(name: Mode, goal: PlaceGoal, exact_goal: bool = False) -> Phase:
    """A held move towards an aim or a pour (with exact_goal, its goal solved onto the hands' targets); out of
    reach, the object is set back down."""
    return Phase(
        name, PhaseKind.MOVE, MoveKind.HELD, goal=goal, exact_goal=exact_goal, if_unreachable=TaskName.SET_BACK
    )


def set_back_task() -> Task:
    """The held object's goal is out of reach: carry it back over where it was taken, set it down there, let go,
    back off; then the pick fails with the failure that started this."""
    *letting_go, _ = _letting_go(held_looks=False)  # (no confirm: the pick fails after it)
    phases = (Phase(Mode.CARRY, PhaseKind.MOVE, MoveKind.HELD, goal=PlaceGoal.CARRY), *letting_go)
    return Task(TaskName.SET_BACK, phases, Then.FAIL, if_check_fails=None)


def back_off_task() -> Task:
    """The object moved before the approach: back off (a reach from beside it would start in collision); then the
    pick's task again from its reach."""
    phases = (Phase(Mode.BACK_OFF, PhaseKind.MOVE, MoveKind.STRAIGHT, Targets.RETREAT),)
    return Task(TaskName.BACK_OFF, phases, Then.REACH_AGAIN, if_check_fails=None)


def recovery_task() -> Task:
    """After a failed attempt: open the hands, back off along the approach axes, go back to the start; then the next
    attempt."""
    phases = (
        Phase(Mode.RECOVER_OPEN, PhaseKind.OPEN, hand_width=OPEN_WIDTH, wait_s=SETTLE_S),
        Phase(Mode.RECOVER_RETREAT, PhaseKind.MOVE, MoveKind.STRAIGHT, Targets.RETREAT),
        Phase(Mode.RECOVER_HOME, PhaseKind.MOVE, MoveKind.FREE, Targets.HOME),
    )
    return Task(TaskName.RECOVER, phases, Then.NEXT_ATTEMPT, if_check_fails=None)


def give_up_task() -> Task:
    """A clear task's object given up: open the hands, back off along the approach axes; then the next object."""
    phases = (
        Phase(Mode.NEXT_OBJECT_OPEN, PhaseKind.OPEN, hand_width=OPEN_WIDTH, wait_s=SETTLE_S),
        Phase(Mode.NEXT_OBJECT_RETREAT, PhaseKind.MOVE, MoveKind.STRAIGHT, Targets.RETREAT),
    )
    return Task(TaskName.GIVE_UP, phases, Then.NEXT_OBJECT, if_check_fails=None)


def home_task() -> Task:
    """Between a clear task's objects: home (PickStatus.q_home: the clear's home, or where the robot started); then
    the next object."""
    phases = (Phase(Mode.NEXT_OBJECT_HOME, PhaseKind.MOVE, MoveKind.FREE, Targets.HOME),)
    return Task(TaskName.HOME, phases, Then.NEXT_OBJECT, if_check_fails=None)


def lift_pick(check: bool = True) -> PickTasks:
    """A pick that lifts the object (lift_task) and its back-off and recovery."""
    return _pick(lift_task(check=check))


def place_pick(check: bool = True, held_looks: bool = True) -> PickTasks:
    """A pick that places the object (place_task) and its re-place, back-off and recovery."""
    return _pick(place_task(check=check, held_looks=held_looks), replace_task(held_looks))


def aim_pick(check: bool = True, held_looks: bool = True) -> PickTasks:
    """A pick that aims a drill at a board (aim_task) and its set-back, re-place, back-off and recovery."""
    return _pick(aim_task(check=check, held_looks=held_looks), set_back_task(), replace_task(held_looks))


def pour_pick(check: bool = True, held_looks: bool = True) -> PickTasks:
    """A pick that pours from a can into a container (pour_task) and its set-back, re-place, back-off and recovery."""
    return _pick(pour_task(check=check, held_looks=held_looks), set_back_task(), replace_task(held_looks))


def clear_pick(check: bool = True, held_looks: bool = True) -> PickTasks:
    """A pick that clears the table: the place task on each object in turn (a carry out of reach sets the object back
    down), give_up after each failed one, home between two; and the re-place, back-off and recovery."""
    place = place_task(check=check, held_looks=held_looks, if_unreachable=TaskName.SET_BACK)
    tasks = _pick(place, set_back_task(), replace_task(held_looks), give_up_task(), home_task()).tasks
    return PickTasks(TaskName.PLACE, tasks, after_given_up=TaskName.GIVE_UP, home=TaskName.HOME)


def _pick(main: Task, *others: Task) -> PickTasks:
    tasks = (main, *others, back_off_task(), recovery_task())
    return PickTasks(main.name, {task.name: task for task in tasks})
