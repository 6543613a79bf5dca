"""The held-out shop drills: six hand-made designs of the handles real two-handed drills have, never drawn by a
generator.

Each is built in the category's frame O (drill.py: origin at the centre of the face it rests on, z up, x towards
the chuck, the side handle towards +y) with its true grasps by the category's convention
(instance.handle_grasp): the left hand on the side handle's middle (the top handle's top), along it, from above
and behind; the right hand on the grip's middle, along it, from behind and the right. Their forms and details
are their own: a motor block under a rotary hammer's housing, a bellied side handle on a collar, a box housing
with a carry bar on splayed posts, a side handle swung forward, a steep handle on a compact drill.
"""

import numpy as np
import trimesh

from diagrams.generation.objects import drill, geometry
from diagrams.generation.objects.instance import ObjectInstance, Part, handle_grasp, tube_part
from systems.perception.parts import PartRole

LEFT, RIGHT, TOOL = PartRole.LEFT_HANDLE, PartRole.RIGHT_HANDLE, PartRole.TOOL
MASS = 1.7  # kg


def _solid(name: str, mesh: trimesh.Trimesh, role: PartRole = PartRole.BODY, density: float = 1.0) -> Part:
    return Part(name, mesh, [mesh], density=density, role=role)


def _grasps(left_point, left_axis, right_point, right_axis) -> dict:
    tilt, turn = drill.APPROACH_TILT, drill.RIGHT_APPROACH_YAW
    return {
        "left": handle_grasp(left_point, left_axis, approach=[np.sin(tilt), 0.0, -np.cos(tilt)]),
        "right": handle_grasp(right_point, right_axis, approach=[np.cos(turn), np.sin(turn), 0.0]),
    }


def _housing(rear, length: float, radius: float, chuck_length: float) -> list[Part]:
    """A round housing along +x from `rear` (narrowing to 0.85 of its radius) and its chuck."""
    rear = np.asarray(rear, dtype=float)
    front = rear + [length, 0.0, 0.0]
    chuck = geometry.frustum(front - [0.005, 0.0, 0.0], front + [chuck_length, 0.0, 0.0], 0.55 * radius, 0.33 * radius)
    return [
        _solid("housing", geometry.frustum(rear, front, radius, 0.85 * radius), density=1.5),
        _solid("chuck", chuck, TOOL, density=2.0),
    ]


def _side_handle(start, axis, length: float, radius: float, belly: float = 1.0) -> tuple[list[Part], np.ndarray]:
    """A side handle from `start` (inside the housing) along `axis`, `belly` times thicker at its middle, with a
    flared end; and the middle of its grip."""
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    start = np.asarray(start, dtype=float)
    middle, end = start + 0.5 * length * axis, start + length * axis
    profile = ((start, radius), (middle, belly * radius), (end, radius))
    rings = [geometry.circle_ring(centre, axis, r, 24) for centre, r in profile]
    parts = [
        _solid("side_handle", geometry.convex_loft(rings), LEFT),
        _solid("knob", geometry.frustum(end - 0.004 * axis, end + 0.014 * axis, 1.45 * radius, 1.15 * radius), LEFT),
    ]
    return parts, middle


def _pistol_grip(bottom, axis, length: float, radius: float, underside: float) -> tuple[Part, np.ndarray]:
    """A grip from `bottom` (1 cm into what it stands on) along `axis` into the housing, whose underside lies at
    height `underside` (m); and the middle of its bare stretch."""
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    bottom = np.asarray(bottom, dtype=float)
    grip = geometry.frustum(bottom, bottom + length * axis, radius, 0.92 * radius)
    middle = bottom + (0.5 * (bottom[2] + 0.01 + underside) - bottom[2]) / axis[2] * axis
    return _solid("grip", grip, RIGHT), middle


