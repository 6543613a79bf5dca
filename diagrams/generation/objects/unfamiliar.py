"""Watering cans and drills outside the generators' families, as a user would bring them (written as plain OBJ
meshes by scripts/make_unfamiliar_objects.py).

Two splits, apart on purpose:
- held_out: six designs per category that no generator makes (docs/shape_space.md shows them): a box-bodied
  jerrycan, a bulbous can, a tall slim can with its spout at the foot, a squat can with a wide arch, a can with one
  handle from the lid round to the back, a bucket widening upwards; a long hammer drill, a compact drill with a
  thick grip, a drill whose side handle slopes down, a corded drill (no battery: a heel and a cable), a drill whose
  grip stands under the housing's middle, a drill on a big round battery pack. No parameter of the pipeline is
  chosen on them; they were changed only until the ground-truth pick could reach them.
- tune: the generators' own shapes with their parameters stretched past the generators' ranges (bigger, smaller,
  further out handles), for choosing the registrar's parameters.

The pipeline reaches these objects only through `--object-file` (and the benchmarks' `--object-files`). Each mesh
stands in the category's object frame O (origin at the centre of its bottom face, z up, x along the functional
axis: spout or chuck), already where `--object-file` recentres a mesh, so `<name>.info.yaml` beside it (its true
grasp frames and mass, for judging, never read by the pick) is in the frame the pick uses.
"""

from dataclasses import replace

import numpy as np
from pydrake.common.schema import Transform
from pydrake.math import RigidTransform

from diagrams.generation.objects import catalog, geometry
from diagrams.generation.objects import drill as drill_convention
from diagrams.generation.objects import watering_can as can_convention
from diagrams.generation.objects.instance import ObjectInstance, Part, make_grasp
from diagrams.generation.objects.library import recentred
from diagrams.generation.part_labels import PartSurface, part_surface
from systems.messages import PartRole

CAN_MASS = 0.9  # kg
DRILL_MASS = 1.6  # kg


def _left_can_grasp(point):
    """The can's convention: the left hand from above, tilted towards the robot's left, along the top handle."""
    tilt = can_convention.LEFT_APPROACH_TILT
    return make_grasp(point, approach=[0, -np.sin(tilt), -np.cos(tilt)], handle_axis=[1, 0, 0])


def _right_can_grasp(point, handle_axis=(0, 0, 1)):
    """The can's convention: the right hand from behind, right and above, along the rear handle."""
    turn, dip = can_convention.RIGHT_APPROACH_TURN, can_convention.RIGHT_APPROACH_DIP
    return make_grasp(point, approach=[np.cos(turn), np.sin(turn), -dip], handle_axis=handle_axis)


def _rounded_path(corners: np.ndarray, radius: float, samples: int = 8) -> np.ndarray:
    """A polyline through `corners` (n x 3) with each inner corner rounded by a circular fillet of `radius`."""
    points = [corners[0]]
    for a, b, c in zip(corners[:-2], corners[1:-1], corners[2:], strict=True):
        u, v = (a - b) / np.linalg.norm(a - b), (c - b) / np.linalg.norm(c - b)
        start, end = b + radius * u, b + radius * v
        for s in np.linspace(0, 1, samples):  # a quadratic Bezier: close to the fillet, smooth enough for a tube
            points.append((1 - s) ** 2 * start + 2 * s * (1 - s) * b + s**2 * end)
    points.append(corners[-1])
    path = np.array(points)
    keep = np.r_[True, np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-6]
    return path[keep]


def _tube_part(name, path, radius):
    return Part(name, geometry.tube(path, radius), geometry.convex_pieces_of_tube(path, radius, 6))


def _revolved(profile: list[tuple[float, float]], ratio: float = 1.0) -> "geometry.trimesh.Trimesh":
    """A convex body of revolution from (z, radius) pairs (an ellipse of y/x = ratio at each height)."""
    return geometry.convex_loft([geometry.ellipse_ring([0, 0, z], r, r * ratio) for z, r in profile])


