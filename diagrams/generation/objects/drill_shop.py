"""The shop family of two-handed drills (`shop_<seed>`): handles in the forms and directions real drills have them.

What the paper-like and wider families never make: for the right hand a D-shaped rear grip (a closed loop behind
the housing, the motor in a column under it, as on rotary hammers) besides the pistol grip; for the left hand a
side handle at any slope from horizontal along y_O down to 70 degrees below it, or a top handle (a bar on two
posts or an arch over the housing's front half); a battery, or none (a corded drill's flat foot).

The grasps follow the category's convention (drill.py) on whatever handle there is, through
instance.handle_grasp: the left hand on the side handle's middle (the top handle's top), x_G along the handle,
from above and behind; the right hand on the grip's middle (the D's straight stretch), along it, from behind
and the right.
"""

from dataclasses import dataclass

import numpy as np

from diagrams.generation.objects import drill, geometry
from diagrams.generation.objects.instance import Handle, ObjectInstance, Part, handle_grasp, tube_part
from systems.perception.parts import PartRole

CATEGORY = drill.CATEGORY
# Codes of the parameters "grip_shape", "left_shape" and "base_shape".
GRIP_SHAPES = ("pistol", "d")
LEFT_SHAPES = ("side", "top_bar", "top_arch")
BASE_SHAPES = ("foot", "battery")
# Shares of the draws.
D_GRIP_SHARE = 0.4
TOP_HANDLE_SHARE = 0.3
BATTERY_SHARE = 0.75
# The steepest side handle: this far below horizontal (rad); the shortest side handle (m).
MAX_SIDE_SLOPE = np.radians(70.0)
MIN_SIDE_HANDLE = 0.1


def sample_shop_parameters(rng: np.random.Generator) -> dict[str, float]:
    """Draws a drill of the shop family (metres, radians, kg; shapes as codes into GRIP_SHAPES, LEFT_SHAPES and
    BASE_SHAPES), again until its handles stand clear of its base and the table."""
    for _ in range(100):
        p = _draw(rng)
        p["side_handle_length"] = min(p["side_handle_length"], _longest_side_handle(p))
        if p["side_handle_length"] >= MIN_SIDE_HANDLE and _handles_fit(p):
            return p
    raise RuntimeError("no shop drill whose handles fit in 100 draws")


def _longest_side_handle(p: dict[str, float]) -> float:
    """The longest side handle (m) whose end stays 3 cm above the table: a steep handle on a low housing is
    shorter."""
    slope = max(p["side_handle_slope"], 1e-6)
    drop = _layout(p).housing_rear[2] - 0.03 - 1.5 * p["side_handle_radius"]
    return drop / np.sin(slope) - p["housing_radius"] - 0.015


def _draw(rng: np.random.Generator) -> dict[str, float]:
    battery = rng.uniform() < BATTERY_SHARE
    top = rng.uniform() < TOP_HANDLE_SHARE
    return {
        "base_shape": float(battery),
        "grip_shape": float(rng.uniform() < D_GRIP_SHARE),
        "left_shape": float(1 + rng.integers(2)) if top else 0.0,
        # A battery, or a corded drill's foot (lighter, lower).
        "base_length": rng.uniform(0.08, 0.15) if battery else rng.uniform(0.09, 0.13),
        "base_width": rng.uniform(0.06, 0.1) if battery else rng.uniform(0.05, 0.07),
        "base_height": rng.uniform(0.035, 0.08) if battery else rng.uniform(0.02, 0.03),
        # The grip (a pistol grip, or the D's straight stretch).
        "grip_length": rng.uniform(0.09, 0.14),
        "grip_radius": rng.uniform(0.015, 0.022),
        "grip_tilt": rng.uniform(-0.1, 0.35),
        "grip_x": rng.uniform(-0.05, 0.0),
        "housing_radius": rng.uniform(0.028, 0.05),
        "housing_length": rng.uniform(0.14, 0.3),
        "housing_overhang": rng.uniform(0.02, 0.1),
        "chuck_length": rng.uniform(0.03, 0.1),
        # A D grip: the motor column under the housing (x of its axis, its radius), the D's bends, its bottom bar
        # above the base and the lengths of its top and bottom bars (m).
        "column_x": rng.uniform(-0.01, 0.03),
        "column_radius": rng.uniform(0.025, 0.04),
        "d_fillet": rng.uniform(0.015, 0.028),
        "d_clearance": rng.uniform(0.015, 0.03),
        "d_top_bar": rng.uniform(0.03, 0.06),
        "d_bottom_bar": rng.uniform(0.03, 0.06),
        "side_handle_length": rng.uniform(0.12, 0.2),
        "side_handle_radius": rng.uniform(0.014, 0.022),
        "side_handle_position": rng.uniform(0.45, 0.9),
        "side_handle_slope": 0.0 if rng.uniform() < 0.1 else rng.uniform(0.0, MAX_SIDE_SLOPE),
        # A top handle: its middle along the housing's front part (0: as far back as it goes, 1: as far forward),
        # half-span, room above the housing, tube radius and (a bar's) corner radius (m).
        "top_handle_position": rng.uniform(0.0, 1.0),
        "top_handle_span": rng.uniform(0.045, 0.07),
        "top_handle_clearance": rng.uniform(0.035, 0.06),
        "top_handle_radius": rng.uniform(0.011, 0.015),
        "top_handle_fillet": rng.uniform(0.015, 0.025),
        "mass": rng.uniform(1.2, 2.4),
    }


