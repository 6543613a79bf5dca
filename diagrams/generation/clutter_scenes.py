"""Cluttered tables: the object to pick among 1-4 others, drawn from a seed.

Scene k of a split is made from the seed [CLUTTER_SEED, split, k] alone. The object to pick (the target) is an
unseen generated instance near the default spot; the others are instances of both categories and distractors
(boxes, cylinders, bowls of random size and colour). Footprints (their convex outlines on the table) never
overlap. In every scene one other object stands within NEAR_GAP_M of the target, and in half of them one stands
between the target and the robot. Another instance of the target's category always stands farther from the robot
than the target, so that the nearest one of the category is the target.

The draw keeps the hands' way to the target's true grasps free (HAND_CLEARANCE_M beside the approach, unless the
other object is low enough to pass over): a scene is a problem the robot can solve. Ground truth shapes the scene
only; the pick never reads it.
"""

import dataclasses
import functools

import numpy as np
import trimesh
from pydrake.math import RollPitchYaw

from diagrams.generation.objects import catalog
from diagrams.generation.objects.library import generated_instance_directory
from diagrams.planning_scene import true_grasp_poses
from diagrams.scenario import ClutterObjectConfig, Scenario, initial_positions, replace_object
from diagrams.station import TABLE_HEIGHT
from systems.planning.outlines import convex_outline, distance_to, edge_distances, gap_between, inside

CLUTTER_SEED = 35
# Each split's code in its tables' seeds (code 0, a report range looked at while the scenes were built, is unused).
SPLIT_CODES = {"report": 2, "tune": 1, "validation": 3}
# The target: extra_<first + k> in the report and validation splits (unseen; validation's for tuning what training
# instances cannot show, report's never tuned on), train_<k % 8> in the tune split; placed within TARGET_HALF_SIZE_M
# (x, y) of TARGET_CENTRE (table_top frame, m) and TARGET_MAX_YAW of the presentation.
TARGET_FIRST_INSTANCE = {"report": 2200, "validation": 2500}
TARGET_CENTRE = (-0.09, 0.0)  # (3 cm farther than the default spot: room in view for an object in front)
TARGET_HALF_SIZE_M = (0.04, 0.08)
TARGET_MAX_YAW = 0.3
# Other instances of a category: one of extra_<OTHERS_FIRST_INSTANCE..+OTHERS_INSTANCES-1>.
OTHERS_FIRST_INSTANCE = 2100
OTHERS_INSTANCES = 40
# Where other objects stand (their origins, table_top frame, m): the camera sees the table from x = -0.32 on.
REGION_X = (-0.32, 0.3)
REGION_Y = (-0.45, 0.45)
NEAR_GAP_M = (0.01, 0.05)  # the near object's gap to the target's outline
MIN_GAP_M = 0.015  # between any two outlines
FRONT_MAX_HEIGHT_M = 0.09  # an object between the target and the robot is no taller
HAND_CLEARANCE_M = 0.08  # an object's outline from the hands' approach paths (xy), unless it passes under them
HAND_PASS_OVER_M = 0.15  # how far below a point of the approach (a grasp frame) an object's top must stay to pass
# under the hand (its palm and fingers reach 7 cm below the grasp frame)
ROBOT_CLEARANCE_M = 0.05  # an object's outline from the robot at its start (its sphere model), unless well below it
KINDS = ("box", "cylinder", "bowl", "other_category", "same_category")
KIND_WEIGHTS = (0.25, 0.2, 0.2, 0.2, 0.15)
TRIES = 200


@dataclasses.dataclass
class Placed:
    """An object's outline on the table (convex, M x 2 in the table_top frame, m) and its height (m)."""

    outline: np.ndarray
    height: float