def _spout(base, angle, length, radius):
    direction = np.array([np.cos(angle), 0.0, np.sin(angle)])
    end = base + length * direction
    tip = 0.6 * radius
    return [
        Part("spout", geometry.frustum(base, end, radius, tip), [geometry.frustum(base, end, radius, tip)]),
        Part("rose", geometry.frustum(end - 0.01 * direction, end + 0.02 * direction, tip, 1.8 * tip), []),
    ]


def jerrycan(name):
    """A box body with rounded edges; the top handle a straight bar on two posts, the rear handle a D."""
    w, d, h, tube = 0.2, 0.13, 0.24, 0.012
    rings = [geometry.ellipse_ring([0, 0, z], w / 2, d / 2, 8) for z in (0.0, h)]
    corners = np.vstack(rings)
    body = geometry.trimesh.convex.convex_hull(corners)
    top_corners = [[0.05, 0, h - 0.01], [0.05, 0, h + 0.06], [-0.07, 0, h + 0.06], [-0.07, 0, h - 0.01]]
    top = _rounded_path(np.array(top_corners), 0.02)
    back = -w / 2
    rear_corners = [[back + 0.01, 0, 0.17], [back - 0.06, 0, 0.17], [back - 0.06, 0, 0.06], [back + 0.01, 0, 0.06]]
    rear = _rounded_path(np.array(rear_corners), 0.02)
    parts = [Part("body", body, [body]), _tube_part("top_handle", top, tube), _tube_part("rear_handle", rear, tube)]
    parts += _spout(np.array([w / 2 - 0.03, 0, 0.18]), 0.9, 0.14, 0.018)
    grasps = {"left": _left_can_grasp([-0.01, 0, h + 0.06]), "right": _right_can_grasp([-w / 2 - 0.06, 0, 0.115])}
    return ObjectInstance("watering_can", name, {"design": 0.0}, parts, CAN_MASS, grasps)


def bulb_can(name):
    """A bulbous body (widest at mid height, narrow neck); a high narrow arch on top, a large rear loop."""
    profile = [(0.0, 0.07), (0.05, 0.1), (0.1, 0.11), (0.15, 0.1), (0.2, 0.075), (0.22, 0.06)]
    body = _revolved(profile)
    tube, h = 0.012, 0.22
    angles = np.linspace(0, np.pi, 24)
    top = np.column_stack([0.045 * np.cos(angles), 0 * angles, h - 0.01 + 0.1 * np.sin(angles)])
    rear = geometry.arc([-0.085, 0, 0.12], 0.08, np.pi / 2, 3 * np.pi / 2)
    parts = [Part("body", body, [body]), _tube_part("top_handle", top, tube), _tube_part("rear_handle", rear, tube)]
    parts += _spout(np.array([0.07, 0, 0.06]), 0.7, 0.22, 0.017)
    grasps = {"left": _left_can_grasp([0, 0, h + 0.09]), "right": _right_can_grasp([-0.165, 0, 0.12])}
    return ObjectInstance("watering_can", name, {"design": 1.0}, parts, CAN_MASS, grasps)


def slim_can(name):
    """A tall slim cylinder whose spout leaves at the foot; a tall D-shaped rear handle, a small top arch."""
    r, h, tube = 0.062, 0.31, 0.012
    body = _revolved([(0.0, r), (h, r)])
    angles = np.linspace(0, np.pi, 24)
    top = np.column_stack([0.035 * np.cos(angles), 0 * angles, h - 0.01 + 0.07 * np.sin(angles)])
    rear_corners = [[-r + 0.01, 0, 0.25], [-r - 0.06, 0, 0.25], [-r - 0.06, 0, 0.09], [-r + 0.01, 0, 0.09]]
    rear = _rounded_path(np.array(rear_corners), 0.025)
    parts = [Part("body", body, [body]), _tube_part("top_handle", top, tube), _tube_part("rear_handle", rear, tube)]
    parts += _spout(np.array([r - 0.02, 0, 0.03]), 0.5, 0.32, 0.016)
    grasps = {"left": _left_can_grasp([0, 0, h + 0.06]), "right": _right_can_grasp([-r - 0.06, 0, 0.17])}
    return ObjectInstance("watering_can", name, {"design": 2.0}, parts, CAN_MASS, grasps)


