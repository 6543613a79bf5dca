"""The shop family of watering cans (`shop_<seed>`): handles in the forms and directions real cans have them.

What the paper-like and wider families never make: a top handle across the body (perpendicular to the spout, as
on most metal and many plastic cans) as well as along it, shaped as an arch, a straight bar on two posts or a D
(a flat top on rounded shoulders); a rear handle as an arc, as a D with a straight grip (upright or leaning
back), or none, where one loop handle runs from the lid round to the back; small indoor cans (9-11 cm bodies,
about 20 cm long, with a loop handle: a top handle on so small a lid is too short for the hand) to big garden
cans; round, oval and box-like bodies; spouts high or low.

The grasps follow the category's convention (watering_can.py) on whatever handle there is, through
instance.handle_grasp: the left hand on the top of the top handle (the middle of the loop's top run), x_G along
the handle there, from above; the right hand on the middle of the rear grip, along it, from behind. A loop
handle is two parts: its top stretch the left hand's, its rear stretch the right hand's, split at the bend
between them.
"""

from dataclasses import dataclass

import numpy as np

from diagrams.generation.objects import geometry
from diagrams.generation.objects import watering_can as can
from diagrams.generation.objects.instance import (
    HANDLE_PATH_SPACING,
    Handle,
    ObjectInstance,
    Part,
    handle_grasp,
    tube_part,
)
from systems.perception.parts import PartRole

CATEGORY = can.CATEGORY
# Codes of the parameters "top_shape" and "rear_shape" ("loop": one handle from the lid round to the back is both).
TOP_SHAPES = ("loop", "arch", "bar", "d")
REAR_SHAPES = ("loop", "arc", "d")
BODY_OUTLINES = ("round", "oval", "box")
# Shares of the draws: small indoor cans (all with a loop handle), loop handles on the others, top handles across
# the body.
SMALL_SHARE = 0.2
LOOP_SHARE = 0.2
ACROSS_SHARE = 0.55
# The smallest half-span of a top handle, m: the fingers (6 cm wide) fit on its top.
MIN_TOP_SPAN = 0.045
# How far a top handle's foot (the tube's outside) keeps from the lid's edge, m.
LID_RIM = 0.004
# How deep a handle's end reaches into the lid, and into the wall, m.
LID_FOOT = 0.01
WALL_FOOT = 0.012
# The shortest straight stretch a hand holds (the fingers are 6 cm wide), m.
MIN_GRIP_STRETCH = 0.07


def sample_shop_parameters(rng: np.random.Generator) -> dict[str, float]:
    """Draws a can of the shop family (metres, radians, kg; shapes as codes into TOP_SHAPES, REAR_SHAPES and
    BODY_OUTLINES), again until its handles fit its body."""
    for _ in range(100):
        p = _draw(rng)
        if _handles_fit(p):
            return p
    raise RuntimeError("no shop can whose handles fit its body in 100 draws")