@dataclass
class _Layout:
    """Where a drill's housing lies and its grip runs (O, m)."""

    # The centre of the housing's rear end.
    housing_rear: np.ndarray
    # The grip's axis (unit, upwards).
    grip_axis: np.ndarray
    # The grip's centre line: a pistol grip's bottom and top; a D's corners (in the column, the lower bend, the
    # upper bend, in the housing's rear).
    grip_line: np.ndarray


def _layout(p: dict[str, float]) -> _Layout:
    hb, rh = p["base_height"], p["housing_radius"]
    if GRIP_SHAPES[int(p["grip_shape"])] == "pistol":
        bottom = np.array([p["grip_x"], 0.0, hb - 0.01])
        axis = np.array([np.sin(p["grip_tilt"]), 0.0, np.cos(p["grip_tilt"])])
        top = bottom + p["grip_length"] * axis
        housing_rear = np.array([top[0] - p["housing_overhang"], 0.0, top[2] + 0.6 * rh])
        return _Layout(housing_rear, axis, np.array([bottom, top]))
    # The D: its bottom bar from the column back to the lower bend, the grip up (leaning back by grip_tilt at its
    # top) to the upper bend at the housing's axis height, the top bar forward into the housing's rear.
    fillet, tube = p["d_fillet"], 0.85 * p["grip_radius"]
    z_low = hb + p["d_clearance"] + tube
    axis = np.array([-np.sin(p["grip_tilt"]), 0.0, np.cos(p["grip_tilt"])])
    column_back = p["column_x"] - p["column_radius"]
    lower = np.array([column_back - p["d_bottom_bar"], 0.0, z_low])
    upper = lower + (p["grip_length"] + 2 * fillet) / np.cos(p["grip_tilt"]) * axis
    housing_rear = np.array([upper[0] + p["d_top_bar"], 0.0, upper[2]])
    corners = [[column_back + 0.01, 0.0, z_low], lower, upper, housing_rear + [0.015, 0.0, 0.0]]
    return _Layout(housing_rear, axis, np.array(corners, dtype=float))


def _side_handle_axis(p: dict[str, float]) -> np.ndarray:
    slope = p["side_handle_slope"]
    return np.array([0.0, np.cos(slope), -np.sin(slope)])


def _handles_fit(p: dict[str, float]) -> bool:
    rear, rh, length = _layout(p).housing_rear, p["housing_radius"], p["housing_length"]
    hb, half_length, half_width = p["base_height"], p["base_length"] / 2, p["base_width"] / 2
    if GRIP_SHAPES[int(p["grip_shape"])] == "d":
        # The column stands under the housing, in front of its rear end.
        if not rear[0] + 0.02 <= p["column_x"] <= rear[0] + 0.6 * length:
            return False
    if LEFT_SHAPES[int(p["left_shape"])] != "side":
        back, ahead = _top_handle_room(p, rear[0])
        return back <= ahead
    # The side handle (and its knob) above the table, clear of the base.
    radius = p["side_handle_radius"]
    start = rear + [p["side_handle_position"] * length, 0.0, 0.0]
    reach = rh + p["side_handle_length"] + 0.015
    axis_points = start + np.linspace(rh, reach, 12)[:, None] * _side_handle_axis(p)
    margin = 1.5 * radius + 0.005
    in_base = (
        (np.abs(axis_points[:, 0]) < half_length + margin)
        & (np.abs(axis_points[:, 1]) < half_width + margin)
        & (axis_points[:, 2] < hb + margin)
    )
    return bool(np.min(axis_points[:, 2]) >= margin + 0.015 and not in_base.any())


def _top_handle_room(p: dict[str, float], rear_x: float) -> tuple[float, float]:
    """The rearmost and foremost x of a top handle's middle (m): over the housing's front half, its front foot 1 cm
    short of the housing's front end."""
    span, length = p["top_handle_span"], p["housing_length"]
    back = rear_x + 0.5 * length
    ahead = rear_x + length - 0.01 - span - p["top_handle_radius"]
    return back, ahead