def squat_can(name):
    """A wide, low, slightly oval body; a wide flat arch across the whole lid, a small rear loop."""
    r, h, tube = 0.125, 0.14, 0.012
    body = _revolved([(0.0, r), (h, 0.9 * r)], ratio=0.9)
    angles = np.linspace(0, np.pi, 28)
    top = np.column_stack([0.1 * np.cos(angles), 0 * angles, h - 0.01 + 0.07 * np.sin(angles)])
    rear = geometry.arc([-0.125 + 0.01, 0, 0.075], 0.045, np.pi / 2, 3 * np.pi / 2)
    parts = [Part("body", body, [body]), _tube_part("top_handle", top, tube), _tube_part("rear_handle", rear, tube)]
    parts += _spout(np.array([0.1, 0, 0.04]), 0.6, 0.2, 0.02)
    grasps = {"left": _left_can_grasp([0, 0, h + 0.06]), "right": _right_can_grasp([-0.16, 0, 0.075])}
    return ObjectInstance("watering_can", name, {"design": 3.0}, parts, CAN_MASS, grasps)


def one_loop_can(name):
    """One handle from the front of the lid up, back over the top and down to the rear wall: the left hand
    takes its top run, the right hand its rear run."""
    r, h, tube = 0.085, 0.22, 0.012
    body = _revolved([(0.0, r), (h, r)])
    back = -r - 0.06
    corners = [[0.03, 0, h - 0.01], [0.03, 0, h + 0.07], [back, 0, h + 0.07], [back, 0, 0.07], [-r + 0.01, 0, 0.07]]
    loop = _rounded_path(np.array(corners), 0.035)
    parts = [Part("body", body, [body]), _tube_part("handle", loop, tube)]
    parts += _spout(np.array([r - 0.03, 0, 0.05]), 0.75, 0.22, 0.018)
    grasps = {"left": _left_can_grasp([-0.04, 0, h + 0.07]), "right": _right_can_grasp([-r - 0.06, 0, 0.15])}
    return ObjectInstance("watering_can", name, {"design": 4.0}, parts, CAN_MASS, grasps)


def bucket_can(name):
    """A body widening upwards (a bucket); the top arch set back, the rear handle a straight bar leaning back."""
    h, tube = 0.2, 0.012
    body = _revolved([(0.0, 0.07), (h, 0.105)])
    angles = np.linspace(0, np.pi, 24)
    top = np.column_stack([-0.02 + 0.06 * np.cos(angles), 0 * angles, h - 0.01 + 0.075 * np.sin(angles)])
    lean = np.array([-np.sin(0.3), 0, np.cos(0.3)])
    foot = np.array([-0.075, 0, 0.05])
    out = foot + [-0.05, 0, 0]
    rear = _rounded_path(np.array([foot, out, out + 0.12 * lean, [-0.1, 0, 0.17]]), 0.02)
    parts = [Part("body", body, [body]), _tube_part("top_handle", top, tube), _tube_part("rear_handle", rear, tube)]
    parts += _spout(np.array([0.06, 0, 0.08]), 0.8, 0.2, 0.017)
    grip = foot + [-0.05, 0, 0] + 0.06 * lean
    grasps = {"left": _left_can_grasp([-0.02, 0, h + 0.065]), "right": _right_can_grasp(grip, handle_axis=lean)}
    return ObjectInstance("watering_can", name, {"design": 5.0}, parts, CAN_MASS, grasps)


