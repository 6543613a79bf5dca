"""The held-out shop cans: six hand-made designs of the handles real cans have, never drawn by a generator.

Each is built in the category's frame O (watering_can.py: origin at the centre of the bottom face, z up, x towards
the spout) with its true grasps by the category's convention (instance.handle_grasp): the left hand on the top of
the top handle, along it, from above; the right hand on the middle of the rear grip, along it, from behind.
Their proportions and details are their own: a bail handle whose sides stand outside the body, a bar on thin
posts, a loop that curves all the way, a moulded bar, a grip leaning forward on a cone.
"""

import numpy as np
import trimesh

from diagrams.generation.objects import geometry
from diagrams.generation.objects import watering_can as can
from diagrams.generation.objects.instance import ObjectInstance, Part, handle_grasp, tube_part
from systems.perception.parts import PartRole

LEFT, RIGHT, TOOL = PartRole.LEFT_HANDLE, PartRole.RIGHT_HANDLE, PartRole.TOOL
X, Y, Z = np.eye(3)


def _grasps(left_point, left_axis, right_point, right_axis) -> dict:
    tilt, turn, dip = can.LEFT_APPROACH_TILT, can.RIGHT_APPROACH_TURN, can.RIGHT_APPROACH_DIP
    return {
        "left": handle_grasp(left_point, left_axis, approach=[0.0, -np.sin(tilt), -np.cos(tilt)]),
        "right": handle_grasp(right_point, right_axis, approach=[np.cos(turn), np.sin(turn), -dip]),
    }


def _revolved(profile, ratio: float = 1.0, exponent: float = 2.0) -> trimesh.Trimesh:
    """A convex body from (z, x radius) pairs: a superellipse of y/x = ratio at each height."""
    return geometry.convex_loft(
        [geometry.superellipse_ring([0.0, 0.0, z], r, r * ratio, exponent, sections=64) for z, r in profile]
    )


def _solid(name: str, mesh: trimesh.Trimesh, role: PartRole = PartRole.BODY) -> Part:
    return Part(name, mesh, [mesh], role=role)


def _spout(base, angle: float, length: float, radius: float, rose: float | None) -> list[Part]:
    """A straight spout from `base` (inside the front wall) up at `angle` (rad), and a rose of `rose` times its tip's
    radius on its end (none: a plain spout)."""
    direction = np.array([np.cos(angle), 0.0, np.sin(angle)])
    end = np.asarray(base, dtype=float) + length * direction
    tip = 0.55 * radius
    parts = [_solid("spout", geometry.frustum(base, end, radius, tip), TOOL)]
    if rose:
        cone = geometry.frustum(end - 0.01 * direction, end + 0.03 * direction, tip, rose * tip)
        parts.append(_solid("rose", cone, TOOL))
    return parts


def metal_garden_can(name: str) -> ObjectInstance:
    """A tall galvanised can: a bail handle across the body, its sides outside the wall, riveted below the rim;
    a long spout from the foot with a wide rose; a tall rear D leaning back."""
    h = 0.26
    body = _revolved([(0.0, 0.104), (0.02, 0.106), (h, 0.094)])
    bail_x, top, rivet = -0.01, h + 0.055, h - 0.03
    side = [[bail_x, -0.082, rivet], [bail_x, -0.112, rivet], [bail_x, -0.112, top]]
    corners = np.array(side + [[x, -y, z] for x, y, z in side[::-1]])
    bail = tube_part("top_handle", geometry.filleted_path(corners, 0.03), 0.0105, LEFT)
    grip_top, grip_low = np.array([-0.168, 0.0, 0.235]), np.array([-0.152, 0.0, 0.075])
    rear_corners = np.array([[-0.085, 0.0, 0.235], grip_top, grip_low, [-0.092, 0.0, 0.075]])
    rear = tube_part("rear_handle", geometry.filleted_path(rear_corners, 0.025), 0.012, RIGHT)
    parts = [_solid("body", body), bail, rear, *_spout([0.08, 0.0, 0.035], 0.6, 0.42, 0.017, 3.8)]
    grasps = _grasps([bail_x, 0.0, top], Y, 0.5 * (grip_top + grip_low), grip_top - grip_low)
    return ObjectInstance("watering_can", name, {"design": 0.0}, parts, 1.0, grasps)


