"""Where a held drill goes to aim at a target on a board: its bit's axis along the board's normal, into it, through
the target, the bit's tip a standoff off the surface.

Frames: W the world, O the object (origin on its support surface, z up). The drill turns the least that brings its
bit's axis onto the board's inward normal (about their cross product, through the grasps' midpoint, so both hands
turn with it), then moves so the tip lies `standoff` in front of the target. For an upright drill and a vertical
board that turn is a yaw: the drill stays upright.
"""

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RotationMatrix

from systems.messages import AimTarget, BoardSeen, GraspPoses, ObjectBelief, PlaceGoal
from systems.shape_space.tool_frame import ToolFrame

AIM_STANDOFF_M = 0.005  # m: the bit's tip this far off the board's surface
LEVEL_AXIS_MAX_DEG = 10.0  # a perceived tool axis this near level is taken level (level())
AIM_APPROACH_M = 0.10  # m: the aim is approached, and left, along the board's normal over this
# deg: the aim's moves (its approach, the aim, the way back) turned about the bit's axis (through its tip, along the
# board's normal), tried in turn after the unturned goal where the one before is out of reach or finds no plan: the
# bit aims the same, the drill's body and the hands turn about it. The aim that follows a turned approach keeps its
# turn (aim_pose turns the least), and the way back may turn it further or back.
AIM_ROLLS_DEG = (-15.0, 15.0, -30.0, 30.0)


def aim_pose(
    X_WO: RigidTransform,
    tool_O: ToolFrame,
    pivot_O: np.ndarray,
    target_W: np.ndarray,
    normal_W: np.ndarray,
    standoff: float = AIM_STANDOFF_M,
) -> RigidTransform:
    """X_WO aiming the held object (at X_WO now) at `target_W` (3, m) on a surface whose outward normal is `normal_W`
    (3, towards the robot), its tool's tip `standoff` (m) off it; pivot_O (3,): the turn's centre (the grasps'
    midpoint), in O."""
    normal = np.asarray(normal_W, dtype=float) / np.linalg.norm(normal_W)
    axis = tool_O.moved(X_WO).axis
    cross = np.cross(axis, -normal)
    angle = float(np.arctan2(np.linalg.norm(cross), axis @ -normal))
    if np.linalg.norm(cross) < 1e-9:  # already along it, or straight away from it: turn about the vertical
        cross = np.array([0.0, 0.0, 1.0])
    pivot_W = X_WO.multiply(np.asarray(pivot_O, dtype=float))
    turned = turned_about(pivot_W, RotationMatrix(AngleAxis(angle, cross / np.linalg.norm(cross)))) @ X_WO
    return RigidTransform(np.asarray(target_W) + standoff * normal - turned.multiply(tool_O.tip)) @ turned


def aim_target(board: BoardSeen, grasps: GraspPoses, X_WO: RigidTransform) -> AimTarget:
    """What to aim (AimTarget) from the board seen and the grasps and tool frame perceived with the object at X_WO.

    Raises:
        ValueError: no board, or no tool frame (a poor fit's grasps from the seen handles carry none).
    """
    if not board.found:
        raise ValueError(board.message)
    tool_O, pivot_O = held_tool(grasps, X_WO, "aim")
    return AimTarget(level(tool_O), pivot_O, board.target_W, board.normal_W)


def held_tool(grasps: GraspPoses, X_WO: RigidTransform, use: str) -> tuple[ToolFrame, np.ndarray]:
    """The perceived tool frame and the grasps' midpoint (the turns' pivot, (3,) m), in O, the object at X_WO.

    Raises:
        ValueError: no tool frame (a poor fit's grasps from the seen handles carry none), naming the `use`.
    """
    if grasps.tool_W is None:
        raise ValueError(f"no tool frame to {use}: the registration handed on none ({grasps.message})")
    X_OW = X_WO.inverse()
    hands = [grasps.poses_W[f"{side}_grasp"].translation() for side in ("left", "right")]
    return grasps.tool_W.moved(X_OW), X_OW.multiply(np.mean(hands, axis=0))


def level(tool_O: ToolFrame) -> ToolFrame:
    """The tool frame (in O) with its axis level, where it is within LEVEL_AXIS_MAX_DEG of level: a drill standing
    on its base holds its bit level (the generators' drills, the held-out and shop designs), and the perceived
    axis's dip is the registration's error there (test drills' first pick frames: -4.3 to +0.3 deg, its yaw within
    1.3 deg). The tip keeps its place; a steeper axis is kept as perceived."""
    axis = tool_O.axis
    if abs(axis[2]) > np.sin(np.radians(LEVEL_AXIS_MAX_DEG)):
        return tool_O
    return ToolFrame(tool_O.tip, [axis[0], axis[1], 0.0])


def aim_motion(goal: PlaceGoal, belief: ObjectBelief, aim: AimTarget) -> tuple[RigidTransform, RigidTransform]:
    """The held move of an aim goal from where the object is believed to be, as (X_motion_W, carried_motion_W: the
    object's motion since it was seen; the planner keeps the perceived object, moved by it, clear of the scene)."""
    now = belief.now_W
    if goal == PlaceGoal.AIM_BACK:
        X_goal = RigidTransform(AIM_APPROACH_M * aim.normal_W) @ now
    elif goal in (PlaceGoal.AIM_APPROACH, PlaceGoal.AIM):
        standoff = AIM_STANDOFF_M + (AIM_APPROACH_M if goal == PlaceGoal.AIM_APPROACH else 0.0)
        X_goal = aim_pose(now, aim.tool_O, aim.pivot_O, aim.target_W, aim.normal_W, standoff)
    else:
        raise ValueError(f"{goal!r} is no aim goal")
    return X_goal @ now.inverse(), now @ belief.seen_W.inverse()


def aim_rolls(X_motion_W: RigidTransform, belief: ObjectBelief, aim: AimTarget) -> tuple[RigidTransform, ...]:
    """An aim goal's move (X_motion_W: aim_motion's, from where the object is believed to be) with its goal turned
    about the bit's axis, the line through the tip along the board's normal, by each of AIM_ROLLS_DEG in turn (at
    every aim goal aim_pose has put the perceived bit's axis along the normal)."""
    tip_W = (X_motion_W @ belief.now_W).multiply(aim.tool_O.tip)
    normal = np.asarray(aim.normal_W, dtype=float) / np.linalg.norm(aim.normal_W)
    return rolled_about(X_motion_W, tip_W, normal, AIM_ROLLS_DEG)


def rolled_about(
    X_motion_W: RigidTransform, point_W: np.ndarray, axis_W: np.ndarray, rolls_deg
) -> tuple[RigidTransform, ...]:
    """A held move (X_motion_W) with its goal turned about the line through point_W along axis_W (unit, W) by each
    of rolls_deg (deg, right-handed about axis_W) in turn."""
    return tuple(
        turned_about(point_W, RotationMatrix(AngleAxis(np.radians(roll), axis_W))) @ X_motion_W for roll in rolls_deg
    )


def turned_about(point_W: np.ndarray, rotation: RotationMatrix) -> RigidTransform:
    """The turn by `rotation` about a point (W)."""
    return RigidTransform(point_W) @ RigidTransform(rotation) @ RigidTransform(-np.asarray(point_W))