def _drill_grasps(grip_middle, grip_axis, side_middle, side_axis=(0, 1, 0)):
    tilt, turn = drill_convention.APPROACH_TILT, drill_convention.RIGHT_APPROACH_YAW
    return {
        "left": make_grasp(side_middle, approach=[np.sin(tilt), 0, -np.cos(tilt)], handle_axis=side_axis),
        "right": make_grasp(grip_middle, approach=[np.cos(turn), np.sin(turn), 0], handle_axis=grip_axis),
    }


def _drill(name, design, battery, grip, housing, chuck, side, extra=()):
    """Assembles a drill from (bottom, axis, length, radius) of the grip, (rear, length, radius) of the housing,
    (length, radius factor) of the chuck and (position along the housing, length, radius, axis) of the side handle."""
    grip_bottom, grip_axis, grip_length, grip_radius = grip
    grip_axis = np.asarray(grip_axis, float) / np.linalg.norm(grip_axis)
    housing_rear, housing_length, rh = housing
    housing_front = housing_rear + [housing_length, 0, 0]
    chuck_length, chuck_factor = chuck
    position, side_length, side_radius, side_axis = side
    side_axis = np.asarray(side_axis, float) / np.linalg.norm(side_axis)
    side_start = housing_rear + [position * housing_length, 0, 0]
    side_end = side_start + (rh + side_length) * side_axis
    chuck_start, chuck_end = housing_front - [0.005, 0, 0], housing_front + [chuck_length, 0, 0]
    knob_start, knob_end = side_end - 0.005 * side_axis, side_end + 0.018 * side_axis
    grip_top = grip_bottom + (grip_length + rh) * grip_axis
    parts = [
        _solid("grip", geometry.frustum(grip_bottom, grip_top, grip_radius, grip_radius)),
        _solid("housing", geometry.frustum(housing_rear, housing_front, rh, 0.85 * rh), density=1.5),
        _solid("chuck", geometry.frustum(chuck_start, chuck_end, chuck_factor * rh, 0.6 * chuck_factor * rh), 2.0),
        _solid("side_handle", geometry.frustum(side_start, side_end, side_radius, side_radius)),
        _solid("knob", geometry.frustum(knob_start, knob_end, 1.5 * side_radius, 1.2 * side_radius)),
        *battery,
        *extra,
    ]
    grip_middle = grip_bottom + 0.5 * grip_length * grip_axis
    side_middle = side_start + 0.5 * (rh + side_length) * side_axis
    grasps = _drill_grasps(grip_middle, grip_axis, side_middle, side_axis)
    return ObjectInstance("drill", name, {"design": float(design)}, parts, DRILL_MASS, grasps)


def _solid(name, mesh, density=1.0):
    """A convex part, its own collision piece."""
    return Part(name, mesh, [mesh], density=density)


def _box_battery(length, width, height, centre_x=0.0):
    return [_solid("battery", geometry.box([length, width, height], [centre_x, 0, height / 2]), density=2.5)]


def hammer_drill(name):
    """Long and heavy-fronted: a 30 cm housing, a long chuck, the side handle near the front."""
    hb = 0.07
    return _drill(
        name,
        0,
        _box_battery(0.13, 0.09, hb),
        grip=(np.array([-0.04, 0, hb - 0.01]), [0.1, 0, 1], 0.115, 0.019),
        housing=(np.array([-0.09, 0, hb + 0.14]), 0.3, 0.045),
        chuck=(0.09, 0.5),
        side=(0.85, 0.16, 0.018, (0, 1, 0)),
    )


def compact_drill(name):
    """Short and stubby: a 13 cm housing, a short thick grip, a small battery, a short side handle."""
    hb = 0.045
    return _drill(
        name,
        1,
        _box_battery(0.08, 0.065, hb),
        grip=(np.array([-0.02, 0, hb - 0.01]), [0.05, 0, 1], 0.095, 0.021),
        housing=(np.array([-0.06, 0, hb + 0.11]), 0.13, 0.034),
        chuck=(0.04, 0.6),
        side=(0.6, 0.11, 0.016, (0, 1, 0)),
    )


