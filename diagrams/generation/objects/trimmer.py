"""Hedge trimmers, a family for teaching and judging the user paths (scripts/make_trimmer_models.py writes them as
a user would bring them: plain meshes, one annotated). Not a generated category: the pipeline reaches them only
through add_category.py and --object-file.

Each trimmer lies across the robot (its length along y_O): a flat motor body, a blade reaching out to the
robot's left (+y_O), an arched front handle over the body near the blade and a closed rear handle (a rounded
loop) behind the body, to the robot's right. Unlike a pot it is not half-turn symmetric. The left hand takes the
front arch's top from above and from the blade's side (its bar along x_O), the right hand the rear loop's upper
grip from above and from the robot's side (its bar along y_O). The object frame O has its origin at the centre
of the body's bottom face, z up.
"""

import numpy as np

from diagrams.generation.objects import geometry
from diagrams.generation.objects.instance import ObjectInstance, Part, make_grasp

CATEGORY = "trimmer"
# The hands come down onto the handles tilted this far from vertical (rad): the left one from the blade's side
# (+y_O), the right one from the robot's side (-x_O). Set once, as a user annotating the model would.
APPROACH_TILT = 0.4
CORNER_RADIUS = 0.015  # m: the rear loop's rounded corners


def sample_parameters(rng: np.random.Generator) -> dict[str, float]:
    """Shape parameters of one trimmer (metres, kg)."""
    return {
        "body_depth": rng.uniform(0.045, 0.06),  # half the body's extent along x_O
        "body_half_length": rng.uniform(0.08, 0.11),  # along y_O
        "body_height": rng.uniform(0.085, 0.11),
        "body_squareness": rng.uniform(2.0, 3.5),  # the footprint's superellipse exponent
        "blade_length": rng.uniform(0.14, 0.22),
        "blade_height": rng.uniform(0.02, 0.03),
        "tube_radius": rng.uniform(0.010, 0.013),
        "arch_offset": rng.uniform(0.02, 0.045),  # the front arch's plane, this far in from the body's +y end
        "arch_clearance": rng.uniform(0.045, 0.06),  # the arch's top above the body's
        "grip_length": rng.uniform(0.10, 0.13),  # the rear loop's upper grip
        "grip_drop": rng.uniform(0.01, 0.02),  # the grip's centre line below the body's top
        "loop_bottom": rng.uniform(0.018, 0.025),  # the loop's lower bar's centre line above the table
        "mass": rng.uniform(1.2, 1.8),
    }


def _rear_loop(y0: float, grip_length: float, top: float, bottom: float, samples: int = 12) -> np.ndarray:
    """The rear loop's centre line in O (x_O = 0): from the body's rear wall at y0 out along -y_O at `top`, down,
    and back to the wall at `bottom`, with rounded corners."""
    r = CORNER_RADIUS
    far = y0 - grip_length
    upper = np.column_stack([np.zeros(samples), np.linspace(y0, far + r, samples), np.full(samples, top)])
    corner_top = geometry.arc([0.0, far + r, top - r], r, np.pi / 2, np.pi, "yz", 6)
    down = np.column_stack([np.zeros(samples), np.full(samples, far), np.linspace(top - r, bottom + r, samples)])
    corner_bottom = geometry.arc([0.0, far + r, bottom + r], r, np.pi, 1.5 * np.pi, "yz", 6)
    lower = np.column_stack([np.zeros(samples), np.linspace(far + r, y0, samples), np.full(samples, bottom)])
    # (Each piece after the first without its first point: the one the piece before ended on.)
    return np.vstack([upper, corner_top[1:], down[1:], corner_bottom[1:], lower[1:]])


def build(name: str, p: dict[str, float]) -> ObjectInstance:
    """The trimmer's parts and true grasps from its parameters."""
    depth, half, h, tube = p["body_depth"], p["body_half_length"], p["body_height"], p["tube_radius"]
    n = p["body_squareness"]
    body = geometry.convex_loft(
        [geometry.superellipse_ring([0, 0, z], depth, half, n) for z in (0.0, h - 0.01)]
        + [geometry.superellipse_ring([0, 0, h], depth - 0.01, half - 0.01, n)]
    )
    blade_z = 0.5 * p["blade_height"] + 0.01
    blade = geometry.box(
        [0.022, p["blade_length"] + 0.02, p["blade_height"]], [0, half + 0.5 * p["blade_length"], blade_z]
    )
    parts = [Part("body", body, [body]), Part("blade", blade, [blade], density=3.0)]
    # Front arch over the body, across it (x_O), its feet sunk half a tube into the body's sides.
    arch_y, feet_z, arch_top = half - p["arch_offset"], 0.35 * h, h + p["arch_clearance"]
    angles = np.linspace(0.0, np.pi, 24)
    arch = np.column_stack(
        [
            (depth - 0.5 * tube) * np.cos(angles),
            np.full_like(angles, arch_y),
            feet_z + (arch_top - feet_z) * np.sin(angles),
        ]
    )
    parts.append(Part("front_handle", geometry.tube(arch, tube), geometry.convex_pieces_of_tube(arch, tube, 6)))
    # Rear loop behind the body, starting half a tube inside its rear wall.
    grip_z = h - p["grip_drop"]
    loop = _rear_loop(-half + 0.5 * tube, p["grip_length"], grip_z, p["loop_bottom"])
    parts.append(Part("rear_handle", geometry.tube(loop, tube), geometry.convex_pieces_of_tube(loop, tube, 8)))
    tilt = APPROACH_TILT
    grasps = {
        "left": make_grasp(
            [0.0, arch_y, arch_top], approach=[0.0, -np.sin(tilt), -np.cos(tilt)], handle_axis=[1, 0, 0]
        ),
        "right": make_grasp(
            [0.0, -half - 0.5 * p["grip_length"], grip_z],
            approach=[np.sin(tilt), 0.0, -np.cos(tilt)],
            handle_axis=[0, 1, 0],
        ),
    }
    return ObjectInstance(CATEGORY, name, p, parts, p["mass"], grasps)
