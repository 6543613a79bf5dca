"""Procedural watering cans: body, spout, top handle and rear handle.

Object frame O: origin at the centre of the bottom face, z up, x towards the spout.
The left hand grasps the top handle from above; the right hand grasps the rear
handle from behind (approach about +x_O).
"""

from dataclasses import dataclass

import numpy as np

from diagrams.generation.objects import geometry
from diagrams.generation.objects.instance import ObjectInstance, Part, make_grasp
from systems.perception.parts import PartRole

CATEGORY = "watering_can"
# Yaw of O in the world at the paper's "0 rad" presentation: spout pointing away from
# the robot, rear handle towards it.
PRESENTATION_YAW = 0.0
BODY_STYLES = ("cylinder", "oval", "tapered")
TUBE_RADIUS_RANGE = (0.011, 0.014)
# The left hand reaches over the top handle from the robot's left (+y_O), tilted this
# far from vertical (rad). The right hand takes the rear handle from behind, right and
# above: its approach is (cos turn, sin turn, -dip) in O, normalised. These directions
# lie well inside the arms' workspace for the paper's yaw range.
LEFT_APPROACH_TILT = 0.6
RIGHT_APPROACH_TURN = 0.6
RIGHT_APPROACH_DIP = 1.0


def sample_parameters(rng: np.random.Generator, body_style: str | None = None) -> dict[str, float]:
    """Draws the shape parameters of one can (metres, radians, kg)."""
    style = body_style or BODY_STYLES[rng.integers(len(BODY_STYLES))]
    radius = rng.uniform(0.075, 0.1)
    height = rng.uniform(0.18, 0.26)
    p = {
        "body_style": float(BODY_STYLES.index(style)),
        "radius": radius,
        "height": height,
        "oval_ratio": rng.uniform(0.65, 0.8) if style == "oval" else 1.0,
        "taper": rng.uniform(0.7, 0.85) if style == "tapered" else 1.0,
        "spout_base": rng.uniform(0.12, 0.3) * height,
        "spout_angle": rng.uniform(0.55, 0.95),
        "spout_length": rng.uniform(0.16, 0.28),
        "spout_radius": rng.uniform(0.015, 0.021),
        "tube_radius": rng.uniform(*TUBE_RADIUS_RANGE),
        "mass": rng.uniform(0.8, 1.1),
    }
    top_radius = radius * p["taper"]
    # The top handle's feet must stand on the lid, leaving a rim of 1.5 cm.
    p["top_handle_offset"] = rng.uniform(-0.25, 0.05) * top_radius
    max_top = top_radius - p["tube_radius"] - 0.015 - abs(p["top_handle_offset"])
    p["top_handle_radius"] = rng.uniform(0.75, 1.0) * min(max_top, 0.085)
    # The arc is an ellipse: tall enough for the fingers whatever the lid's size.
    p["top_handle_height"] = rng.uniform(0.06, 0.085)
    p["rear_handle_radius"] = rng.uniform(0.05, 0.075)
    lo = 0.025 + p["rear_handle_radius"]
    hi = height - 0.015 - p["rear_handle_radius"]
    p["rear_handle_height"] = rng.uniform(lo, max(lo, hi))
    return p


def sample_wide_parameters(rng: np.random.Generator) -> dict[str, float]:
    """Draws a can of the wider family (the `wide_<seed>` instances): what real cans vary in beyond the
    paper-like family: small indoor cans to 10 l garden cans, bodies from round to rounded boxes (plastic cans),
    straight, tapered, flared or bellied, low or high spouts, larger and taller (D-shaped) rear handles, taller
    top arches. Metres, radians, kg; the keys of `sample_parameters` and the profile's own."""
    radius = rng.uniform(0.065, 0.125)
    height = rng.uniform(0.16, 0.34)
    p = {
        "radius": radius,
        "height": height,
        "oval_ratio": rng.uniform(0.55, 1.0),
        "taper": rng.uniform(0.7, 1.25),
        # The body's outline: a superellipse of this exponent at every height (2: an ellipse; 5: a rounded box),
        # and a belly: the radius grows by this share at mid height.
        "squareness": rng.choice([2.0, rng.uniform(2.0, 5.0)]),
        "bulge": rng.choice([0.0, rng.uniform(0.0, 0.3)]),
        "spout_base": rng.uniform(0.05, 0.45) * height,
        "spout_angle": rng.uniform(0.45, 1.0),
        "spout_length": rng.uniform(0.14, 0.34),
        "spout_radius": rng.uniform(0.013, 0.024),
        "tube_radius": rng.uniform(0.01, 0.016),
        "mass": rng.uniform(0.8, 1.2),
    }
    top_radius = radius * min(p["taper"], 1.0)
    p["top_handle_offset"] = rng.uniform(-0.3, 0.1) * top_radius
    max_top = top_radius - p["tube_radius"] - 0.015 - abs(p["top_handle_offset"])
    p["top_handle_radius"] = rng.uniform(0.65, 1.0) * min(max_top, 0.11)
    p["top_handle_height"] = rng.uniform(0.05, 0.11)
    p["rear_handle_radius"] = rng.uniform(0.045, 0.1)
    # A D-shaped rear handle: its half ellipse this many times taller than deep.
    p["rear_handle_stretch"] = rng.choice([1.0, rng.uniform(1.0, 1.8)])
    reach = p["rear_handle_radius"] * p["rear_handle_stretch"]
    lo = 0.025 + reach
    hi = height - 0.015 - reach
    p["rear_handle_height"] = rng.uniform(lo, max(lo, hi))
    return p