def plastic_can(name: str) -> ObjectInstance:
    """A moulded plastic can: a long box-like body narrow across; its top handle across it, a thick bar on posts
    splaying outwards; a thick rear bar on thin arms; a high shallow spout with a flat rose."""
    h = 0.2
    body = _revolved([(0.0, 0.13), (h, 0.12)], ratio=0.6, exponent=4.0)
    x0, top = -0.03, h + 0.075
    top_path = geometry.filleted_path(
        np.array([[x0, -0.045, h - 0.01], [x0, -0.062, top], [x0, 0.062, top], [x0, 0.045, h - 0.01]]), 0.02
    )
    handle = tube_part("top_handle", top_path, 0.016, LEFT)
    wall = -0.125
    bar_low, bar_high = np.array([wall - 0.06, 0.0, 0.045]), np.array([wall - 0.06, 0.0, 0.175])
    arms = [
        _solid(f"rear_arm_{i}", geometry.frustum([wall + 0.012, 0.0, z], [wall - 0.06, 0.0, z], 0.009, 0.009), RIGHT)
        for i, z in enumerate((0.06, 0.16))
    ]
    bar = _solid("rear_bar", geometry.frustum(bar_low, bar_high, 0.016, 0.016), RIGHT)
    parts = [_solid("body", body), handle, bar, *arms, *_spout([0.1, 0.0, 0.17], 0.35, 0.2, 0.021, 2.2)]
    grasps = _grasps([x0, 0.0, top], Y, [wall - 0.06, 0.0, 0.11], Z)
    return ObjectInstance("watering_can", name, {"design": 1.0}, parts, 0.8, grasps)


def bar_handle_can(name: str) -> ObjectInstance:
    """A barrel-bellied can with a straight bar along it on two thin posts (the bar overhanging them); a round
    rear loop low on the back; a spout from mid height."""
    h = 0.22
    body = _revolved([(0.0, 0.08), (0.06, 0.095), (0.12, 0.1), (0.18, 0.093), (h, 0.08)], ratio=0.85)
    top = h + 0.065
    posts = [
        _solid(f"top_post_{i}", geometry.frustum([x, 0.0, h - 0.01], [x, 0.0, top], 0.007, 0.007), LEFT)
        for i, x in enumerate((-0.05, 0.05))
    ]
    bar = _solid("top_bar", geometry.frustum([-0.068, 0.0, top], [0.068, 0.0, top], 0.012, 0.012), LEFT)
    rear_centre, rear_radius = np.array([-0.076, 0.0, 0.1]), 0.062
    rear_path = geometry.arc(rear_centre, rear_radius, np.pi / 2, 3 * np.pi / 2, samples=40)
    rear = tube_part("rear_handle", rear_path, 0.012, RIGHT)
    parts = [_solid("body", body), bar, *posts, rear, *_spout([0.065, 0.0, 0.09], 0.8, 0.24, 0.018, 2.0)]
    grasps = _grasps([0.0, 0.0, top], X, rear_centre - [rear_radius, 0.0, 0.0], Z)
    return ObjectInstance("watering_can", name, {"design": 2.0}, parts, 0.9, grasps)


def _catmull_rom(points, samples: int = 12) -> np.ndarray:
    """A smooth curve through `points` (n x 3), `samples` per span (the end points repeated as their own guides)."""
    p = np.vstack([points[:1], points, points[-1:]])
    s = np.linspace(0.0, 1.0, samples, endpoint=False)[:, None]
    curve = []
    for a, b, c, d in zip(p[:-3], p[1:-2], p[2:-1], p[3:], strict=True):
        curve.append(0.5 * (2 * b + (c - a) * s + (2 * a - 5 * b + 4 * c - d) * s**2 + (3 * b - a - 3 * c + d) * s**3))
    return np.vstack([*curve, points[-1:]])


