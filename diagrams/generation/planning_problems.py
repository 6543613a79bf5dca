"""Seeded planning problems for the planner benchmark (scripts/benchmark_planner.py), MotionBenchMaker-style:
problem k of a family and split is made from (family, split, k) alone, and each is distinct.

Held moves (both hands hold an object at its true grasps; the closure and the hands' world orientation kept, a
turn keeping only their tilt; the object moves with the hands and must stay clear of table and boxes):
  lift:     from LIFT_START_M above where the object rests, up 10-30 cm and 10-25 cm sideways;
  carry:    lifted 5-15 cm, carried 20-45 cm across the table (its height changing by up to 5 cm);
  turn:     lifted 5-15 cm, turned 0.4-1.2 rad either way about the vertical between the hands (and moved up to
            8 cm);
  set_down: lifted 10-25 cm, set down 10-35 cm away, LIFT_START_M above the table;
  aim:      a drill lifted USE_RAISED_M, turned about the vertical between the hands and moved until its bit points
            along the normal of a vertical board (facing the robot, 15-25 cm in from the table's far edge, 0-10 cm
            either side of its middle) at a target 25-30 cm up and up to 10 cm along it, the bit's tip 5 mm off it
            (systems/planning/aim_goals.py, the task's held move; the board is one of its boxes);
  pour:     a watering can lifted USE_RAISED_M, turned about the vertical between the hands until its outflow
            points POUR_HEADING_W and tilted about the same point until it points 14-24 deg down (an asked 10-20 deg
            and the task's POUR_TILT_MARGIN_RAD), its spout's tip POUR_CLEARANCE_M over the opening of a bowl or pot
            drawn beside it as the pour task draws it (systems/planning/pour_goals.py: the task's pour_approach and
            pour in one move); the container is one of its boxes (its footprint's square, its height), and the
            hands' orientation is free (the closure kept).
Reaches (no constraint): both hands from the arms under the table top or from the ready pose to their pre-grasps
of an object standing on the table, past boxes at the table's edge and a board above.

Every problem has 0-3 boxes: standing on the table or hanging (a shelf board), placed where the held object's
straight path goes (a turn: where the turning object sweeps) or, for a reach, between the table's edge and the
object, with random sizes. The object stands at a random place and yaw (evaluation's placement region).

Splits: `tune` draws the objects from the training instances train_0..7 of both categories and seeds from
TUNE_FIRST_SEED; `report` from the unseen generated instances extra_<REPORT_FIRST_INSTANCE..+39> and seeds from
REPORT_FIRST_SEED. Nobody chooses parameters on `report`.

A problem is kept or dropped by IK at its start and goal and their clearance alone: Drake's exact geometry (the
robot, the held object, table and boxes) at least MIN_CLEARANCE_M apart (a reach: REACH_MIN_CLEARANCE_M), and
the planners' sphere model clear by STOMP's required clearance. No planner runs here.
"""

import dataclasses
from dataclasses import dataclass

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from diagrams.aim_board import AIM_TARGET_RANGE, board_box, board_placement
from diagrams.evaluation import PAPER_CATEGORIES, PLACEMENT_HALF_SIZE_M, PLACEMENT_MAX_YAW
from diagrams.generation.objects.library import ObjectModel, resolve_object
from diagrams.planning_scene import MakeRobotScene, object_collision_surface_W, object_surface_W
from diagrams.pour_container import pour_container, true_opening
from diagrams.scenario import (
    TABLE_HALF_SIZE,
    AimConfig,
    PourConfig,
    Scenario,
    initial_positions,
    load_scenario,
    replace_object,
)
from diagrams.station import TABLE_HEIGHT, object_pose_on_table
from systems.planning.aim_goals import aim_pose
from systems.planning.closure import ClosureConstraint, OrientationConstraint, deviations, orientation_deviations
from systems.planning.ik import IkResult
from systems.planning.obstacles import Obstacles
from systems.planning.pick_motions import PickMotions, PlannerConfig
from systems.planning.pour_goals import POUR_HEADING_W, POUR_TILT_MARGIN_RAD, pour_poses
from systems.planning.stomp import Stomp
from systems.planning.straight_motions import PlanningError
from systems.planning.world import LIMIT_TOLERANCE_RAD, SIDES, PlanningWorld

