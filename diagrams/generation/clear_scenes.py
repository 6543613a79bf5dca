"""Tables to clear (the clear task): 2-3 familiar objects among 1-2 distractors, drawn from a seed.

Table k of a split is made from the seed [CLEAR_SEED, split, k] alone. The familiar objects are generated instances of
either category (unseen extra_ ones in the report and validation splits, train_ ones in the tune split), standing
where the arms pick them
(FAMILIAR_X, FAMILIAR_Y: between the table's middle and its left, the drop zone being at its right), at least
FAMILIAR_GAP_M apart, each one's hands' way to its true grasps free of every other object (clutter_scenes'
HAND_CLEARANCE_M), and each one within the arms' reach alone as the pick moves (arms_reach: its true pre-grasps or
their families', the straight approach to its grasps, the lift; of the first report tables' 40 objects drawn without
it, it refuses the four drills the ground-truth pick could not reach). The distractors (boxes, cylinders, bowls)
stand anywhere else on the table, clear of the robot. Nothing stands within ZONE_CLEARANCE_M of the drop zone. Ground
truth shapes the table only; the pick never reads it.
"""

import dataclasses

import numpy as np
from pydrake.math import RigidTransform

from diagrams.generation.clutter_scenes import (
    HAND_CLEARANCE_M,
    HAND_PASS_OVER_M,
    MIN_GAP_M,
    REGION_X,
    REGION_Y,
    TRIES,
    Placed,
    approach_points,
    clear_of_robot,
    draw_object,
    instance_outline,
    object_height,
    place_anywhere,
    robot_at_start,
)
from diagrams.generation.objects import catalog
from diagrams.generation.objects.library import resolve_object
from diagrams.planning_scene import make_pick_motions, object_surface_W, true_grasp_poses
from diagrams.scenario import ClutterObjectConfig, Scenario, initial_positions, replace_object
from diagrams.station import TABLE_HEIGHT, object_pose_on_table
from systems.messages import SIDES
from systems.pick_tasks import PLACE_LIFT_HEIGHT
from systems.planning.outlines import distance_to, gap_between
from systems.planning.pick_motions import PickMotions
from systems.planning.straight_motions import PlanningError

CLEAR_SEED = 81
SPLIT_CODES = {"report": 2, "tune": 1, "validation": 3}
# The unseen splits' familiar objects: extra_<first + 3 k + i>. Validation's are unseen too, for tuning what the
# training instances cannot show (perception of novel instances in clutter); report's are never tuned on.
UNSEEN_FIRST_INSTANCE = {"report": 2300, "validation": 2600}
FAMILIAR_COUNT = (2, 3)  # at least, at most
# m, table_top frame: where the arms pick (evaluation.py's random placements' range, on the side away from the zone)
FAMILIAR_X = (-0.22, -0.02)
FAMILIAR_Y = (-0.1, 0.2)
FAMILIAR_MAX_YAW = 0.3  # rad, from the presentation pose
FAMILIAR_GAP_M = 0.04  # m: between familiar objects' outlines
DISTRACTOR_COUNT = (1, 2)
DISTRACTOR_KINDS = ("box", "cylinder", "bowl")
DISTRACTOR_WEIGHTS = (0.4, 0.3, 0.3)
ZONE_CLEARANCE_M = 0.03  # m: every outline from the drop zone
REACH_CHECK_POINTS = 2000  # the object's true surface, sampled: the reach's obstacle, and its grasps' families' judge


def clear_scene(base: Scenario, k: int, split: str = "report") -> Scenario:
    """Table k of `split` for the clear task: base with its first familiar object as the scenario's object, the others
    and the distractors as clutter.

    Raises:
        ValueError: an unknown split.
    """
    if split not in SPLIT_CODES:
        raise ValueError(f"unknown split {split!r}: one of {tuple(SPLIT_CODES)}")
    rng = np.random.default_rng([CLEAR_SEED, SPLIT_CODES[split], k])
    zone = _zone_outline(base)
    count = int(rng.integers(FAMILIAR_COUNT[0], FAMILIAR_COUNT[1] + 1))
    for _ in range(20):  # (drawn again until at least FAMILIAR_COUNT[0] stand)
        familiar = _familiar_objects(base, rng, k, split, count, zone)
        if len(familiar) >= FAMILIAR_COUNT[0]:
            break
    robot = robot_at_start(base)
    placed = [p for _, p, _ in familiar]
    distractors = []
    for _ in range(int(rng.integers(DISTRACTOR_COUNT[0], DISTRACTOR_COUNT[1] + 1))):
        for _ in range(TRIES):
            other = draw_object(rng, "", "", "any", DISTRACTOR_KINDS, DISTRACTOR_WEIGHTS)
            candidate = Placed(place_anywhere(rng, other), object_height(other))
            x, y = other.xy
            inside = REGION_X[0] <= x <= REGION_X[1] and REGION_Y[0] <= y <= REGION_Y[1]
            if not inside or gap_between(candidate.outline, zone) < ZONE_CLEARANCE_M:
                continue
            if any(gap_between(candidate.outline, p.outline) < MIN_GAP_M for p in placed):
                continue
            if all(_hands_free(base, candidate, h) for _, _, h in familiar) and clear_of_robot(robot, candidate, base):
                placed.append(candidate)
                distractors.append(other)
                break
    first, *rest = (config for config, _, _ in familiar)
    scenario = replace_object(base, category=first.kind, instance=first.instance, file="", xy=first.xy, yaw=first.yaw)
    return dataclasses.replace(
        scenario, task="clear", clutter=[*rest, *distractors], random_seed=base.random_seed + k, requested_category=""
    )