def curved_loop_can(name: str) -> ObjectInstance:
    """One handle curving from the front of the lid up, back and down the rear into the wall low: no straight
    stretch. The left hand takes its highest point, the right its rearmost; each hand's part ends half way
    along the handle between them."""
    h = 0.23
    body = _revolved([(0.0, 0.095), (h, 0.085)])
    guide = np.array(
        [[0.045, 0, h - 0.01], [0.045, 0, h + 0.045], [-0.01, 0, h + 0.085], [-0.09, 0, h + 0.08],
         [-0.15, 0, h + 0.02], [-0.165, 0, 0.14], [-0.14, 0, 0.08], [-0.08, 0, 0.065]],
        dtype=float,
    )  # fmt: skip
    path = geometry.resampled(_catmull_rom(guide), 0.004)
    tangents = np.gradient(path, axis=0)
    top, rear = int(np.argmax(path[:, 2])), int(np.argmin(path[:, 0]))
    split = (top + rear) // 2  # evenly resampled: the middle by length
    tube = 0.0125
    parts = [
        _solid("body", body),
        tube_part("loop_top", path[: split + 2], tube, LEFT),
        tube_part("loop_rear", path[split:], tube, RIGHT),
        *_spout([0.07, 0.0, 0.05], 0.7, 0.27, 0.018, 2.0),
    ]
    grasps = _grasps(path[top], -tangents[top], path[rear], -tangents[rear])
    return ObjectInstance("watering_can", name, {"design": 3.0}, parts, 0.85, grasps)


def small_indoor_can(name: str) -> ObjectInstance:
    """A small indoor can, 20 cm long: a tall narrow bail across it, a short rear D, a thin spout from the foot
    with no rose."""
    h, r = 0.12, 0.048
    body = _revolved([(0.0, r), (0.05, r + 0.004), (h, r - 0.004)])
    top = h + 0.07
    corners = [[0.0, -0.036, h - 0.015], [0.0, -0.066, h - 0.015], [0.0, -0.066, top], [0.0, 0.066, top]]
    corners += [[0.0, 0.066, h - 0.015], [0.0, 0.036, h - 0.015]]
    bail = tube_part("top_handle", geometry.filleted_path(np.array(corners), 0.022), 0.009, LEFT)
    grip_top, grip_low = np.array([-r - 0.04, 0.0, 0.112]), np.array([-r - 0.04, 0.0, 0.025])
    rear_corners = np.array([[-r + 0.01, 0.0, grip_top[2]], grip_top, grip_low, [-r + 0.01, 0.0, grip_low[2]]])
    rear = tube_part("rear_handle", geometry.filleted_path(rear_corners, 0.012), 0.0095, RIGHT)
    parts = [_solid("body", body), bail, rear, *_spout([r - 0.015, 0.0, 0.02], 0.78, 0.09, 0.0095, None)]
    grasps = _grasps([0.0, 0.0, top], Y, 0.5 * (grip_top + grip_low), Z)
    return ObjectInstance("watering_can", name, {"design": 4.0}, parts, 0.55, grasps)


def cone_can(name: str) -> ObjectInstance:
    """A cone narrowing upwards; a tall narrow arch along it, set back; a rear grip parallel to the sloping wall
    (leaning forward at its top); a steep spout from the foot."""
    h = 0.24
    body = _revolved([(0.0, 0.118), (h, 0.068)])
    angles = np.linspace(np.pi, 0.0, 40)
    arch_x, arch_z = -0.008, h - 0.01
    top_path = np.column_stack([arch_x + 0.045 * np.cos(angles), 0 * angles, arch_z + 0.115 * np.sin(angles)])
    arch = tube_part("top_handle", top_path, 0.011, LEFT)
    lean = np.arctan2(0.118 - 0.068, h)
    axis = np.array([np.sin(lean), 0.0, np.cos(lean)])

    def wall(z: float) -> float:
        return -(0.118 - (0.118 - 0.068) * z / h)

    grip_low = np.array([wall(0.05) - 0.055, 0.0, 0.05])
    grip_high = grip_low + 0.15 * axis
    rear_corners = [[wall(grip_low[2]) + 0.012, 0.0, grip_low[2]], grip_low, grip_high]
    rear_corners.append([wall(grip_high[2]) + 0.012, 0.0, grip_high[2]])
    rear = tube_part("rear_handle", geometry.filleted_path(np.array(rear_corners), 0.02), 0.012, RIGHT)
    parts = [_solid("body", body), arch, rear, *_spout([0.1, 0.0, 0.03], 1.0, 0.3, 0.019, 2.4)]
    grasps = _grasps([arch_x, 0.0, arch_z + 0.115], X, 0.5 * (grip_low + grip_high), axis)
    return ObjectInstance("watering_can", name, {"design": 5.0}, parts, 0.95, grasps)


DESIGNS = (metal_garden_can, plastic_can, bar_handle_can, curved_loop_can, small_indoor_can, cone_can)
