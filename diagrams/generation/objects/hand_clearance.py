"""Whether the robot's hand fits at an instance's grasps: clear of the object and above the table.

The hand is sdf/centauro/hand.sdf's (frame G at the grasp, z_G the approach, fingers closing along y_G): a palm
box 9 x 15 x 4 cm whose front face lies 4.5 cm behind G, and two finger pads 6 x 1.5 x 7 cm reaching 2.5 cm past
G, open to the reaching width (systems/messages.py OPEN_WIDTH) until they close. Checked: the palm at the grasp;
the pads closed on the handle, from the palm to the grasp plane, against everything but the handle itself; the
open hand at the pre-grasp. The fingers' tips may touch the object (the right hand's tips touch many a can's
rear wall, and the ground-truth picks lift those cans), and the pads may touch the grasped handle's own bends
(a can's arch leans into them under the tilted approach).
"""

import itertools

import numpy as np
import trimesh
from pydrake.math import RigidTransform

from diagrams.generation.objects.instance import ObjectInstance
from systems.messages import OPEN_WIDTH
from systems.perception.parts import PartRole

# (centre, size) of the hand's boxes in G, m.
PALM = (np.array([0.0, 0.0, -0.065]), np.array([0.09, 0.15, 0.04]))
FINGER_THICKNESS = 0.015
FINGERS = [
    (np.array([0.0, side * (OPEN_WIDTH / 2 + FINGER_THICKNESS / 2), -0.01]), np.array([0.06, FINGER_THICKNESS, 0.07]))
    for side in (1.0, -1.0)
]
# The closed pads' inner faces this far from the handle's surface (m).
CLOSED_GAP = 0.002
# Sample points per metre along each box's edges.
POINTS_PER_M = 200
# How deep a design's hand may press into the object (its collision pieces) or the table, m: the paper-like
# family's grasps press at most 1 mm.
PENETRATION_TOLERANCE = 0.003


def _box_points(centre: np.ndarray, size: np.ndarray) -> np.ndarray:
    axes = [np.linspace(-s / 2, s / 2, max(int(s * POINTS_PER_M), 2)) for s in size]
    return centre + np.array(list(itertools.product(*axes)))


PALM_POINTS_G = _box_points(*PALM)
HAND_POINTS_G = np.vstack([PALM_POINTS_G, *(_box_points(*finger) for finger in FINGERS)])


def _depth_inside(points: np.ndarray, pieces: list[trimesh.Trimesh]) -> float:
    """The deepest any point lies inside one of the convex pieces, m (0 where none is inside)."""
    deepest = 0.0
    for piece in pieces:
        normals = piece.face_normals
        offsets = np.einsum("ij,ij->i", normals, piece.triangles[:, 0])
        deepest = max(deepest, float(-np.min(np.max(points @ normals.T - offsets, axis=1))))
    return deepest


def _closed_pad_points(handle_radius: float) -> np.ndarray:
    """The pads closed on a handle of `handle_radius` (m), from the palm's front face to the grasp plane, in G."""
    size = np.array([0.06, FINGER_THICKNESS, 0.045])
    offset = handle_radius + CLOSED_GAP + FINGER_THICKNESS / 2
    return np.vstack([_box_points(np.array([0.0, side * offset, -0.0225]), size) for side in (1.0, -1.0)])


def hand_penetration(instance: ObjectInstance, side: str) -> dict[str, float]:
    """How deep (m) `side`'s hand lies in the object or below the table: its palm at the grasp ("grasp"), its pads
    closed on the handle in anything but the handle ("closed"), its palm and open fingers at the pre-grasp
    ("pregrasp")."""
    role = PartRole.LEFT_HANDLE if side == "left" else PartRole.RIGHT_HANDLE
    pieces = [piece for part in instance.parts for piece in part.collision]
    others = [piece for part in instance.parts if part.role != role for piece in part.collision]
    grasp = instance.grasps[side]
    X_OG: RigidTransform = grasp.grasp.GetDeterministicValue()
    handle_radius = max(
        trimesh.proximity.signed_distance(part.mesh, X_OG.translation()[None, :])[0]
        for part in instance.parts
        if part.role == role
    )
    depths = {}
    for kind, X, points_G, against in (
        ("grasp", X_OG, PALM_POINTS_G, pieces),
        ("closed", X_OG, _closed_pad_points(handle_radius), others),
        ("pregrasp", grasp.pregrasp.GetDeterministicValue(), HAND_POINTS_G, pieces),
    ):
        points_O = X.multiply(points_G.T).T
        depths[kind] = max(_depth_inside(points_O, against), float(-np.min(points_O[:, 2])), 0.0)
    return depths


def hands_overlap(instance: ObjectInstance) -> bool:
    """Whether the two hands, open, overlap each other at their grasps or at their pre-grasps."""
    left, right = instance.grasps["left"], instance.grasps["right"]
    for kind in ("grasp", "pregrasp"):
        X_OL = getattr(left, kind).GetDeterministicValue()
        X_OR = getattr(right, kind).GetDeterministicValue()
        for X_AB in (X_OL.inverse() @ X_OR, X_OR.inverse() @ X_OL):
            points_A = X_AB.multiply(HAND_POINTS_G.T).T
            for centre, size in (PALM, *FINGERS):
                if np.any(np.all(np.abs(points_A - centre) <= size / 2, axis=1)):
                    return True
    return False


def hands_fit(instance: ObjectInstance) -> bool:
    """Both hands within PENETRATION_TOLERANCE of clear of the object and the table at their grasps and
    pre-grasps, and clear of each other."""
    pressed = max(max(hand_penetration(instance, side).values()) for side in instance.grasps)
    return pressed <= PENETRATION_TOLERANCE and not hands_overlap(instance)