def _draw(rng: np.random.Generator) -> dict[str, float]:
    small = rng.uniform() < SMALL_SHARE
    outline = int(rng.integers(len(BODY_OUTLINES)))
    height = rng.uniform(0.1, 0.15) if small else rng.uniform(0.16, 0.32)
    spout_radius = rng.uniform(0.01, 0.014) if small else rng.uniform(0.013, 0.024)
    p = {
        "small": float(small),
        "body_outline": float(outline),
        "radius": rng.uniform(0.045, 0.055) if small else rng.uniform(0.065, 0.125),
        "height": height,
        "oval_ratio": 1.0 if BODY_OUTLINES[outline] == "round" else rng.uniform(0.6, 0.9),
        "squareness": rng.uniform(3.0, 5.0) if BODY_OUTLINES[outline] == "box" else 2.0,
        "taper": rng.uniform(0.75, 1.15),
        "bulge": rng.uniform(0.0, 0.25) if rng.uniform() < 0.4 else 0.0,
        # The spout's root, low or high, its tube above the table.
        "spout_base": max(rng.uniform(0.05, 0.5) * height, spout_radius + 0.01),
        "spout_angle": rng.uniform(0.45, 1.0),
        "spout_length": rng.uniform(0.05, 0.08) if small else rng.uniform(0.14, 0.34),
        "spout_radius": spout_radius,
        "tube_radius": rng.uniform(0.009, 0.012) if small else rng.uniform(0.01, 0.016),
        "mass": rng.uniform(0.55, 0.75) if small else rng.uniform(0.7, 1.2),
    }
    loop = rng.uniform() < LOOP_SHARE or small
    top_shape = 0 if loop else 1 + int(rng.integers(3))
    p |= {
        "top_shape": float(top_shape),
        "top_across": float(rng.uniform() < ACROSS_SHARE),
        # The top handle's middle along x_O (across) or its centre (along), as a share of the lid's x radius.
        "top_offset": rng.uniform(-0.35, 0.15),
        "top_span": rng.uniform(0.75, 1.0),  # its half-span, as a share of the most the lid allows (up to 11 cm)
        "top_height": rng.uniform(0.055, 0.1),  # its top above its feet, m
        "top_flatness": rng.uniform(3.0, 6.0),  # a D's superellipse exponent
        "top_fillet": rng.uniform(0.015, 0.025),  # a bar's corner radius, m
        "rear_shape": 0.0 if loop else float(1 + rng.integers(2)),
        "rear_radius": rng.uniform(0.045, 0.09),  # an arc's radius, m
        "rear_stretch": rng.uniform(1.0, 1.6) if rng.uniform() < 0.5 else 1.0,  # an arc's height over its depth
        "rear_grip_length": rng.uniform(0.08, 0.13),  # a D's straight grip, m
        "rear_depth": rng.uniform(0.05, 0.08),  # a D's grip behind the wall, m
        "rear_lean": rng.uniform(-0.05, 0.3),  # a D's grip leaning back at its top, rad
        "rear_fillet": rng.uniform(0.018, 0.03),
        "rear_height": rng.uniform(0.3, 0.7),  # the rear grip's middle, as a share of the room on the wall
        "loop_front": rng.uniform(-0.1, 0.5),  # the loop's front post on the lid, as a share of the lid's x radius
        "loop_height": rng.uniform(0.05, 0.09),  # its top run above the lid, m
        "loop_depth": rng.uniform(0.04, 0.05) if small else rng.uniform(0.045, 0.08),  # its rear run behind the body, m
        "loop_low": rng.uniform(0.2, 0.5),  # where it meets the rear wall, as a share of the height
        "loop_fillet": rng.uniform(0.015, 0.025) if small else rng.uniform(0.02, 0.04),
    }
    return p


def lid_half_width_y(p: dict[str, float], x: float) -> float:
    """The lid's half-width along y_O at x (m): its outline is a superellipse."""
    rx = can.radius_at(p, p["height"])
    ry, n = rx * p["oval_ratio"], p.get("squareness", 2.0)
    return ry * max(1.0 - abs(x / rx) ** n, 0.0) ** (1.0 / n)


def top_span_limit(p: dict[str, float]) -> float:
    """The most half-span the top handle may have for its feet to stand on the lid, m."""
    rx = can.radius_at(p, p["height"])
    centre = p["top_offset"] * rx
    if p["top_across"]:
        return lid_half_width_y(p, centre) - p["tube_radius"] - LID_RIM
    return rx - abs(centre) - p["tube_radius"] - LID_RIM


def _wall_x(p: dict[str, float], z_low: float, z_high: float) -> float:
    """The rear wall's x over heights z_low..z_high: the rearmost of it (m, negative)."""
    return -max(can.radius_at(p, z) for z in np.linspace(z_low, z_high, 9))