def sloped_handle_drill(name):
    """The side handle slopes down and outwards by 17 degrees."""
    hb = 0.06
    axis = (0, np.cos(0.3), -np.sin(0.3))
    return _drill(
        name,
        2,
        _box_battery(0.11, 0.08, hb),
        grip=(np.array([-0.035, 0, hb - 0.01]), [0.15, 0, 1], 0.11, 0.018),
        housing=(np.array([-0.07, 0, hb + 0.125]), 0.21, 0.038),
        chuck=(0.06, 0.55),
        side=(0.7, 0.14, 0.017, axis),
    )


def corded_drill(name):
    """No battery: the grip, leaning back, ends in a round heel with a cable stub; a bulge behind the motor."""
    grip_bottom = np.array([-0.03, 0, 0.02])
    axis = np.array([0.25, 0, 1.0])
    heel = geometry.frustum([-0.03, 0, 0.0], [-0.03, 0, 0.03], 0.027, 0.022)
    cable = geometry.frustum([-0.05, 0, 0.012], [-0.12, 0, 0.01], 0.008, 0.007)
    housing_rear = np.array([-0.04, 0, 0.17])
    bulge = geometry.frustum(housing_rear - [0.05, 0, 0], housing_rear + [0.01, 0, 0], 0.03, 0.042)
    return _drill(
        name,
        3,
        [_solid("heel", heel, density=2.0)],
        grip=(grip_bottom, axis, 0.12, 0.018),
        housing=(housing_rear, 0.19, 0.04),
        chuck=(0.06, 0.55),
        side=(0.7, 0.14, 0.017, (0, 1, 0)),
        extra=[_solid("cable", cable), _solid("bulge", bulge, density=1.5)],
    )


def centre_grip_drill(name):
    """The grip stands under the middle of a long housing (a T), on a wide battery."""
    hb = 0.06
    return _drill(
        name,
        4,
        _box_battery(0.1, 0.1, hb, centre_x=-0.02),
        grip=(np.array([-0.02, 0, hb - 0.01]), [0.1, 0, 1], 0.11, 0.019),
        housing=(np.array([-0.08, 0, hb + 0.125]), 0.26, 0.038),
        chuck=(0.05, 0.55),
        side=(0.65, 0.14, 0.017, (0, 1, 0)),
    )


def round_pack_drill(name):
    """A big round battery pack (a flat cylinder) under a forward-leaning grip."""
    pack = geometry.frustum([-0.02, 0, 0.0], [-0.02, 0, 0.065], 0.065, 0.06)
    return _drill(
        name,
        5,
        [_solid("battery", pack, density=2.5)],
        grip=(np.array([-0.035, 0, 0.055]), [0.2, 0, 1], 0.11, 0.018),
        housing=(np.array([-0.075, 0, 0.055 + 0.13]), 0.2, 0.037),
        chuck=(0.06, 0.55),
        side=(0.65, 0.13, 0.017, (0, 1, 0)),
    )


def stretched(category: str, index: int) -> ObjectInstance:
    """A generator's shape with its parameters drawn, then stretched past the generator's ranges (seeded by index)."""
    module = catalog.category_module(category)
    rng = np.random.default_rng([TUNING_SEED, list(DESIGNS).index(category), index])
    p = module.sample_parameters(rng)
    grow = lambda low, high: rng.choice([low, high])  # noqa: E731 (either end, past the range)
    if category == "watering_can":
        p["radius"] *= grow(0.75, 1.3)
        p["height"] *= grow(0.7, 1.35)
        p["rear_handle_radius"] *= grow(0.75, 1.5)
        p["rear_handle_height"] = min(max(p["rear_handle_height"], 0.03 + p["rear_handle_radius"]), p["height"] - 0.02)
        p["top_handle_height"] *= grow(0.8, 1.4)
        p["top_handle_offset"] = rng.uniform(-0.45, 0.05) * p["radius"]
        p["spout_length"] *= grow(0.6, 1.4)
    else:
        p["housing_length"] *= grow(0.7, 1.4)
        p["battery_length"] *= grow(0.75, 1.4)
        p["battery_height"] *= grow(0.75, 1.4)
        p["grip_tilt"] += rng.uniform(0.15, 0.3)
        p["side_handle_position"] = rng.uniform(0.4, 1.0)
        p["side_handle_length"] *= grow(0.75, 1.3)
    return module.build(f"stretched_{index}", p)