def radius_at(p: dict[str, float], z: float) -> float:
    """Body x-radius at height z (linear taper; times the belly, where the can has one)."""
    r = p["radius"] * (1.0 + (p["taper"] - 1.0) * z / p["height"])
    if p.get("bulge", 0.0):
        r *= 1.0 + p["bulge"] * np.sin(np.pi * z / p["height"])
    return r


def body_mesh(p: dict[str, float]):
    """The body: a convex loft of its outline (a superellipse, an ellipse without `squareness`) at its bottom and
    top, and for the wider family's bodies (a belly or a box outline) at 7 heights between."""
    h, ratio, exponent = p["height"], p["oval_ratio"], p.get("squareness", 2.0)
    heights = np.linspace(0.0, h, 9) if p.get("bulge", 0.0) or exponent != 2.0 else (0.0, h)
    return geometry.convex_loft(
        [geometry.superellipse_ring([0, 0, z], radius_at(p, z), radius_at(p, z) * ratio, exponent) for z in heights]
    )


@dataclass
class SpoutAxis:
    """The spout's axis in O, m."""

    start: np.ndarray  # (3,): inside the body's front wall
    direction: np.ndarray  # (3,) unit: up and forward in the xz plane
    end: np.ndarray  # (3,): where the rose begins


def spout_axis(p: dict[str, float]) -> SpoutAxis:
    """The spout's axis of a can with parameters p."""
    start = np.array([radius_at(p, p["spout_base"]) - 0.03, 0.0, p["spout_base"]])
    direction = np.array([np.cos(p["spout_angle"]), 0.0, np.sin(p["spout_angle"])])
    return SpoutAxis(start, direction, start + p["spout_length"] * direction)


def spout_and_rose(p: dict[str, float]):
    """The spout (a frustum narrowing from the body's front wall to its end) and the rose on its end."""
    axis = spout_axis(p)
    start, direction, end = axis.start, axis.direction, axis.end
    tip_radius = 0.6 * p["spout_radius"]
    spout = geometry.frustum(start, end, p["spout_radius"], tip_radius)
    rose = geometry.frustum(end - 0.01 * direction, end + 0.025 * direction, tip_radius, 1.9 * tip_radius)
    return spout, rose


def build(name: str, p: dict[str, float]) -> ObjectInstance:
    """Builds the instance's parts and ground-truth grasps from its parameters."""
    h, tube = p["height"], p["tube_radius"]
    body = body_mesh(p)
    spout, rose = spout_and_rose(p)

    # Top handle: half ellipse in the xz plane standing on the lid.
    top_center = np.array([p["top_handle_offset"], 0.0, h - 0.01])
    angles = np.linspace(0.0, np.pi, 24)
    top_path = top_center + np.column_stack(
        [p["top_handle_radius"] * np.cos(angles), np.zeros_like(angles), p["top_handle_height"] * np.sin(angles)]
    )
    top = geometry.tube(top_path, tube)

    # Rear handle: half circle (or half ellipse, taller than deep) in the xz plane bulging backwards (-x).
    rz, rr = p["rear_handle_height"], p["rear_handle_radius"]
    stretch = p.get("rear_handle_stretch", 1.0)
    rear_x = -min(radius_at(p, rz - stretch * rr), radius_at(p, rz + stretch * rr)) + 0.012
    rear_center = np.array([rear_x, 0.0, rz])
    rear_path = geometry.arc(rear_center, rr, np.pi / 2, 3 * np.pi / 2)
    if stretch != 1.0:
        rear_path[:, 2] = rz + stretch * (rear_path[:, 2] - rz)
    rear = geometry.tube(rear_path, tube)

    parts = [
        Part("body", body, [body]),
        Part("spout", spout, [spout], role=PartRole.TOOL),
        Part("rose", rose, [rose], role=PartRole.TOOL),
        Part("top_handle", top, geometry.convex_pieces_of_tube(top_path, tube, 6), role=PartRole.LEFT_HANDLE),
        Part("rear_handle", rear, geometry.convex_pieces_of_tube(rear_path, tube, 6), role=PartRole.RIGHT_HANDLE),
    ]
    top_apex = top_center + [0.0, 0.0, p["top_handle_height"]]
    rear_apex = rear_center - [rr, 0.0, 0.0]
    grasps = {
        "left": make_grasp(
            top_apex, approach=[0, -np.sin(LEFT_APPROACH_TILT), -np.cos(LEFT_APPROACH_TILT)], handle_axis=[1, 0, 0]
        ),
        "right": make_grasp(
            rear_apex,
            approach=[np.cos(RIGHT_APPROACH_TURN), np.sin(RIGHT_APPROACH_TURN), -RIGHT_APPROACH_DIP],
            handle_axis=[0, 0, 1],
        ),
    }
    return ObjectInstance(CATEGORY, name, p, parts, p["mass"], grasps)