def _left_handle(p: dict[str, float], rear: np.ndarray) -> Handle:
    """The left hand's handle: a side handle and its knob, held at the middle; or a top handle, held at its top."""
    rh, length = p["housing_radius"], p["housing_length"]
    if LEFT_SHAPES[int(p["left_shape"])] == "side":
        radius, axis = p["side_handle_radius"], _side_handle_axis(p)
        start = rear + [p["side_handle_position"] * length, 0.0, 0.0]
        end = start + (rh + p["side_handle_length"]) * axis
        side = geometry.frustum(start, end, radius, radius)
        knob = geometry.frustum(end - 0.005 * axis, end + 0.015 * axis, 1.5 * radius, 1.2 * radius)
        parts = [
            Part("side_handle", side, [side], role=PartRole.LEFT_HANDLE),
            Part("knob", knob, [knob], role=PartRole.LEFT_HANDLE),
        ]
        return Handle(parts, start + 0.5 * (rh + p["side_handle_length"]) * axis, axis)
    # A top handle over the housing's front half: its feet half way into the housing, in the xz plane.
    back, ahead = _top_handle_room(p, rear[0])
    centre_x = back + p["top_handle_position"] * (ahead - back)
    span, tube = p["top_handle_span"], p["top_handle_radius"]
    radius_there = rh * (1.0 - 0.15 * (centre_x - rear[0]) / length)  # the housing narrows to 0.85 rh at its front
    foot_z = rear[2] + 0.5 * radius_there
    top_z = rear[2] + radius_there + p["top_handle_clearance"] + tube
    if LEFT_SHAPES[int(p["left_shape"])] == "top_bar":
        corners = [[-span, foot_z], [-span, top_z], [span, top_z], [span, foot_z]]
        path = geometry.filleted_path(np.array([[x + centre_x, 0.0, z] for x, z in corners]), p["top_handle_fillet"])
    else:
        angles = np.linspace(np.pi, 0.0, 48)
        path = np.column_stack(
            [centre_x + span * np.cos(angles), np.zeros_like(angles), foot_z + (top_z - foot_z) * np.sin(angles)]
        )
    part = tube_part("top_handle", path, tube, PartRole.LEFT_HANDLE)
    return Handle([part], np.array([centre_x, 0.0, top_z]), np.array([1.0, 0.0, 0.0]))


def _right_handle(p: dict[str, float], layout: _Layout) -> Handle:
    """The right hand's grip: a pistol grip or a D grip, held at the middle of its straight stretch."""
    axis, rh = layout.grip_axis, p["housing_radius"]
    if GRIP_SHAPES[int(p["grip_shape"])] == "pistol":
        (bottom, top), r = layout.grip_line, p["grip_radius"]
        grip = geometry.frustum(bottom, top + 0.5 * rh * axis, r, r)
        return Handle(
            [Part("grip", grip, [grip], role=PartRole.RIGHT_HANDLE)], bottom + 0.5 * p["grip_length"] * axis, axis
        )
    corners = layout.grip_line
    grip = tube_part(
        "grip", geometry.filleted_path(corners, p["d_fillet"]), 0.85 * p["grip_radius"], PartRole.RIGHT_HANDLE
    )
    return Handle([grip], 0.5 * (corners[1] + corners[2]), axis)  # the middle of the straight stretch


def build(name: str, p: dict[str, float]) -> ObjectInstance:
    """Builds a shop drill's parts and ground-truth grasps from its parameters."""
    hb, rh = p["base_height"], p["housing_radius"]
    layout = _layout(p)
    rear = layout.housing_rear
    front = rear + [p["housing_length"], 0.0, 0.0]
    base = geometry.box([p["base_length"], p["base_width"], hb], [0.0, 0.0, hb / 2])
    housing = geometry.frustum(rear, front, rh, 0.85 * rh)
    chuck = geometry.frustum(front - [0.005, 0, 0], front + [p["chuck_length"], 0.0, 0.0], 0.55 * rh, 0.35 * rh)
    battery = BASE_SHAPES[int(p["base_shape"])] == "battery"
    parts = [
        Part("battery" if battery else "foot", base, [base], density=2.5 if battery else 1.5),
        Part("housing", housing, [housing], density=1.5),
        Part("chuck", chuck, [chuck], density=2.0, role=PartRole.TOOL),
    ]
    if GRIP_SHAPES[int(p["grip_shape"])] == "d":
        # The motor column under the housing, which the D closes onto.
        bottom, top = [p["column_x"], 0.0, hb - 0.01], [p["column_x"], 0.0, rear[2]]
        column = geometry.frustum(bottom, top, p["column_radius"], 0.9 * p["column_radius"])
        parts.append(Part("column", column, [column], density=1.5))
    left, right = _left_handle(p, rear), _right_handle(p, layout)
    parts += right.parts + left.parts
    tilt, turn = drill.APPROACH_TILT, drill.RIGHT_APPROACH_YAW
    grasps = {
        "left": handle_grasp(left.point, left.axis, approach=[np.sin(tilt), 0.0, -np.cos(tilt)]),
        "right": handle_grasp(right.point, right.axis, approach=[np.cos(turn), np.sin(turn), 0.0]),
    }
    return ObjectInstance(CATEGORY, name, p, parts, p["mass"], grasps)