def clutter_scene(base: Scenario, category: str, k: int, split: str = "report") -> Scenario:
    """Scene k of `split`: base with the target (a `category` instance) placed, and its clutter.

    Raises:
        ValueError: an unknown split or category.
    """
    if split not in SPLIT_CODES:
        raise ValueError(f"unknown split {split!r}: one of {tuple(SPLIT_CODES)}")
    other_category = {"watering_can": "drill", "drill": "watering_can"}.get(category)
    if other_category is None:
        raise ValueError(f"cluttered scenes are drawn for the generated categories, not {category!r}")
    rng = np.random.default_rng([CLUTTER_SEED, SPLIT_CODES[split], k])
    first = TARGET_FIRST_INSTANCE.get(split)
    instance = f"train_{k % 8}" if first is None else f"extra_{first + k}"
    xy = np.array(TARGET_CENTRE) + rng.uniform(-1, 1, 2) * TARGET_HALF_SIZE_M
    yaw = float(rng.uniform(-TARGET_MAX_YAW, TARGET_MAX_YAW))
    scenario = replace_object(base, category=category, instance=instance, file="", xy=[*map(float, xy)], yaw=yaw)
    target = Placed(*instance_outline(category, instance, xy, catalog.presentation_yaw(category) + yaw))
    hands = approach_points(scenario)
    robot = robot_at_start(scenario)
    count = int(rng.integers(1, 5))
    # The object in front first (its room in view is small), in half of the tables; then the near one.
    in_front = rng.uniform() < 0.5
    roles = (["front", "near"] if in_front else ["near", "any"]) + ["any"] * 2
    count = max(count, 2) if in_front else count
    placed, others = [target], []
    for role in roles[:count]:
        for _ in range(TRIES):
            other = draw_object(rng, category, other_category, role)
            outline = _place(rng, other, role, target)
            if outline is None:
                continue
            candidate = Placed(outline, object_height(other))
            if _acceptable(candidate, other, role, placed, hands, target, scenario) and clear_of_robot(
                robot, candidate, scenario
            ):
                placed.append(candidate)
                others.append(other)
                break
    # The user names the category to pick: the pick takes the nearest object of it.
    return dataclasses.replace(scenario, clutter=others, random_seed=base.random_seed + k, requested_category=category)


def draw_object(
    rng, category: str, other_category: str, role: str, kinds=KINDS, weights=KIND_WEIGHTS
) -> ClutterObjectConfig:
    """Another object for a role ("front", "near", "any"): one of `kinds` (with `weights`), its size, colour and yaw
    drawn; its xy is set by place()."""
    kind = kinds[rng.choice(len(kinds), p=weights)]
    color = [float(c) for c in rng.uniform(0.05, 0.95, 3)]
    yaw = float(rng.uniform(-np.pi, np.pi))
    tall = FRONT_MAX_HEIGHT_M if role == "front" else 0.2
    if role == "front" and kind not in ("box", "cylinder"):
        kind = "box"  # (instances and bowls are too large to stand in front in view, or to pass under the hands)
    if kind in ("other_category", "same_category"):
        name = other_category if kind == "other_category" else category
        instance = f"extra_{OTHERS_FIRST_INSTANCE + int(rng.integers(OTHERS_INSTANCES))}"
        if role == "front" and _instance_height(name, instance) > FRONT_MAX_HEIGHT_M:
            kind = "box"  # too tall to stand in front: a box instead
        else:
            return ClutterObjectConfig(kind=name, instance=instance, yaw=yaw)
    wide = 0.08 if role == "front" else 0.14  # (in front, the camera's view leaves little room)
    if kind == "box":
        size = [*rng.uniform(0.04, wide, 2), rng.uniform(0.03, tall)]
    elif kind == "cylinder":
        diameter = rng.uniform(0.05, 0.1)
        size = [diameter, diameter, rng.uniform(0.06, min(tall, 0.18))]
    else:
        diameter = rng.uniform(0.12, 0.18)
        size = [diameter, diameter, rng.uniform(0.05, 0.08)]
    mass = float(rng.uniform(0.2, 0.6))
    return ClutterObjectConfig(kind=kind, size=[float(v) for v in size], color=color, yaw=yaw, mass=mass)


def _place(rng, other: ClutterObjectConfig, role: str, target: Placed) -> np.ndarray | None:
    """Chooses other.xy for its role (in place) and returns its outline there, or None."""
    centre = target.outline.mean(axis=0)
    if role == "any":
        return place_anywhere(rng, other)
    # Near the target, or in front of it (towards the robot, -x): slide in from afar along a direction until the
    # gap to the target's outline is the one drawn.
    angle = rng.uniform(-np.pi, np.pi) if role == "near" else np.pi + rng.uniform(-0.35, 0.35)
    gap = rng.uniform(*NEAR_GAP_M) if role == "near" else rng.uniform(NEAR_GAP_M[0], 0.15)
    direction = np.array([np.cos(angle), np.sin(angle)])
    for distance in np.arange(0.45, 0.0, -0.004):
        other.xy = [float(v) for v in centre + distance * direction]
        outline = outline_of(other)
        if gap_between(outline, target.outline) <= gap:
            return outline
    return None


def place_anywhere(rng, other: ClutterObjectConfig) -> np.ndarray:
    """Sets other.xy anywhere in the region; returns its outline there."""
    other.xy = [float(rng.uniform(*REGION_X)), float(rng.uniform(*REGION_Y))]
    return outline_of(other)


