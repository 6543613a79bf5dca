"""What the pick's moves go towards (systems/pick_supervisor.py's): each move phase's PlanRequest, the use targets
read once the object is perceived (an aim's board, a pour's container, with the perceived tool frame) and each
held goal's motion from where the object is believed to be (systems/planning/place_goals.py, aim_goals.py,
pour_goals.py).

An aim reads the board perceived in the frame the object was perceived in and aims the tool frame perceived with the
grasps; a pour reads the container's opening perceived there and pours with the same tool frame. Without the board
(the container) the pick fails at stage board (container), without a tool frame at registration, before any move.
"""

import numpy as np
from pydrake.math import RigidTransform

from systems.messages import (
    BoardSeen,
    ContainerSeen,
    PerceptionResult,
    PickStatus,
    PlaceGoal,
    PlanRequest,
    Stage,
    Targets,
)
from systems.pick_looks import object_motion
from systems.pick_tasks import Phase
from systems.planning.aim_goals import aim_motion, aim_rolls, aim_target
from systems.planning.place_goals import place_motion
from systems.planning.pour_goals import inside_left_out, pour_motion, pour_rolls, pour_target

AIM_GOALS = (PlaceGoal.AIM_APPROACH, PlaceGoal.AIM, PlaceGoal.AIM_BACK)
POUR_GOALS = (PlaceGoal.POUR_APPROACH, PlaceGoal.POUR, PlaceGoal.POUR_BACK)


def read_use_targets(
    status: PickStatus,
    result: PerceptionResult,
    board: BoardSeen | None,
    container: ContainerSeen | None,
    pour_tilt_rad: float,
) -> tuple[Stage, str] | None:
    """Sets status.aim from the board seen (None: no aim) and status.pour from the container seen (None: no pour),
    with the tool frame perceived in `result`; returns why either cannot be, as (the stage that failed, its message),
    or None."""
    if board is not None:
        try:
            status.aim = aim_target(board, result.grasps, result.X_WO_seen)
        except ValueError as error:
            return (Stage.REGISTRATION if board.found else Stage.BOARD), str(error)
    if container is not None:
        try:
            status.pour = pour_target(container, result.grasps, result.X_WO_seen, pour_tilt_rad)
        except ValueError as error:
            return (Stage.REGISTRATION if container.found else Stage.CONTAINER), str(error)
    return None


def held_goal_motion(
    goal: PlaceGoal, status: PickStatus, place_target_W: RigidTransform
) -> tuple[RigidTransform, RigidTransform | None, tuple | None]:
    """A goal's held move from where the object is believed to be: (X_motion_W, carried_motion_W: the object's motion
    since it was seen, or None; the scene region left out of it: a pour's container's inside, or None)."""
    if goal in AIM_GOALS:
        return *aim_motion(goal, status.belief, status.aim), None
    if goal in POUR_GOALS:
        return *pour_motion(goal, status.belief, status.pour), inside_left_out(status.pour)
    return *place_motion(goal, status.belief, place_target_W), None


def move_request(
    phase: Phase,
    status: PickStatus,
    place_target_W: RigidTransform | None,
    measured_q: np.ndarray,
    full_back_off: bool = False,
    set_down_W: np.ndarray | None = None,
) -> PlanRequest:
    """The next PlanRequest, for a move phase, from where the last plan ended: a held goal's motion from where the
    object is believed to be (or the phase's own motion), its targets, and a joint goal where it names one (HOME:
    where the pick started; MEASURED: where the arms are measured, `measured_q`, rad). `place_target_W`: where a
    held goal sets the object down (None for a move without a held goal: between a clear's objects none is believed).
    full_back_off: the held move is planned only where the hands can then back off the whole way
    (PlanRequest.full_back_off). set_down_W: more of the scene to plan around (PlanRequest.set_down_W)."""
    X_motion_W, carried, left_out = phase.X_motion_W or RigidTransform(), None, None
    alternatives = ()
    if phase.goal is not None:
        X_motion_W, carried, left_out = held_goal_motion(phase.goal, status, place_target_W)
    if phase.goal == PlaceGoal.POUR:  # (the tilt rolled about the outflow where it is out of reach)
        alternatives = pour_rolls(X_motion_W, status.belief, status.pour)
    elif phase.goal in AIM_GOALS:  # (the aim's moves rolled about the bit's axis, the same)
        alternatives = aim_rolls(X_motion_W, status.belief, status.aim)
    q_goal = {Targets.HOME: status.q_home, Targets.MEASURED: np.array(measured_q, dtype=float)}.get(phase.targets)
    return PlanRequest(
        status.request.id + 1 if status.request.id >= 0 else 1,
        phase.name,
        status.plan_end_q,
        phase.path,
        phase.targets or Targets.PREGRASP,
        X_motion_W,
        phase.min_fraction,
        carried,
        q_goal=q_goal,
        object_motion_W=object_motion(status.belief, phase.targets),
        grasp_offsets_G=status.grasp_offsets_G if phase.targets == Targets.GRASP else None,
        inside_left_out=left_out,
        full_back_off=full_back_off,
        set_down_W=set_down_W,
        exact_goal=phase.exact_goal,
        alternatives=alternatives,
    )