def _handles_fit(p: dict[str, float]) -> bool:
    h = p["height"]
    if TOP_SHAPES[int(p["top_shape"])] == "loop":
        loop, bend = _loop(p), p["loop_fillet"]
        runs = loop.front[0] - loop.back_top[0] - 2 * bend, loop.back_top[2] - loop.back_low[2] - 2 * bend
        on_lid = loop.front[0] < can.radius_at(p, h) - p["tube_radius"] - LID_RIM
        return min(runs) >= MIN_GRIP_STRETCH and on_lid
    if top_span_limit(p) < MIN_TOP_SPAN:
        return False
    middle, reach = _rear_middle(p)
    if middle - reach < 0.03 or middle + reach > h - 0.015:
        return False
    # The grip stands clear of the wall in front of it (a belly can reach out towards an arc's middle).
    return _rear_grip_x(p) <= -can.radius_at(p, middle) - 0.035


def _rear_middle(p: dict[str, float]) -> tuple[float, float]:
    """The height of the rear grip's middle, and how far the handle reaches above and below it (m)."""
    if REAR_SHAPES[int(p["rear_shape"])] == "arc":
        reach = p["rear_radius"] * p["rear_stretch"]
    else:
        reach = (0.5 * p["rear_grip_length"] + p["rear_fillet"]) * np.cos(p["rear_lean"])
    low, high = 0.03 + reach, p["height"] - 0.015 - reach
    return low + p["rear_height"] * max(high - low, 0.0), reach


def _rear_grip_x(p: dict[str, float]) -> float:
    """The x of the rear grip's middle (m): an arc's rearmost point, a D's straight grip."""
    z, reach = _rear_middle(p)
    if REAR_SHAPES[int(p["rear_shape"])] == "arc":
        return _arc_feet_x(p) - p["rear_radius"]
    return _wall_x(p, z - reach, z + reach) - p["rear_depth"]


def _arc_feet_x(p: dict[str, float]) -> float:
    """The x of an arc's feet and centre (m): within the wall where it is least deep (as the paper-like
    family's)."""
    z, reach = _rear_middle(p)
    return -min(can.radius_at(p, z - reach), can.radius_at(p, z + reach)) + WALL_FOOT


@dataclass
class _Loop:
    """A loop handle's corners (O, m): the top of its front post, its upper and lower rear bends, and its ends in
    the lid and in the rear wall."""

    front: np.ndarray
    back_top: np.ndarray
    back_low: np.ndarray
    foot_front: np.ndarray
    foot_wall: np.ndarray


def _loop(p: dict[str, float]) -> _Loop:
    h, rx = p["height"], can.radius_at(p, p["height"])
    z_top, z_low = h + p["loop_height"], max(p["loop_low"] * h, 0.05)
    back = _wall_x(p, z_low, h) - p["loop_depth"]
    front = np.array([p["loop_front"] * rx, 0.0, z_top])
    return _Loop(
        front=front,
        back_top=np.array([back, 0.0, z_top]),
        back_low=np.array([back, 0.0, z_low]),
        foot_front=front - [0.0, 0.0, front[2] - (h - LID_FOOT)],
        foot_wall=np.array([-can.radius_at(p, z_low) + WALL_FOOT, 0.0, z_low]),
    )


def _top_handle(p: dict[str, float]) -> Handle:
    """The top handle, held at its top along its axis there."""
    h, rx = p["height"], can.radius_at(p, p["height"])
    span = max(p["top_span"] * min(top_span_limit(p), 0.11), MIN_TOP_SPAN)
    height = p["top_height"]
    axis = np.array([0.0, 1.0, 0.0]) if p["top_across"] else np.array([1.0, 0.0, 0.0])
    centre = np.array([p["top_offset"] * rx, 0.0, h - LID_FOOT])
    shape = TOP_SHAPES[int(p["top_shape"])]
    if shape == "bar":
        corners = np.array([[-span, 0.0, 0.0], [-span, 0.0, height], [span, 0.0, height], [span, 0.0, 0.0]])
        outline = geometry.filleted_path(corners, p["top_fillet"])
        s, t = outline[:, 0], outline[:, 2]
    else:
        angles = np.linspace(np.pi, 0.0, 48)
        power = 2.0 / (2.0 if shape == "arch" else p["top_flatness"])
        c, si = np.cos(angles), np.sin(angles)
        s, t = span * np.sign(c) * np.abs(c) ** power, height * np.abs(si) ** power
    path = centre + s[:, None] * axis + t[:, None] * [0.0, 0.0, 1.0]
    part = tube_part("top_handle", path, p["tube_radius"], PartRole.LEFT_HANDLE)
    return Handle([part], centre + [0.0, 0.0, height], axis)


