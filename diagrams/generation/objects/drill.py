"""Procedural two-handed drills: battery, pistol grip, motor housing, chuck, side handle.

Object frame O: origin at the centre of the battery's bottom face, z up, x towards
the chuck, the side handle along +y. The right hand grasps the pistol grip from
behind and to the right (approach in the x_O-y_O plane); the left hand grasps the
side handle from above.
"""

import numpy as np

from diagrams.generation.objects import geometry
from diagrams.generation.objects.instance import ObjectInstance, Part, make_grasp
from systems.perception.parts import PartRole

CATEGORY = "drill"
# Yaw of O in the world at the "0 rad" presentation: chuck away from the robot.
PRESENTATION_YAW = 0.0
# The left hand reaches over the side handle from the robot's side (-x_O), tilted
# this far from vertical (rad).
APPROACH_TILT = 0.6
# The right hand comes at the pistol grip from behind, turned this far towards the
# robot's right (rad about z_O): straight from behind, the right arm cannot reach.
RIGHT_APPROACH_YAW = 0.5


def sample_parameters(rng: np.random.Generator) -> dict[str, float]:
    """Draws the shape parameters of one drill (metres, radians, kg)."""
    return {
        "battery_length": rng.uniform(0.1, 0.13),
        "battery_width": rng.uniform(0.07, 0.09),
        "battery_height": rng.uniform(0.05, 0.07),
        "grip_length": rng.uniform(0.1, 0.13),
        "grip_radius": rng.uniform(0.016, 0.02),
        "grip_tilt": rng.uniform(0.0, 0.25),
        "housing_radius": rng.uniform(0.032, 0.042),
        "housing_length": rng.uniform(0.17, 0.24),
        "chuck_length": rng.uniform(0.04, 0.07),
        "side_handle_length": rng.uniform(0.12, 0.16),
        "side_handle_radius": rng.uniform(0.015, 0.019),
        "side_handle_position": rng.uniform(0.6, 0.8),
        "mass": rng.uniform(1.4, 2.0),
    }


def sample_wide_parameters(rng: np.random.Generator) -> dict[str, float]:
    """Draws a drill of the wider family (the `wide_<seed>` instances): what real two-handed drills vary in
    beyond the paper-like family: compact to hammer-drill housings, slim to thick grips leaning back or forward,
    the grip further back or further under the housing, small to large batteries, side handles anywhere along
    the housing and sloping down. Metres, radians, kg; the keys of `sample_parameters` and three more."""
    return {
        "battery_length": rng.uniform(0.08, 0.15),
        "battery_width": rng.uniform(0.06, 0.1),
        "battery_height": rng.uniform(0.035, 0.08),
        "grip_length": rng.uniform(0.09, 0.15),
        "grip_radius": rng.uniform(0.015, 0.025),
        "grip_tilt": rng.uniform(-0.1, 0.4),
        "housing_radius": rng.uniform(0.028, 0.05),
        "housing_length": rng.uniform(0.14, 0.32),
        "chuck_length": rng.uniform(0.03, 0.1),
        "side_handle_length": rng.uniform(0.1, 0.2),
        "side_handle_radius": rng.uniform(0.014, 0.022),
        "side_handle_position": rng.uniform(0.45, 0.9),
        # How far the housing reaches behind the grip's top (m), where on the battery the grip stands (x, m),
        # and how far the side handle slopes down from horizontal (rad).
        "housing_overhang": rng.uniform(0.02, 0.1),
        "grip_x": rng.uniform(-0.05, 0.0),
        "side_handle_slope": rng.choice([0.0, rng.uniform(0.0, 0.35)]),
        "mass": rng.uniform(1.3, 2.4),
    }


def build(name: str, p: dict[str, float]) -> ObjectInstance:
    """Builds the instance's parts and ground-truth grasps from its parameters."""
    hb, rg, rh = p["battery_height"], p["grip_radius"], p["housing_radius"]
    battery = geometry.box([p["battery_length"], p["battery_width"], hb], [0.0, 0.0, hb / 2])

    # The grip leans forward by grip_tilt from the battery up to the housing.
    grip_bottom = np.array([p.get("grip_x", -0.035), 0.0, hb - 0.01])
    grip_axis = np.array([np.sin(p["grip_tilt"]), 0.0, np.cos(p["grip_tilt"])])
    grip_top = grip_bottom + p["grip_length"] * grip_axis
    grip = geometry.frustum(grip_bottom, grip_top + 0.5 * rh * grip_axis, rg, rg)

    housing_z = grip_top[2] + 0.6 * rh
    housing_rear = np.array([grip_top[0] - p.get("housing_overhang", 0.04), 0.0, housing_z])
    housing_front = housing_rear + [p["housing_length"], 0.0, 0.0]
    housing = geometry.frustum(housing_rear, housing_front, rh, 0.85 * rh)
    chuck_end = housing_front + [p["chuck_length"], 0.0, 0.0]
    chuck = geometry.frustum(housing_front - [0.005, 0, 0], chuck_end, 0.55 * rh, 0.35 * rh)

    side_x = housing_rear[0] + p["side_handle_position"] * p["housing_length"]
    side_start = np.array([side_x, 0.0, housing_z])
    slope = p.get("side_handle_slope", 0.0)
    side_axis = np.array([0.0, np.cos(slope), -np.sin(slope)])
    side_end = side_start + p["side_handle_length"] * side_axis
    side = geometry.frustum(side_start, side_end, p["side_handle_radius"], p["side_handle_radius"])
    knob = geometry.frustum(
        side_end - 0.005 * side_axis,
        side_end + 0.015 * side_axis,
        1.5 * p["side_handle_radius"],
        1.2 * p["side_handle_radius"],
    )

    parts = [
        # Most of a cordless drill's mass sits in its battery and motor.
        Part("battery", battery, [battery], density=2.5),
        Part("grip", grip, [grip], role=PartRole.RIGHT_HANDLE),
        Part("housing", housing, [housing], density=1.5),
        Part("chuck", chuck, [chuck], density=2.0, role=PartRole.TOOL),
        Part("side_handle", side, [side], role=PartRole.LEFT_HANDLE),
        # The knob ends the side handle: the left hand's part.
        Part("knob", knob, [knob], role=PartRole.LEFT_HANDLE),
    ]
    grip_middle = grip_bottom + 0.5 * p["grip_length"] * grip_axis
    side_middle = side_start + 0.5 * (rh + p["side_handle_length"]) * side_axis
    grasps = {
        "left": make_grasp(
            side_middle, approach=[np.sin(APPROACH_TILT), 0, -np.cos(APPROACH_TILT)], handle_axis=side_axis
        ),
        "right": make_grasp(
            grip_middle, approach=[np.cos(RIGHT_APPROACH_YAW), np.sin(RIGHT_APPROACH_YAW), 0], handle_axis=grip_axis
        ),
    }
    return ObjectInstance(CATEGORY, name, p, parts, p["mass"], grasps)