def _acceptable(candidate, other, role, placed, hands, target, scenario) -> bool:
    x, y = other.xy
    if not (REGION_X[0] <= x <= REGION_X[1] and REGION_Y[0] <= y <= REGION_Y[1]):
        return False
    if any(gap_between(candidate.outline, p.outline) < MIN_GAP_M for p in placed):
        return False
    if role == "near" and gap_between(candidate.outline, target.outline) > NEAR_GAP_M[1]:
        return False
    # The hands' approach stays free, unless the object is low enough for the hands to pass over it.
    top = scenario.table_xyz[2] + TABLE_HEIGHT + candidate.height
    for point in hands:
        if point[2] - top < HAND_PASS_OVER_M and distance_to(candidate.outline, point[:2]) < HAND_CLEARANCE_M:
            return False
    if other.kind == scenario.object.category:  # farther from the robot than the target
        return x > target.outline.mean(axis=0)[0] + 0.1
    return True


def clear_of_robot(robot: np.ndarray, candidate: Placed, scenario: Scenario) -> bool:
    """Whether an object stands ROBOT_CLEARANCE_M clear of the robot at its start (spheres S x 4, W): in xy, of
    every sphere that reaches below its top plus that clearance."""
    top = scenario.table_xyz[2] + TABLE_HEIGHT + candidate.height
    low = robot[robot[:, 2] - robot[:, 3] < top + ROBOT_CLEARANCE_M]
    if not len(low):
        return True
    xy = low[:, :2] - scenario.table_xyz[:2]
    if inside(xy, candidate.outline).any():
        return False
    return bool(np.all(edge_distances(xy, candidate.outline) > low[:, 3] + ROBOT_CLEARANCE_M))


def robot_at_start(scenario: Scenario) -> np.ndarray:
    """The robot's sphere model at its initial positions (S x 4: centre in W, radius; m)."""
    from diagrams.planning_scene import make_planning_world  # (a plant: built once per robot and start)

    key = (tuple(scenario.initial_arm_positions), scenario.pelvis_height, scenario.robot.torso)
    if key not in _ROBOT_AT_START:
        world = make_planning_world(scenario)
        q = initial_positions(scenario)
        centres = world.spheres.centres_W(world.kinematics.body_poses(q[None]))[0]
        _ROBOT_AT_START[key] = np.column_stack([centres, world.spheres.radius])
    return _ROBOT_AT_START[key]


_ROBOT_AT_START: dict = {}


def approach_points(scenario: Scenario) -> np.ndarray:
    """Points along each hand's straight approach from its true pre-grasp to its grasp (W; x, y in the
    table_top frame), and the grasp frames' fingertips either side."""
    poses = true_grasp_poses(scenario)
    points = []
    for side in ("left", "right"):
        start, end = poses[f"{side}_pregrasp"].translation(), poses[f"{side}_grasp"].translation()
        points += [start + s * (end - start) for s in np.linspace(0, 1, 5)]
    points = np.array(points)
    points[:, :2] -= scenario.table_xyz[:2]
    return points


def outline_of(other: ClutterObjectConfig) -> np.ndarray:
    """The object's convex outline on the table (M x 2, table_top frame, m)."""
    if other.instance:
        yaw = catalog.presentation_yaw(other.kind) + other.yaw
        return instance_outline(other.kind, other.instance, other.xy, yaw)[0]
    if other.kind == "box":
        hx, hy = 0.5 * np.array(other.size[:2])
        local = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
    else:
        angles = np.linspace(0, 2 * np.pi, 32, endpoint=False)
        local = 0.5 * other.size[0] * np.column_stack([np.cos(angles), np.sin(angles)])
    return _moved(local, other.xy, other.yaw)


def object_height(other: ClutterObjectConfig) -> float:
    return _instance_height(other.kind, other.instance) if other.instance else other.size[2]


@functools.cache
def _instance_mesh(category: str, instance: str) -> trimesh.Trimesh:
    return trimesh.load(generated_instance_directory(category, instance) / "visual.obj", force="mesh")


def _instance_height(category: str, instance: str) -> float:
    return float(_instance_mesh(category, instance).bounds[1, 2])


def instance_outline(category: str, instance: str, xy, yaw: float) -> tuple[np.ndarray, float]:
    hull = convex_outline(_instance_mesh(category, instance).vertices[:, :2])
    return _moved(hull, xy, yaw), _instance_height(category, instance)


def _moved(local: np.ndarray, xy, yaw: float) -> np.ndarray:
    R = RollPitchYaw(0.0, 0.0, yaw).ToRotationMatrix().matrix()[:2, :2]
    return local @ R.T + np.asarray(xy)


def scene_outlines(scenario: Scenario) -> list[np.ndarray]:
    """The outlines of the target (first) and of every other object of a scenario (table_top frame): for tests and
    figures."""
    obj = scenario.object
    target = instance_outline(obj.category, obj.instance, obj.xy, catalog.presentation_yaw(obj.category) + obj.yaw)
    return [target[0]] + [outline_of(other) for other in scenario.clutter]