def _rear_handle(p: dict[str, float]) -> Handle:
    """The rear handle, held at the middle of its grip along the grip."""
    z, _ = _rear_middle(p)
    if REAR_SHAPES[int(p["rear_shape"])] == "arc":
        rr, centre = p["rear_radius"], np.array([_arc_feet_x(p), 0.0, z])
        path = geometry.arc(centre, rr, np.pi / 2, 3 * np.pi / 2, samples=48)
        path[:, 2] = z + p["rear_stretch"] * (path[:, 2] - z)
        grip, axis = centre - [rr, 0.0, 0.0], np.array([0.0, 0.0, 1.0])
    else:
        grip = np.array([_rear_grip_x(p), 0.0, z])
        lean = p["rear_lean"]
        axis = np.array([-np.sin(lean), 0.0, np.cos(lean)])
        corner = 0.5 * p["rear_grip_length"] + p["rear_fillet"]
        corner_low, corner_high = grip - corner * axis, grip + corner * axis
        feet = [[-can.radius_at(p, c[2]) + WALL_FOOT, 0.0, c[2]] for c in (corner_low, corner_high)]
        path = geometry.filleted_path(np.array([feet[0], corner_low, corner_high, feet[1]]), p["rear_fillet"])
    return Handle([tube_part("rear_handle", path, p["tube_radius"], PartRole.RIGHT_HANDLE)], grip, axis)


def _loop_handles(p: dict[str, float]) -> tuple[Handle, Handle]:
    """The loop handle as the left hand's (its top stretch, held at the middle of its top run) and the right
    hand's (its rear stretch, held at the middle of its rear run), split at the bend between them."""
    loop = _loop(p)
    corners = np.array([loop.foot_front, loop.front, loop.back_top, loop.back_low, loop.foot_wall])
    path = geometry.resampled(geometry.filleted_path(corners, p["loop_fillet"]), HANDLE_PATH_SPACING)
    # The bend's middle is the point of the path nearest its corner; the stretches share one step of the path.
    split = int(np.argmin(np.linalg.norm(path - loop.back_top, axis=1)))
    tube = p["tube_radius"]
    top = tube_part("loop_top", path[: split + 2], tube, PartRole.LEFT_HANDLE)
    rear = tube_part("loop_rear", path[split:], tube, PartRole.RIGHT_HANDLE)
    return (
        Handle([top], 0.5 * (loop.front + loop.back_top), np.array([1.0, 0.0, 0.0])),
        Handle([rear], 0.5 * (loop.back_top + loop.back_low), np.array([0.0, 0.0, 1.0])),
    )


def build(name: str, p: dict[str, float]) -> ObjectInstance:
    """Builds a shop can's parts and ground-truth grasps from its parameters."""
    body = can.body_mesh(p)
    spout, rose = can.spout_and_rose(p)
    if TOP_SHAPES[int(p["top_shape"])] == "loop":
        left, right = _loop_handles(p)
    else:
        left, right = _top_handle(p), _rear_handle(p)
    parts = [
        Part("body", body, [body]),
        Part("spout", spout, [spout], role=PartRole.TOOL),
        Part("rose", rose, [rose], role=PartRole.TOOL),
        *left.parts,
        *right.parts,
    ]
    tilt, turn, dip = can.LEFT_APPROACH_TILT, can.RIGHT_APPROACH_TURN, can.RIGHT_APPROACH_DIP
    grasps = {
        "left": handle_grasp(left.point, left.axis, approach=[0.0, -np.sin(tilt), -np.cos(tilt)]),
        "right": handle_grasp(right.point, right.axis, approach=[np.cos(turn), np.sin(turn), -dip]),
    }
    return ObjectInstance(CATEGORY, name, p, parts, p["mass"], grasps)