# The planning core the problems are drawn with: SNOPT's IK, as when the families were first drawn (the batched IK
# finds other, equally valid starts and goals: problem k would change).
DRAWN_WITH = PlannerConfig(batched_ik=False)
HELD_FAMILIES = ("lift", "carry", "turn", "set_down", "aim", "pour")
# (a family's code in the seeds: its index here; a new family goes last)
FAMILIES = ("lift", "carry", "turn", "set_down", "reach", "aim", "pour")
SPLITS = ("tune", "report")
KEPT = ("orientation", "tilt", "closure")  # what a held problem keeps of its start: held_problem's `kept`
TUNE_FIRST_SEED = 0
REPORT_FIRST_SEED = 100_000
TRAINING_INSTANCES = [f"train_{i}" for i in range(8)]
REPORT_FIRST_INSTANCE = 3000  # unseen generated instances extra_3000..3039 (no other script uses them)
REPORT_INSTANCES = 40
# The object stands in evaluation's random-placement region (PLACEMENT_HALF_SIZE_M, PLACEMENT_MAX_YAW) about the
# default scenario's object.xy (table top frame, m).
PLACEMENT_CENTRE = (-0.12, 0.0)
USE_RAISED_M = 0.10  # an aim or a pour starts with the object this far above where it rests (the tasks' lift)
POUR_TILT_DEG = (10.0, 20.0)  # a pour's asked tilt below the horizontal (the task adds POUR_TILT_MARGIN_RAD)
LIFT_START_M = 0.03  # a lift starts, and a set-down ends, with the object this far above the table top
MIN_CLEARANCE_M = 0.02  # start and goal: every pair of robot, held object, table and boxes this far apart at least
REACH_MIN_CLEARANCE_M = 0.01  # ... in a reach (the open hands come near the object at their pre-grasps)
OBSTACLE_COUNT_P = (0.1, 0.3, 0.35, 0.25)  # probabilities of 0, 1, 2 and 3 boxes
LIFT_LEADING_SHARE = 0.2  # a lift's boxes stand where this share of its points, those leading its sideways move, pass
HANGING_P = 0.35  # the share of boxes that are hanging boards
BOX_GAP_M = 0.03  # a box stands at least this far from the held object at start and goal
BOX_DRAWS = 20
ARM_LENGTH_M = 0.35  # from the grasp frame back along the approach axis: the hand, the wrist and the forearm
ARM_GAP_M = 0.09  # a box stands at least this far from those points at start and goal (the forearm's radius and more)
# Arms under the table top, the torso straight (a reach's start where the straight line collides).
BELOW_TABLE = np.array([0, 0.15, 0, -0.1, 0, 0, 0, 0, -0.15, 0, -0.1, 0, 0, 0.0, 0.0])
DENSE_STEP_RAD = 0.01  # the dense checks: no joint turns more than this between two checked states
MAX_GOAL_JOINT_CHANGE = 2.0  # rad: a held move's goal no further from its start in any joint (its branch)
CHECK_POINTS = 1000  # the held object's surface points the checks move with the hands
# The planners' carried object: spheres spread over this many points of its collision pieces (the judge's geometry).
CARRIED_SURFACE_POINTS = 3000
# Integer codes of the families and splits in the seed sequence (the random stream of each problem).
_FAMILY_CODE = {name: i for i, name in enumerate(FAMILIES)}
_SPLIT_CODE = {name: i for i, name in enumerate(SPLITS)}


@dataclass
class PlanningProblem:
    """One problem: plan the planned joints (15: both arms and the torso yaw) from q_start to q_goal.

    Attributes:
        held: both hands hold the object (closure constraint); else a reach.
        orientation: the hands' orientation constraint of a held move (None: a reach, or a held move that keeps
            only the closure: a pour).
        X_WO: the object's pose at q_start (a reach: where it stands).
        X_WO_goal: where q_goal holds it (a held move), else None.
        boxes: the obstacles besides the table, each (X_WB of its centre, size in m).
        model: the object's model (files and true grasps).
        check_world: the robot, table and boxes with the object in Drake's exact geometry (held: welded to the
            left hand as at q_start; a reach: standing at X_WO), for the dense checks.
        obstacles: the planners' scene for the sphere model (table, boxes, and the object: carried in a held move,
            as spheres covering its collision pieces' surface; standing in a reach, its visual mesh's surface).
        object_points_W: the object's surface (its visual mesh) at X_WO (N x 3, m).
    """

    family: str
    split: str
    index: int  # k: the k-th problem of the split (kept or dropped)
    scenario: Scenario
    held: bool
    q_start: np.ndarray
    q_goal: np.ndarray
    orientation: OrientationConstraint | None
    X_WO: RigidTransform
    X_WO_goal: RigidTransform | None
    boxes: list
    model: ObjectModel
    check_world: PlanningWorld
    obstacles: Obstacles
    object_points_W: np.ndarray


@dataclass
class Dropped:
    """A problem the generator could not make: no IK at its start or goal, or one of them not clear."""

    family: str
    split: str
    index: int
    reason: str


