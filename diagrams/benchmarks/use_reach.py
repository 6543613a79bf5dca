"""Whether the arms reach the poses that use a held object (scripts/benchmark_use_reach.py), goal by goal: IK under
the closure from the held start, as the planner benchmark's problems are drawn.

Pour: for each can and each turn of its spout about the vertical before the pour, the tilts about the grasps'
midpoint (pour_goals: across the outflow's plane, the spout down) the arms reach, and where the outflow then points.
Aim: for each drill and each target on a board at the table's far edge or sides (aim_goals: the bit along the board's
normal, its tip 5 mm off the target), whether the arms reach it.

The object starts as a pick leaves it: lifted LIFT_M above where it stood at the default placement, at its yaw.
Ground truth (the generator's grasps and tool frame) places it: the question is the arms' reach, not perception's.
"""

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RotationMatrix

from diagrams.generation.objects.library import resolve_object
from diagrams.generation.planning_problems import held_problem
from diagrams.scenario import TABLE_HALF_SIZE, load_scenario, replace_object
from diagrams.station import TABLE_HEIGHT, object_pose_on_table
from systems.planning.aim_goals import aim_pose, turned_about
from systems.planning.pick_motions import PickMotions
from systems.planning.pour_goals import outflow_elevation

LIFT_M = 0.10  # m: how high the object is held above where it stood
# The boards: where each stands (the table's far edge, its left and right sides) as (its plane's offset from the
# table's centre along its outward normal's opposite, the normal in W).
BOARDS = {
    "far": (np.array([1.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])),
    "left": (np.array([0.0, 1.0, 0.0]), np.array([0.0, -1.0, 0.0])),
    "right": (np.array([0.0, -1.0, 0.0]), np.array([0.0, 1.0, 0.0])),
}


# The pour's pivot: the grasps' midpoint, or one hand's grasp.
PIVOTS = ("middle", "right", "left")


def pour_reach_rows(
    motions: PickMotions,
    instances: list[str],
    yaws: list[float],
    turns_deg: list[float],
    tilts_deg: list[float],
    pivot: str = "middle",
    lift: float = LIFT_M,
) -> list[dict]:
    """Pour: one row per can, yaw (rad, its placement's) and turn (deg): the outflow's elevation before the tilt, each
    tilt's answer (reached or why not), the largest tilt reached from the smallest up without a gap, and the outflow's
    elevation there (deg; None where none is reached). pivot: PIVOTS, what the can turns about; lift: how high it is
    held, m."""
    rows = []
    for instance in instances:
        for yaw in yaws:
            scenario, X_WO, tool, grasps = _held("watering_can", instance, yaw, lift)
            hands = [grasps[f"{side}_grasp"].translation() for side in ("left", "right") if pivot in ("middle", side)]
            pivot_W = X_WO.multiply(np.mean(hands, axis=0))
            for turn in turns_deg:
                turned = turned_about(pivot_W, RotationMatrix.MakeZRotation(np.radians(turn))) @ X_WO
                outflow = tool.moved(turned).axis
                across = np.cross([0.0, 0.0, 1.0], np.append(outflow[:2] / np.linalg.norm(outflow[:2]), 0.0))
                answers, largest = {}, None
                for tilt in sorted(tilts_deg):
                    tilted = turned_about(pivot_W, RotationMatrix(AngleAxis(np.radians(tilt), across))) @ turned
                    problem = held_problem(motions, scenario, lift, tilted @ X_WO.inverse(), [])
                    answers[tilt] = "reached" if not isinstance(problem, str) else problem
                for tilt in sorted(tilts_deg):  # the largest reached with every smaller one reached too
                    if answers[tilt] != "reached":
                        break
                    largest = tilt
                elevation = np.degrees(outflow_elevation(turned, tool))
                rows.append({
                    "instance": instance, "yaw_rad": yaw, "pivot": pivot, "lift_m": lift, "turn_deg": turn,
                    "elevation_deg": float(elevation),
                    "tilts": {str(t): a for t, a in answers.items()}, "largest_tilt_deg": largest,
                    "outflow_at_largest_deg": None if largest is None else float(elevation - largest),
                })  # fmt: skip
    return rows


def aim_reach_rows(
    motions: PickMotions,
    instances: list[str],
    yaws: list[float],
    heights: list[float],
    offsets: list[float],
    inset: float = 0.0,
) -> list[dict]:
    """Aim: one row per drill, yaw (rad, its placement's), board (BOARDS, standing `inset` m in from the table's
    edge), target height above the table and offset along the board from the table's middle (m): the answer (reached
    or why not)."""
    rows = []
    for instance in instances:
        for yaw in yaws:
            scenario, X_WO, tool, grasps = _held("drill", instance, yaw, LIFT_M)
            pivot_O = 0.5 * (grasps["left_grasp"].translation() + grasps["right_grasp"].translation())
            centre = np.array(scenario.table_xyz) + [0.0, 0.0, TABLE_HEIGHT]
            for board, (outward, normal) in BOARDS.items():
                along = np.cross([0.0, 0.0, 1.0], normal)  # the board's horizontal direction
                edge = np.abs(outward[:2]) @ TABLE_HALF_SIZE - inset
                for height in heights:
                    for offset in offsets:
                        target = centre + edge * outward + offset * along + [0.0, 0.0, height]
                        goal = aim_pose(X_WO, tool, pivot_O, target, normal)
                        problem = held_problem(motions, scenario, LIFT_M, goal @ X_WO.inverse(), [])
                        rows.append({
                            "instance": instance, "yaw_rad": yaw, "board": board, "inset_m": inset, "height_m": height,
                            "offset_m": offset, "target_W": target.tolist(),
                            "answer": "reached" if not isinstance(problem, str) else problem,
                        })  # fmt: skip
    return rows


def _held(category: str, instance: str, yaw: float, lift: float):
    """A generated instance at the default placement and `yaw` (rad) held `lift` (m) above where it stands: the
    scenario, X_WO, its true tool frame and control poses (in O)."""
    scenario = replace_object(load_scenario(), category=category, instance=instance, yaw=yaw)
    model = resolve_object(scenario.object)
    X_WO = RigidTransform([0.0, 0.0, lift]) @ object_pose_on_table(scenario, model)
    return scenario, X_WO, model.info.tool_frame(), model.info.control_poses()