def rotary_hammer(name: str) -> ObjectInstance:
    """A rotary hammer: a long housing over a motor block, a D-shaped rear grip closing onto the block, a long
    battery under both, a side handle straight out from the front collar."""
    z = 0.215
    parts = _housing([-0.07, 0.0, z], 0.27, 0.043, 0.085)
    parts += [
        _solid("motor_block", geometry.box([0.12, 0.075, 0.16], [0.0, 0.0, 0.06 + 0.08]), density=1.5),
        _solid("battery", geometry.box([0.22, 0.09, 0.06], [-0.045, 0.0, 0.03]), density=2.5),
        _solid("collar", geometry.frustum([0.135, 0.0, z], [0.165, 0.0, z], 0.05, 0.05)),
    ]
    grip_top, grip_low = np.array([-0.145, 0.0, z + 0.005]), np.array([-0.155, 0.0, 0.085])
    d_corners = np.array([[-0.055, 0.0, z + 0.005], grip_top, grip_low, [-0.05, 0.0, 0.085]])
    d_path = geometry.filleted_path(d_corners, 0.026)
    parts.append(tube_part("grip", d_path, 0.017, RIGHT))
    side, side_middle = _side_handle([0.15, 0.03, z], [0.0, 1.0, 0.0], 0.17, 0.018, belly=1.15)
    parts += side
    grasps = _grasps(side_middle, [0.0, 1.0, 0.0], 0.5 * (grip_top + grip_low), grip_top - grip_low)
    return ObjectInstance("drill", name, {"design": 0.0}, parts, 2.2, grasps)


def angled_side_handle_drill(name: str) -> ObjectInstance:
    """A pistol drill whose bellied side handle hangs 45 degrees from the vertical off a collar; a slim tall
    battery."""
    hb, z = 0.065, 0.21
    parts = _housing([-0.075, 0.0, z], 0.21, 0.038, 0.06)
    parts.append(_solid("battery", geometry.box([0.11, 0.07, hb], [0.0, 0.0, hb / 2]), density=2.5))
    parts.append(_solid("collar", geometry.frustum([0.085, 0.0, z], [0.115, 0.0, z], 0.045, 0.045)))
    grip, grip_middle = _pistol_grip([-0.035, 0.0, hb - 0.01], [0.15, 0.0, 1.0], 0.14, 0.019, z - 0.038)
    axis = np.array([0.0, np.sin(np.radians(45.0)), -np.cos(np.radians(45.0))])
    side, side_middle = _side_handle([0.1, 0.0, z] + 0.04 * axis, axis, 0.14, 0.016, belly=1.3)
    parts += [grip, *side]
    grasps = _grasps(side_middle, axis, grip_middle, [0.15, 0.0, 1.0])
    return ObjectInstance("drill", name, {"design": 1.0}, parts, MASS, grasps)


def carry_bar_drill(name: str) -> ObjectInstance:
    """A box-shaped housing (a rounded square in section) with a carry bar over its front on two posts splaying
    outwards; a pistol grip on a wide battery; no side handle."""
    hb, z = 0.06, 0.2
    rings = [geometry.superellipse_ring([0.0, 0.0, 0.0], 0.045, 0.04, 4.0, 48) for _ in range(2)]
    section = [ring[:, [2, 1, 0]] + [x, 0.0, z] for ring, x in zip(rings, (-0.08, 0.15), strict=True)]
    housing = trimesh.convex.convex_hull(np.vstack(section))
    chuck = geometry.frustum([0.145, 0.0, z], [0.21, 0.0, z], 0.024, 0.015)
    parts = [
        _solid("housing", housing, density=1.5),
        _solid("chuck", chuck, TOOL, density=2.0),
        _solid("battery", geometry.box([0.12, 0.1, hb], [0.0, 0.0, hb / 2]), density=2.5),
    ]
    grip, grip_middle = _pistol_grip([-0.04, 0.0, hb - 0.01], [0.1, 0.0, 1.0], 0.13, 0.018, z - 0.045)
    top = z + 0.045 + 0.05
    bar_ends = np.array([[0.005, 0.0, top], [0.125, 0.0, top]])
    posts = [
        _solid(f"top_post_{i}", geometry.frustum([x + dx, 0.0, z + 0.03], [x, 0.0, top], 0.008, 0.008), LEFT)
        for i, (x, dx) in enumerate(((0.02, 0.018), (0.11, -0.018)))
    ]
    bar = _solid("top_bar", geometry.frustum(bar_ends[0], bar_ends[1], 0.013, 0.013), LEFT)
    parts += [grip, bar, *posts]
    grasps = _grasps(bar_ends.mean(axis=0), [1.0, 0.0, 0.0], grip_middle, [0.1, 0.0, 1.0])
    return ObjectInstance("drill", name, {"design": 2.0}, parts, MASS, grasps)