def start_hands(end_effectors, q_start: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    """What a held move keeps from its start: the right grasp frame's pose in the left one's (X_E1E2, 4 x 4) and
    both hands' world orientations (R_WE, two 3 x 3)."""
    return end_effectors.relative(q_start[None])[0], [X[0, :3, :3] for X in end_effectors.poses(q_start[None])]


def hand_constraints(stomp: Stomp, problem: "PlanningProblem"):
    """The hand constraints a held problem keeps from its start (HandConstraints): the closure, and the hands'
    world orientation or tilt where the problem keeps one."""
    X_E1E2, R_WE = start_hands(stomp.end_effectors, problem.q_start)
    orientation = problem.orientation
    if orientation is None:
        return stomp.constraints(X_E1E2)
    return stomp.constraints(X_E1E2, R_WE, orientation.upright_only)


def problem_seed(family: str, split: str, index: int) -> np.random.SeedSequence:
    """The random stream of problem `index` of a family and split (nothing else enters it)."""
    first = TUNE_FIRST_SEED if split == "tune" else REPORT_FIRST_SEED
    return np.random.SeedSequence([_FAMILY_CODE[family], _SPLIT_CODE[split], first + index])


def make_problem(motions: PickMotions, family: str, split: str, index: int) -> PlanningProblem | Dropped:
    """Problem `index` of `family` in `split`, or why it was dropped.

    Args:
        motions: the planning core of the default scenario (robot and table; no object), built with DRAWN_WITH:
            its IK solves the start and goal.

    Raises:
        ValueError: an unknown family or split, or motions whose IK is not the one the problems are drawn with.
    """
    if family not in FAMILIES or split not in SPLITS:
        raise ValueError(f"unknown family {family!r} or split {split!r}: families {FAMILIES}, splits {SPLITS}")
    if motions.ik.batched != DRAWN_WITH.batched_ik:
        raise ValueError("the problems are drawn with SNOPT's IK: build the motions with DRAWN_WITH")
    rng = np.random.default_rng(problem_seed(family, split, index))
    scenario = _placement(rng, split)
    model = resolve_object(scenario.object)
    X_WO_rest = object_pose_on_table(scenario, model)
    points_rest, _ = object_surface_W(model, X_WO_rest, CHECK_POINTS)
    if family == "reach":
        return _reach(motions, rng, scenario, model, X_WO_rest, points_rest, index, split)
    if family == "aim":
        return _aim(motions, rng, replace_object(scenario, category="drill"), index, split)
    if family == "pour":
        return _pour(motions, rng, replace_object(scenario, category="watering_can"), index, split)
    table = np.array(scenario.table_xyz) + [0, 0, TABLE_HEIGHT]  # the table top frame's origin in W
    raised, motion = _held_motion(rng, family, X_WO_rest, model, table[:2])
    X_WO = RigidTransform([0, 0, raised]) @ X_WO_rest
    grasps = [X_WO @ model.info.control_poses()[f"{side}_grasp"] for side in SIDES]
    points = points_rest + [0, 0, raised]
    passing = points
    if family == "lift":  # its boxes where the side leading the sideways move passes (elsewhere they block no lift)
        ahead = (points - points.mean(axis=0)) @ motion(1.0).translation()
        passing = points[ahead >= np.quantile(ahead, 1 - LIFT_LEADING_SHARE)]
    boxes = _held_boxes(rng, table[2], points, _arm_points(grasps), motion, passing)
    problem = held_problem(motions, scenario, raised, motion(1.0), boxes, "tilt" if family == "turn" else "orientation")
    if isinstance(problem, str):
        return Dropped(family, split, index, problem)
    return dataclasses.replace(problem, family=family, split=split, index=index)


def held_problem(
    motions: PickMotions,
    scenario: Scenario,
    raised: float,
    motion: RigidTransform,
    boxes: list,
    kept: str = "orientation",
    continued: bool = False,
) -> PlanningProblem | str:
    """The held move of the scenario's object from `raised` (m) above where it rests by `motion` (X_WO -> motion
    X_WO), among `boxes`, the hands keeping their world orientation (kept "orientation"), their tilt ("tilt") or
    neither ("closure": only their relative pose); or why there is none (no IK at start or goal, or either of them
    less than MIN_CLEARANCE_M clear). continued: where the goal's IK from the start fails, it is continued along the
    motion from the start in small steps, as the pick's held moves find theirs (HeldMotions.held_path): after a
    turn of more than a few tenths of a radian, IK from the start lands on another branch. Its family is
    "custom"."""
    if kept not in KEPT:
        raise ValueError(f"a held move keeps one of {KEPT}, not {kept!r}")
    model = resolve_object(scenario.object)
    X_WO = RigidTransform([0, 0, raised]) @ object_pose_on_table(scenario, model)
    X_OG = {side: model.info.control_poses()[f"{side}_grasp"] for side in SIDES}
    start = motions.ik.solve({side: X_WO @ X_OG[side] for side in SIDES}, initial_positions(scenario), restarts=4)
    if not start.success:
        return f"no IK at the start: {start.message}"
    world = motions.world
    X_WG = world.grasp_frame_poses(start.q)
    X_E1E2 = X_WG["left"].InvertAndCompose(X_WG["right"])
    goal = _held_goal(motions, {side: motion @ X for side, X in X_WG.items()}, X_E1E2, start.q)
    if continued and not goal.success:
        goal = _held_goal_continued(motions, motion, start.q)
    if not goal.success:
        return f"no IK at the goal: {goal.message}"
    orientation = None if kept == "closure" else OrientationConstraint(upright_only=kept == "tilt")
    q_start, q_goal = start.q, _on_constraints(motions, start.q, goal.q, orientation)
    if q_goal is None:
        return "no IK at the goal: off the closure or orientation constraint"
    if reason := _outside_the_limits(world, q_start, q_goal):
        return reason
    X_GO = world.grasp_frame_poses(q_start)["left"].InvertAndCompose(X_WO)
    check_world = PlanningWorld(MakeRobotScene(scenario, held_object=model, X_GO=X_GO, boxes=boxes))
    if reason := _too_near(check_world, q_start, q_goal, MIN_CLEARANCE_M):
        return reason
    points, _ = object_surface_W(model, X_WO, CHECK_POINTS)
    carried = motions.carried(q_start, object_collision_surface_W(model, X_WO, CARRIED_SURFACE_POINTS))
    obstacles = check_world.table_obstacles().carrying(carried)
    if reason := _too_near_for_the_planners(motions, obstacles, q_start, q_goal, held=True):
        return reason
    X_WO_goal = world.grasp_frame_poses(q_goal)["left"] @ X_GO  # the motion's, within IK's and projection's error
    return PlanningProblem(
        "custom", "", 0, scenario, True, q_start, q_goal, orientation, X_WO, X_WO_goal, boxes, model, check_world,
        obstacles, points,
    )  # fmt: skip


def _placement(rng: np.random.Generator, split: str) -> Scenario:
    """The default scenario with an object of either category at a random place and yaw."""
    category = PAPER_CATEGORIES[rng.integers(len(PAPER_CATEGORIES))]
    if split == "tune":
        instance = TRAINING_INSTANCES[rng.integers(len(TRAINING_INSTANCES))]
    else:
        instance = f"extra_{REPORT_FIRST_INSTANCE + rng.integers(REPORT_INSTANCES)}"
    xy = np.array(PLACEMENT_CENTRE) + rng.uniform(-1, 1, 2) * PLACEMENT_HALF_SIZE_M
    yaw = rng.uniform(-PLACEMENT_MAX_YAW, PLACEMENT_MAX_YAW)
    return replace_object(load_scenario(), category=category, instance=instance, xy=list(xy), yaw=float(yaw))


def _aim(motions: PickMotions, rng, scenario: Scenario, index: int, split: str) -> PlanningProblem | Dropped:
    """An aim problem (module docstring): a drill at the scenario's place, lifted, aimed at a board's target."""
    model = resolve_object(scenario.object)
    X_WO = RigidTransform([0, 0, USE_RAISED_M]) @ object_pose_on_table(scenario, model)
    board_xyz = [TABLE_HALF_SIZE[0] - rng.uniform(0.15, 0.25), rng.uniform(-0.1, 0.1), 0.0]
    target_yz = [rng.uniform(*AIM_TARGET_RANGE[0]), rng.uniform(*AIM_TARGET_RANGE[1])]
    scenario = dataclasses.replace(scenario, aim=AimConfig(board_xyz, target_yz))
    board = board_placement(scenario)
    goal = aim_pose(X_WO, model.info.tool_frame(), _pivot_O(model), board.target_W, board.normal_W)
    boxes = [board_box(scenario), *_use_boxes(rng, scenario, model, X_WO, goal)]
    problem = held_problem(motions, scenario, USE_RAISED_M, goal @ X_WO.inverse(), boxes, "tilt")
    if isinstance(problem, str):
        return Dropped("aim", split, index, problem)
    return dataclasses.replace(problem, family="aim", split=split, index=index)


def _pour(motions: PickMotions, rng, scenario: Scenario, index: int, split: str) -> PlanningProblem | Dropped:
    """A pour problem (module docstring): a can at the scenario's place, lifted, turned, carried over a container
    drawn beside it and tilted until it pours."""
    model = resolve_object(scenario.object)
    X_WO = RigidTransform([0, 0, USE_RAISED_M]) @ object_pose_on_table(scenario, model)
    tilt = np.radians(rng.uniform(*POUR_TILT_DEG)) + POUR_TILT_MARGIN_RAD
    scenario = dataclasses.replace(
        scenario, task="pour", pour=PourConfig(), random_seed=int(rng.integers(2**31))
    )  # the container drawn from the seed beside the can, as the task draws it
    opening = true_opening(scenario)
    poses = pour_poses(X_WO, model.info.tool_frame(), _pivot_O(model), opening, tilt, heading_W=POUR_HEADING_W)
    container = pour_container(scenario)
    diameter, _, height = container.size
    centre = np.array(scenario.table_xyz) + [*container.xy, TABLE_HEIGHT + height / 2]
    container_box = (RigidTransform(centre), np.array([diameter, diameter, height]))
    boxes = [container_box, *_use_boxes(rng, scenario, model, X_WO, poses.poured_W)]
    motion = poses.poured_W @ X_WO.inverse()
    problem = held_problem(motions, scenario, USE_RAISED_M, motion, boxes, "closure", continued=True)
    if isinstance(problem, str):
        return Dropped("pour", split, index, problem)
    return dataclasses.replace(problem, family="pour", split=split, index=index)


def _pivot_O(model: ObjectModel) -> np.ndarray:
    """The midpoint of the object's two grasps, in O (m): the use tasks' turns' centre."""
    grasps = model.info.control_poses()
    return 0.5 * (grasps["left_grasp"].translation() + grasps["right_grasp"].translation())


def _use_boxes(rng, scenario: Scenario, model: ObjectModel, X_WO: RigidTransform, goal: RigidTransform) -> list:
    """0-3 boxes (_held_boxes) where a point of the object passes part way from X_WO to `goal`, the object turned
    about its grasps' midpoint by the share s of the turn and that point moved the share s of the way."""
    motion = goal @ X_WO.inverse()
    pivot = X_WO.multiply(_pivot_O(model))
    turn = motion.rotation().ToAngleAxis()
    shift = motion.translation() - pivot + motion.rotation().multiply(pivot)

    def partial(s: float) -> RigidTransform:
        turned = RigidTransform(RotationMatrix(AngleAxis(s * turn.angle(), turn.axis())))
        return RigidTransform(s * shift + pivot) @ turned @ RigidTransform(-pivot)

    points, _ = object_surface_W(model, X_WO, CHECK_POINTS)
    grasps = model.info.control_poses()
    arms = _arm_points([X_WO @ grasps[f"{side}_grasp"] for side in SIDES])
    table_top = scenario.table_xyz[2] + TABLE_HEIGHT
    return _held_boxes(rng, table_top, points, arms, partial, points)


def _held_motion(rng, family: str, X_WO_rest: RigidTransform, model: ObjectModel, table_xy):
    """How high the held move starts above where the object rests (m), and its motion: a function of the share s
    in [0, 1] done, giving the transform X_WO -> motion(s) X_WO (a turn: about the vertical between the grasps).
    table_xy: the table top frame's origin in W (x, y, m)."""
    direction = rng.uniform(0, 2 * np.pi)
    across = np.array([np.cos(direction), np.sin(direction), 0.0])
    if family == "turn":
        raised = rng.uniform(0.05, 0.15)
        grasps = model.info.control_poses()
        middle = 0.5 * (grasps["left_grasp"].translation() + grasps["right_grasp"].translation())
        pivot = X_WO_rest.multiply(middle) + [0, 0, raised]
        angle = rng.choice([-1, 1]) * rng.uniform(0.4, 1.2)
        shift = rng.uniform(0, 0.08) * across

        def turn(s: float) -> RigidTransform:
            return RigidTransform(s * shift + pivot) @ RigidTransform(RollPitchYaw(0, 0, s * angle), -pivot)

        return raised, turn
    if family == "lift":
        raised, move = LIFT_START_M, rng.uniform(0.10, 0.25) * across + [0, 0, rng.uniform(0.10, 0.30)]
    elif family == "carry":
        raised = rng.uniform(0.05, 0.15)
        move = np.append(_goal_xy(rng, table_xy, X_WO_rest, 0.20, 0.45), rng.uniform(-0.05, 0.05))
    else:  # set_down
        raised = rng.uniform(0.10, 0.25)
        move = np.append(_goal_xy(rng, table_xy, X_WO_rest, 0.10, 0.35), LIFT_START_M - raised)
    return raised, lambda s: RigidTransform(s * move)


def _arm_points(X_WG: list[RigidTransform]) -> np.ndarray:
    """Points (N x 3, W) along the hands, wrists and forearms whose grasp frames are at X_WG: from each grasp frame
    back ARM_LENGTH_M along its approach axis z_G."""
    backs = np.outer([0, 0, 1], np.linspace(0, -ARM_LENGTH_M, 8))
    return np.concatenate([X.multiply(backs).T for X in X_WG])


def _goal_xy(rng, table_xy, X_WO: RigidTransform, shortest: float, longest: float) -> np.ndarray:
    """A move (x, y in W, m) of the object from X_WO to a place of the placement region (widened by 5 cm; the table
    top's origin at table_xy in W) between `shortest` and `longest` away (the last of 100 draws if none is)."""
    table = np.asarray(table_xy)
    half = np.array(PLACEMENT_HALF_SIZE_M) + 0.05
    for _ in range(100):
        move = table + PLACEMENT_CENTRE + rng.uniform(-1, 1, 2) * half - X_WO.translation()[:2]
        if shortest <= np.linalg.norm(move) <= longest:
            break
    return move


def _held_boxes(
    rng, table_top: float, points_W: np.ndarray, arm_points_W: np.ndarray, motion, passing_W: np.ndarray
) -> list:
    """0-3 boxes where the held object goes (points_W: its surface at the start, N x 3; arm_points_W: its hands' and
    forearms' (_arm_points); motion(s) as _held_motion's): each standing on the table or hanging, where a point of
    passing_W (some of points_W) passes part way along the straight motion, about as high as the object's bottom
    (standing) or top (hanging) is there, and at least BOX_GAP_M from the object and ARM_GAP_M from the arms'
    points at start and goal (redrawn up to BOX_DRAWS times, else left out). table_top: its height in W (m)."""
    goal = motion(1.0)
    ends = np.concatenate([points_W, goal.multiply(points_W.T).T])
    arms = np.concatenate([arm_points_W, goal.multiply(arm_points_W.T).T])
    boxes = []
    for _ in range(rng.choice(len(OBSTACLE_COUNT_P), p=OBSTACLE_COUNT_P)):
        for _ in range(BOX_DRAWS):
            along = motion(rng.uniform(0.3, 0.7))  # the object part way along its motion
            moved = along.multiply(points_W.T).T
            centre = along.multiply(passing_W[rng.integers(len(passing_W))]) + [*rng.normal(0, 0.03, 2), 0]
            bottom, top = moved[:, 2].min(), moved[:, 2].max()
            if rng.uniform() < HANGING_P:  # a shelf board whose underside is about where the object's top passes
                size = np.array([*rng.uniform(0.10, 0.25, 2), 0.02])
                centre[2] = top + rng.uniform(-0.10, 0.05) + size[2] / 2
            else:  # standing on the table, up to about where the object's bottom passes
                height = max(0.03, bottom - table_top + rng.uniform(-0.03, 0.10))
                size = np.array([*rng.uniform(0.03, 0.18, 2), height])
                centre[2] = table_top + height / 2
            X_WB = RigidTransform(RollPitchYaw(0, 0, rng.uniform(-np.pi / 2, np.pi / 2)), centre)
            if _clear_of(X_WB, size, ends, BOX_GAP_M) and _clear_of(X_WB, size, arms, ARM_GAP_M):
                boxes.append((X_WB, size))
                break
    return boxes


def _outside_the_limits(world: PlanningWorld, q_start: np.ndarray, q_goal: np.ndarray) -> str:
    """Why the start or goal lies beyond a joint limit by more than LIMIT_TOLERANCE_RAD (IK's answers can end a
    little beyond one, where no planner may start or arrive), or ''."""
    for name, q in (("start", q_start), ("goal", q_goal)):
        if (beyond := world.beyond_limits(q)) > LIMIT_TOLERANCE_RAD:
            return f"the {name} is outside the joint limits (by {beyond:.1e} rad)"
    return ""


def _too_near(world: PlanningWorld, q_start: np.ndarray, q_goal: np.ndarray, clearance: float) -> str:
    """Why the start or goal is nearer than `clearance` (m) to a collision (the nearest pair's bodies), or ''."""
    for name, q in (("start", q_start), ("goal", q_goal)):
        world.plant.SetPositions(world.plant_context, world.full_positions(q))
        query = world.plant.get_geometry_query_input_port().Eval(world.plant_context)
        pairs = query.ComputeSignedDistancePairwiseClosestPoints(clearance)
        if pairs:
            nearest = min(pairs, key=lambda pair: pair.distance)
            bodies = [
                world.plant.GetBodyFromFrameId(world.inspector.GetFrameId(g)) for g in (nearest.id_A, nearest.id_B)
            ]
            names = " and ".join(sorted(body.name() for body in bodies))
            return f"the {name} has {names} {1000 * nearest.distance:.0f} mm apart"
    return ""


def _clear_of(X_WB: RigidTransform, size, points_W: np.ndarray, gap: float) -> bool:
    """Whether a box stands at least `gap` (m) from every point."""
    return bool(Obstacles().add_box(X_WB.GetAsMatrix4(), size).distance(points_W).min() >= gap)


def _too_near_for_the_planners(motions: PickMotions, obstacles: Obstacles, q_start, q_goal, held: bool) -> str:
    """Why the start or goal is not clear in the planners' collision model (STOMP's sphere model, the carried
    object's points, by its required clearance), or ''. The spheres are larger than the robot's geometry: where
    they overlap the scene at an end, no planner that uses them can start or arrive."""
    stomp = motions.stomp
    clearance = stomp.clearance(np.stack([q_start, q_goal]), obstacles, held)
    for name, value in zip(("start", "goal"), clearance, strict=True):
        if value <= stomp.config.costs.required_clearance:
            return f"the {name} is {1000 * value:.0f} mm from a collision in the planners' sphere model"
    return ""


def _held_goal(motions: PickMotions, targets: dict, X_E1E2: RigidTransform, q_start: np.ndarray):
    """Both hands at `targets` holding the object (the right one at X_E1E2 from the left), near q_start: solved from
    q_start, else from each arm's IK at its target; on the start's branch (no joint more than MAX_GOAL_JOINT_CHANGE
    away: an arm that flips its elbow or wrist cannot do it while both hands hold the object)."""
    ik = motions.ik
    goal = ik.solve_held(targets["left"], X_E1E2, q_start, 0.002, 0.01)
    if not goal.success:
        alone = ik.solve(targets, q_start, restarts=4)
        if alone.success:
            goal = ik.solve_held(targets["left"], X_E1E2, q_start, 0.002, 0.01, start=alone.q)
    change = np.abs(goal.q - q_start).max()
    if goal.success and change > MAX_GOAL_JOINT_CHANGE:
        return dataclasses.replace(
            goal, success=False, message=f"only on another branch (a joint {change:.1f} rad away)"
        )
    return goal


def _held_goal_continued(motions: PickMotions, motion: RigidTransform, q_start: np.ndarray) -> IkResult:
    """Both hands moved by `motion` holding the object, solved along it from q_start (HeldMotions.held_path)."""
    try:
        path = motions.held_path(q_start, motion, 1.0)
    except PlanningError as error:
        return IkResult(False, q_start, str(error))
    return IkResult(True, path.configurations[-1], "")


def _on_constraints(
    motions: PickMotions, q_start, q_goal, orientation: OrientationConstraint | None
) -> np.ndarray | None:
    """q_goal projected onto the closure and orientation constraints of q_start (None: the closure alone), or None
    if it does not get within a tenth of the closure's limits."""
    X_E1E2, R_WE = start_hands(motions.world.end_effectors, q_start)
    R_kept, upright_only = (None, False) if orientation is None else (R_WE, orientation.upright_only)
    q_goal = motions.stomp.project(q_goal[None], X_E1E2, R_kept, steps=20, upright_only=upright_only)[0]
    t_dev, o_dev = deviations(motions.world.end_effectors, q_goal[None], X_E1E2)
    limits = ClosureConstraint()
    return q_goal if t_dev[0] <= 0.1 * limits.t_max and o_dev[0] <= 0.1 * limits.o_max else None


def _reach(motions, rng, scenario, model, X_WO, points_W, index, split) -> PlanningProblem | Dropped:
    """Both hands from the arms under the table top (or the ready pose) to their pre-grasps of the object."""
    dropped = Dropped("reach", split, index, "")
    q_start = BELOW_TABLE if rng.uniform() < 0.5 else initial_positions(scenario)
    poses = model.info.control_poses()
    targets = {side: X_WO @ poses[f"{side}_pregrasp"] for side in SIDES}
    boxes = _reach_boxes(rng, scenario, X_WO, _arm_points(list(targets.values())))
    goal = motions.ik.solve(targets, initial_positions(scenario), restarts=4)
    if not goal.success:
        return dataclasses.replace(dropped, reason=f"no IK at the goal: {goal.message}")
    if reason := _outside_the_limits(motions.world, q_start, goal.q):
        return dataclasses.replace(dropped, reason=reason)
    check_world = PlanningWorld(MakeRobotScene(scenario, obstacle=model, X_WO=X_WO, boxes=boxes))
    if reason := _too_near(check_world, q_start, goal.q, REACH_MIN_CLEARANCE_M):
        return dataclasses.replace(dropped, reason=reason)
    obstacles = check_world.planning_obstacles()
    if reason := _too_near_for_the_planners(motions, obstacles, q_start, goal.q, held=False):
        return dataclasses.replace(dropped, reason=reason)
    return PlanningProblem(
        "reach", split, index, scenario, False, q_start, goal.q, None, X_WO, None, boxes, model, check_world,
        obstacles, points_W,
    )  # fmt: skip


def _reach_boxes(rng, scenario: Scenario, X_WO: RigidTransform, arm_points_W: np.ndarray) -> list:
    """0-3 boxes: standing between the table's edge and the object, or a board hanging above the object; each at
    least ARM_GAP_M from the arms' points at the pre-grasps (redrawn up to BOX_DRAWS times, else left out)."""
    table = np.array(scenario.table_xyz) + [0, 0, TABLE_HEIGHT]
    edge_x = table[0] - TABLE_HALF_SIZE[0]
    boxes = []
    for _ in range(rng.choice(len(OBSTACLE_COUNT_P), p=OBSTACLE_COUNT_P)):
        for _ in range(BOX_DRAWS):
            if rng.uniform() < HANGING_P:
                size = np.array([*rng.uniform(0.15, 0.35, 2), 0.02])
                centre = X_WO.translation() + [*rng.normal(0, 0.08, 2), 0]
                centre[2] = table[2] + rng.uniform(0.30, 0.50)
            else:
                size = np.array([rng.uniform(0.03, 0.12), rng.uniform(0.05, 0.25), rng.uniform(0.05, 0.25)])
                x = rng.uniform(edge_x + size[0] / 2, max(edge_x + size[0] / 2, X_WO.translation()[0] - 0.15))
                y = X_WO.translation()[1] + rng.uniform(-0.25, 0.25)
                centre = np.array([x, y, table[2] + size[2] / 2])
            X_WB = RigidTransform(RollPitchYaw(0, 0, rng.uniform(-0.5, 0.5)), centre)
            if _clear_of(X_WB, size, arm_points_W, ARM_GAP_M):
                boxes.append((X_WB, size))
                break
    return boxes


def projected_straight_line(problem: PlanningProblem, stomp: Stomp) -> np.ndarray:
    """STOMP's first trajectory before any detour (keyframes x n): the straight joint-space line at its keyframes,
    the interior projected onto the hand constraints (a held move) by its projection steps."""
    s = np.linspace(0, 1, stomp.config.keyframes)[:, None]
    theta = (1 - s) * problem.q_start + s * problem.q_goal
    if problem.held:
        theta[1:-1] = hand_constraints(stomp, problem).project(theta[1:-1], stomp.config.sampling.projection_steps)
    return theta


def dense_states(path: np.ndarray, step: float = DENSE_STEP_RAD) -> np.ndarray:
    """The path's configurations (K x n) and, between each two, straight-line states no joint `step` (rad) apart
    (S x n)."""
    states = [path[:1]]
    for a, b in zip(path[:-1], path[1:], strict=True):
        count = max(1, int(np.ceil(np.abs(b - a).max() / step)))
        s = np.linspace(0, 1, count + 1)[1:, None]
        states.append((1 - s) * a + s * b)
    return np.concatenate(states)


def check_path(problem: PlanningProblem, path: np.ndarray) -> dict:
    """Judges a planner's path (K x n configurations, joined by straight lines) densely: it goes from q_start to
    q_goal within the joint limits, every state clear (Drake's exact geometry: robot, held object, table, boxes),
    and in a held move the closure (ClosureConstraint's t_max and o_max) and the hands' orientation (o_max)
    kept at every state. Returns the verdict ("valid") and the figures."""
    world = problem.check_world
    path = np.asarray(path, float)
    states = dense_states(path)
    ends = np.allclose(path[0], problem.q_start, atol=1e-6) and np.allclose(path[-1], problem.q_goal, atol=1e-6)
    within = world.beyond_limits(states) <= LIMIT_TOLERANCE_RAD
    clearance = min(world.clearance(q) for q in states)
    row = {"min_clearance_m": float(clearance), "states_checked": len(states)}
    valid = ends and within and clearance > 0
    if problem.held:
        end_effectors = world.end_effectors
        X_E1E2, R_WE = start_hands(end_effectors, problem.q_start)
        t_dev, o_dev = deviations(end_effectors, states, X_E1E2)
        hands = np.zeros(1)  # the hands' orientation is free where the problem keeps none
        if problem.orientation is not None:
            hands = orientation_deviations(end_effectors, states, R_WE, problem.orientation.upright_only)
        closure = ClosureConstraint()
        row.update(
            closure_translation_dev_m=float(t_dev.max()),
            closure_orientation_dev_rad=float(o_dev.max()),
            hand_orientation_dev_rad=float(hands.max()),
        )
        valid = valid and t_dev.max() < closure.t_max and o_dev.max() < closure.o_max
        valid = valid and (problem.orientation is None or hands.max() < problem.orientation.o_max)
    row["valid"] = bool(valid)
    return row