TUNING_SEED = 36  # the tuning split's stream
TUNING_COUNT = 6  # per category

DESIGNS = {
    "watering_can": (jerrycan, bulb_can, slim_can, squat_can, one_loop_can, bucket_can),
    "drill": (hammer_drill, compact_drill, sloped_handle_drill, corded_drill, centre_grip_drill, round_pack_drill),
}


# What each named part of the designs is for (systems/messages.py's PartRole); a design's one "handle" (the can
# whose one handle runs from the lid round to the back) belongs to both hands: each stretch of it to the hand whose
# grasp is nearer (parts_surface).
ROLE_BY_NAME = {
    "top_handle": PartRole.LEFT_HANDLE,
    "rear_handle": PartRole.RIGHT_HANDLE,
    "spout": PartRole.TOOL,
    "rose": PartRole.TOOL,
    "grip": PartRole.RIGHT_HANDLE,
    "side_handle": PartRole.LEFT_HANDLE,
    "knob": PartRole.LEFT_HANDLE,
    "chuck": PartRole.TOOL,
}
SHARED_HANDLE = "handle"


def parts_surface(instance: ObjectInstance) -> PartSurface:
    """The design's part surface with each sample's role (ROLE_BY_NAME, else the part's own), its one shared
    handle split between the hands by the nearer grasp."""
    grasps = {
        role: instance.grasps[hand].grasp.GetDeterministicValue().translation()
        for hand, role in (("left", PartRole.LEFT_HANDLE), ("right", PartRole.RIGHT_HANDLE))
    }
    pieces = []
    for part in instance.parts:
        if part.name != SHARED_HANDLE:
            pieces.append(replace(part, role=ROLE_BY_NAME.get(part.name, part.role)))
            continue
        centres = part.mesh.triangles_center
        nearer_left = np.linalg.norm(centres - grasps[PartRole.LEFT_HANDLE], axis=1) < np.linalg.norm(
            centres - grasps[PartRole.RIGHT_HANDLE], axis=1
        )
        for role, faces in ((PartRole.LEFT_HANDLE, nearer_left), (PartRole.RIGHT_HANDLE, ~nearer_left)):
            pieces.append(replace(part, mesh=part.mesh.submesh([np.flatnonzero(faces)], append=True), role=role))
    return part_surface(pieces)


def instances(category: str, split: str) -> list[ObjectInstance]:
    """The category's objects of a split, each moved to where `--object-file` puts a mesh (its grasps with it)."""
    if split == "held_out":
        made = [design(f"held_out_{design.__name__}") for design in DESIGNS[category]]
    else:
        made = [stretched(category, i) for i in range(TUNING_COUNT)]
    out = []
    for instance in made:
        mesh = instance.visual_mesh()
        shift = recentred(mesh, catalog.mean_box_centre(category)).bounds[0] - mesh.bounds[0]
        for part in instance.parts:
            part.mesh = part.mesh.copy()
            part.mesh.apply_translation(shift)
            part.role = ROLE_BY_NAME.get(part.name, part.role)  # (the tool frame is the tool parts')
        for grasp in instance.grasps.values():
            grasp.pregrasp = Transform(RigidTransform(shift) @ grasp.pregrasp.GetDeterministicValue())
            grasp.grasp = Transform(RigidTransform(shift) @ grasp.grasp.GetDeterministicValue())
        out.append(instance)
    return out