def corded_swept_handle_drill(name: str) -> ObjectInstance:
    """A corded drill: no battery, the grip ends in a long flat foot with a cable stub; the side handle swept 25
    degrees forward in the horizontal plane."""
    z = 0.19
    parts = _housing([-0.08, 0.0, z], 0.22, 0.04, 0.07)
    parts += [
        _solid("foot", geometry.box([0.16, 0.07, 0.025], [0.0, 0.0, 0.0125]), density=2.0),
        _solid("cable", geometry.frustum([-0.075, 0.0, 0.013], [-0.15, 0.0, 0.012], 0.008, 0.007)),
    ]
    grip, grip_middle = _pistol_grip([-0.045, 0.0, 0.015], [0.2, 0.0, 1.0], 0.15, 0.019, z - 0.04)
    sweep = np.radians(25.0)
    axis = np.array([np.sin(sweep), np.cos(sweep), 0.0])
    side, side_middle = _side_handle([0.065, 0.0, z] + 0.02 * axis, axis, 0.15, 0.017)
    parts += [grip, *side]
    grasps = _grasps(side_middle, axis, grip_middle, [0.2, 0.0, 1.0])
    return ObjectInstance("drill", name, {"design": 3.0}, parts, 1.6, grasps)


def compact_steep_handle_drill(name: str) -> ObjectInstance:
    """A compact drill whose side handle points down 30 degrees from the vertical, out past a narrow battery."""
    hb, z = 0.07, 0.2
    parts = _housing([-0.06, 0.0, z], 0.2, 0.036, 0.05)
    parts.append(_solid("battery", geometry.box([0.11, 0.066, hb], [0.0, 0.0, hb / 2]), density=2.5))
    grip, grip_middle = _pistol_grip([-0.03, 0.0, hb - 0.01], [0.08, 0.0, 1.0], 0.12, 0.018, z - 0.036)
    angle = np.radians(30.0)
    axis = np.array([0.0, np.sin(angle), -np.cos(angle)])
    side, side_middle = _side_handle([0.115, 0.0, z] + 0.03 * axis, axis, 0.125, 0.016)
    parts += [grip, *side]
    grasps = _grasps(side_middle, axis, grip_middle, [0.08, 0.0, 1.0])
    return ObjectInstance("drill", name, {"design": 4.0}, parts, 1.5, grasps)


def d_grip_top_handle_drill(name: str) -> ObjectInstance:
    """A D-shaped rear grip rising from a square battery pack, and an arched handle over the housing's front."""
    z = 0.23
    parts = _housing([-0.06, 0.0, z], 0.24, 0.04, 0.07)
    parts += [
        _solid("battery", geometry.box([0.14, 0.11, 0.07], [-0.02, 0.0, 0.035]), density=2.5),
        _solid("column", geometry.frustum([0.02, 0.0, 0.06], [0.02, 0.0, z], 0.034, 0.03), density=1.5),
    ]
    grip_top, grip_low = np.array([-0.13, 0.0, z]), np.array([-0.118, 0.0, 0.095])
    d_path = geometry.filleted_path(np.array([[-0.05, 0.0, z], grip_top, grip_low, [0.0, 0.0, 0.095]]), 0.022)
    parts.append(tube_part("grip", d_path, 0.016, RIGHT))
    angles = np.linspace(np.pi, 0.0, 40)
    arch_x, foot_z, top = 0.1, z + 0.02, z + 0.04 + 0.045 + 0.012
    arch = np.column_stack([arch_x + 0.06 * np.cos(angles), 0 * angles, foot_z + (top - foot_z) * np.sin(angles)])
    parts.append(tube_part("top_handle", arch, 0.012, LEFT))
    grasps = _grasps([arch_x, 0.0, top], [1.0, 0.0, 0.0], 0.5 * (grip_top + grip_low), grip_top - grip_low)
    return ObjectInstance("drill", name, {"design": 5.0}, parts, 2.0, grasps)


DESIGNS = (
    rotary_hammer,
    angled_side_handle_drill,
    carry_bar_drill,
    corded_swept_handle_drill,
    compact_steep_handle_drill,
    d_grip_top_handle_drill,
)