def _familiar_objects(base: Scenario, rng, k: int, split: str, count: int, zone: np.ndarray) -> list:
    """Up to `count` familiar objects placed (module docstring): (config, Placed, the hands' approach points) each."""
    familiar: list[tuple[ClutterObjectConfig, Placed, np.ndarray]] = []
    motions = None  # (built at the first object drawn that stands clear)
    for i in range(count):
        category = ("watering_can", "drill")[int(rng.integers(2))]
        first = UNSEEN_FIRST_INSTANCE.get(split)
        instance = f"train_{(3 * k + i) % 8}" if first is None else f"extra_{first + 3 * k + i}"
        for _ in range(TRIES):
            xy = [float(rng.uniform(*FAMILIAR_X)), float(rng.uniform(*FAMILIAR_Y))]
            yaw = float(rng.uniform(-FAMILIAR_MAX_YAW, FAMILIAR_MAX_YAW))
            outline, height = instance_outline(category, instance, xy, catalog.presentation_yaw(category) + yaw)
            placed = Placed(outline, height)
            alone = replace_object(base, category=category, instance=instance, file="", xy=xy, yaw=yaw)
            hands = approach_points(alone)
            if gap_between(outline, zone) < ZONE_CLEARANCE_M:
                continue
            if any(gap_between(outline, other.outline) < FAMILIAR_GAP_M for _, other, _ in familiar):
                continue
            others = [(p, h) for _, p, h in familiar]
            if not all(_hands_free(base, p, hands) and _hands_free(base, placed, h) for p, h in others):
                continue
            if not clear_of_robot(robot_at_start(base), placed, base):
                continue
            motions = motions or make_pick_motions(base)
            if not arms_reach(motions, alone):
                continue
            familiar.append((ClutterObjectConfig(kind=category, instance=instance, xy=xy, yaw=yaw), placed, hands))
            break
    return familiar


def arms_reach(motions: PickMotions, scenario: Scenario) -> bool:
    """Whether the arms reach the scenario's object where it stands as the pick moves, the object alone on the
    table (lifted_configuration)."""
    return lifted_configuration(motions, scenario) is not None


def lifted_configuration(motions: PickMotions, scenario: Scenario) -> np.ndarray | None:
    """The arms' configuration holding the scenario's object, alone on the table, PLACE_LIFT_HEIGHT above where it
    stands, reached as the pick moves: both hands at its true pre-grasps or another grasp of their families (the
    pick's reach around the object, the torso turning where it must: ReachMotions.reach_pregrasps), straight on to
    the grasps, and straight up with it; None where the arms do not reach it so."""
    poses = true_grasp_poses(scenario)
    grasps = {side: poses[f"{side}_grasp"] for side in SIDES}
    model = resolve_object(scenario.object)
    surface, _ = object_surface_W(model, object_pose_on_table(scenario, model), REACH_CHECK_POINTS)
    try:
        keyframes, chosen = motions.reach_pregrasps(
            initial_positions(scenario), {side: poses[f"{side}_pregrasp"] for side in SIDES}, grasps, surface, surface
        )
        held = {side: grasps[side] @ chosen[side] for side in SIDES}
        q_grasp = motions.straight(keyframes[-1], held)[-1]
        lift = {side: RigidTransform([0, 0, PLACE_LIFT_HEIGHT]) @ X for side, X in held.items()}
        return motions.straight(q_grasp, lift)[-1]
    except PlanningError:
        return None


def _zone_outline(scenario: Scenario) -> np.ndarray:
    """The drop zone's outline (4 x 2, table_top frame, m)."""
    (cx, cy), (sx, sy) = scenario.clear.zone_xy, scenario.clear.zone_size
    return np.array([[cx - sx / 2, cy - sy / 2], [cx + sx / 2, cy - sy / 2], [cx + sx / 2, cy + sy / 2],
                     [cx - sx / 2, cy + sy / 2]])  # fmt: skip


def _hands_free(scenario: Scenario, other: Placed, hands: np.ndarray) -> bool:
    """Whether an object leaves the hands' approach (points, x, y in the table_top frame) free: HAND_CLEARANCE_M
    from it, unless it is low enough for the hands to pass over it."""
    top = scenario.table_xyz[2] + TABLE_HEIGHT + other.height
    for point in hands:
        low = point[2] - top < HAND_PASS_OVER_M
        if low and distance_to(other.outline, point[:2]) < HAND_CLEARANCE_M:
            return False
    return True
