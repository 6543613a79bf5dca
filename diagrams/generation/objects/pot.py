"""Two-handled cooking pots, a family for teaching and judging the user paths (scripts/make_pot_models.py writes them
as a user would bring them: plain meshes, one annotated). Not a generated category: the pipeline reaches them only
through add_category.py and --object-file.

Each pot: a lidded body (cylinder or slightly tapered), a knob on the lid, and two loop handles on the
wall rising above the rim, leaning outwards, one at +y and one at -y. The object frame O has its origin at
the centre of the bottom face, z up; the pots are half-turn symmetric about z. The left hand takes the
+y handle's apex from above and outside, the right hand the -y one.
"""

import numpy as np

from diagrams.generation.objects import geometry
from diagrams.generation.objects.instance import ObjectInstance, Part, make_grasp

CATEGORY = "pot"
# The hands come down onto the handles tilted this far outwards from vertical (rad): the can's tilt leaves a hand
# out of reach with the pot turned (docs/history/categories.md).
APPROACH_TILT = 0.3


def sample_parameters(rng: np.random.Generator) -> dict[str, float]:
    """Shape parameters of one pot (metres, radians, kg)."""
    return {
        "radius": rng.uniform(0.10, 0.13),
        "height": rng.uniform(0.11, 0.17),
        "taper": rng.uniform(0.85, 1.0),  # bottom radius / top radius
        "knob_radius": rng.uniform(0.012, 0.02),
        "knob_height": rng.uniform(0.015, 0.03),
        "tube_radius": rng.uniform(0.009, 0.012),
        "handle_half_span": rng.uniform(0.045, 0.06),
        "handle_drop": rng.uniform(0.02, 0.035),  # how far below the rim the handle's feet are
        "handle_height": rng.uniform(0.065, 0.085),
        "handle_lean": rng.uniform(0.15, 0.4),
        "mass": rng.uniform(0.8, 1.3),
    }


def build(name: str, p: dict[str, float]) -> ObjectInstance:
    """The pot's parts and true grasps from its parameters."""
    r, h, tube = p["radius"], p["height"], p["tube_radius"]
    body = geometry.convex_loft(
        [geometry.ellipse_ring([0, 0, 0], r * p["taper"], r * p["taper"]), geometry.ellipse_ring([0, 0, h], r, r)]
    )
    knob = geometry.frustum([0, 0, h - 0.005], [0, 0, h + p["knob_height"]], 0.6 * p["knob_radius"], p["knob_radius"])
    parts = [Part("body", body, [body]), Part("knob", knob, [knob])]
    a, lean = p["handle_half_span"], p["handle_lean"]
    feet_z = h - p["handle_drop"]
    # The feet sit on the wall (the body's radius at their height), half sunk into it.
    wall_radius = r * (p["taper"] + (1.0 - p["taper"]) * feet_z / h)
    feet_y = np.sqrt(wall_radius**2 - a**2) - 0.5 * tube
    grasps = {}
    for side, sign in (("left", 1.0), ("right", -1.0)):
        up = np.array([0.0, sign * np.sin(lean), np.cos(lean)])
        centre = np.array([0.0, sign * feet_y, feet_z])
        angles = np.linspace(0.0, np.pi, 24)
        along, rise = a * np.cos(angles), p["handle_height"] * np.sin(angles)
        path = centre + np.outer(along, [1.0, 0.0, 0.0]) + np.outer(rise, up)
        parts.append(Part(f"{side}_handle", geometry.tube(path, tube), geometry.convex_pieces_of_tube(path, tube, 6)))
        apex = centre + p["handle_height"] * up
        grasps[side] = make_grasp(
            apex, approach=[0.0, -sign * np.sin(APPROACH_TILT), -np.cos(APPROACH_TILT)], handle_axis=[sign, 0.0, 0.0]
        )
    return ObjectInstance(CATEGORY, name, p, parts, p["mass"], grasps)
