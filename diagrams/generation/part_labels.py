"""Part labels of a rendered frame: the functional part (systems/perception/parts.py) each object pixel shows.

Each object pixel with a depth is moved back into the object frame O, and takes the role of the nearest point
of the object's part surfaces. Parts overlap inside the object (a handle's foot in the lid, the spout's root in
the body): a seen point lies on the surface of the part it belongs to, and that surface is the nearest one, so
the nearest surface sample decides.
"""

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from pydrake.math import RigidTransform
from pydrake.systems.sensors import CameraInfo
from scipy import ndimage
from scipy.spatial import cKDTree

from diagrams.generation.objects import catalog
from diagrams.generation.objects.instance import Part
from diagrams.generation.objects.library import recentred
from diagrams.generation.objects.user_mesh import read_user_mesh
from systems.perception.parts import PartRole

# Surface samples per square metre: about one per square millimetre, so the nearest sample of the part a seen
# point lies on is well under a millimetre away.
SAMPLES_PER_M2 = 1.0e6
SAMPLING_SEED = 0


@dataclass(frozen=True)
class PartSurface:
    """Dense samples of an object's surface in O, each with the role of the part it lies on."""

    points_O: np.ndarray  # (n, 3) m
    roles: np.ndarray  # (n,) uint8 PartRole values
    tree: cKDTree

    def roles_at(self, points_O: np.ndarray) -> np.ndarray:
        """The role (uint8) of the nearest surface sample to each point (m, in O)."""
        _, index = self.tree.query(np.asarray(points_O, dtype=float))
        return self.roles[index]


def _surface(meshes_and_roles: Sequence[tuple[trimesh.Trimesh, int]]) -> PartSurface:
    points, roles = [], []
    for mesh, role in meshes_and_roles:
        count = max(int(mesh.area * SAMPLES_PER_M2), 1)
        samples, _ = trimesh.sample.sample_surface(mesh, count, seed=SAMPLING_SEED)
        # The vertices too: a small part (a rose, a knob) keeps its corners however few samples it draws.
        part_points = np.vstack([samples, mesh.vertices])
        points.append(part_points)
        roles.append(np.full(len(part_points), int(role), dtype=np.uint8))
    points_O = np.vstack(points)
    return PartSurface(points_O, np.concatenate(roles), cKDTree(points_O))


def part_surface(parts: Sequence[Part]) -> PartSurface:
    """The surface of a generated instance's parts (in O), each sample with its part's role."""
    return _surface([(part.mesh, part.role) for part in parts])


def face_role_surface(mesh: trimesh.Trimesh, face_roles: np.ndarray) -> PartSurface:
    """The surface of a mesh whose faces carry roles (a held-out OBJ and its parts sidecar), in the mesh's frame."""
    face_roles = np.asarray(face_roles, dtype=np.uint8)
    if face_roles.shape != (len(mesh.faces),):
        raise ValueError(f"{len(face_roles)} face roles for a mesh of {len(mesh.faces)} faces")
    pieces = []
    for role in np.unique(face_roles):
        piece = mesh.submesh([np.flatnonzero(face_roles == role)], append=True)
        pieces.append((piece, role))
    return _surface(pieces)


def face_roles(mesh: trimesh.Trimesh, surface: PartSurface) -> np.ndarray:
    """The role (uint8) of each face of `mesh` (in O; e.g. the parts' union): that of its centroid's nearest
    part surface sample. The union's faces are cut where parts meet, so each lies on one part's surface."""
    return surface.roles_at(mesh.triangles_center)


def object_points_C(depth: np.ndarray, mask: np.ndarray, camera_info: CameraInfo) -> tuple[np.ndarray, np.ndarray]:
    """The masked pixels with a finite, positive depth, and their points in the camera frame C (m).

    Returns:
        (rows, cols) index arrays of the pixels (2, n), and their points (n, 3) in C (z forward, x right, y down).
    """
    valid = mask & np.isfinite(depth) & (depth > 0)
    rows, cols = np.nonzero(valid)
    z = depth[rows, cols].astype(float)
    x = (cols - camera_info.center_x()) * z / camera_info.focal_x()
    y = (rows - camera_info.center_y()) * z / camera_info.focal_y()
    return np.stack([rows, cols]), np.column_stack([x, y, z])


def part_image(
    surface: PartSurface,
    X_WO: RigidTransform,
    depth: np.ndarray,
    mask: np.ndarray,
    camera_info: CameraInfo,
    X_WC: RigidTransform,
) -> np.ndarray:
    """The role of every pixel of a rendered frame (H x W uint8 PartRole values; NONE off the object).

    Args:
        surface: the object's part surface in O (part_surface or face_role_surface).
        X_WO: the object's true pose.
        depth: H x W depth image (m; inf or 0 where nothing was measured).
        mask: H x W bool, the object's pixels in the label image (aligned with the depth image).
        camera_info: the depth camera's intrinsics.
        X_WC: the depth camera's pose.

    An object pixel without a depth takes the role of the nearest object pixel with one.
    """
    mask = np.asarray(mask, dtype=bool)
    depth = np.asarray(depth, dtype=float).reshape(mask.shape)
    image = np.zeros(mask.shape, np.uint8)
    (rows, cols), p_C = object_points_C(depth, mask, camera_info)
    if len(p_C) == 0:
        return image
    p_O = (X_WO.inverse() @ X_WC).multiply(p_C.T).T
    image[rows, cols] = surface.roles_at(p_O)
    missing = mask & (image == PartRole.NONE)
    if missing.any():
        _, (near_rows, near_cols) = ndimage.distance_transform_edt(image == PartRole.NONE, return_indices=True)
        image[missing] = image[near_rows[missing], near_cols[missing]]
    return image


# m: a grasp frame's origin (on its handle's axis) this near its hand's true handle surface lies on that handle
ON_HANDLE_M = 0.025


def true_part_surface(object_config) -> PartSurface | None:
    """The true part surface of a scenario's object (its ObjectConfig) in O, for judging: a generated instance's
    parts, or a user's mesh with `<name>.parts.npz` beside it (its face roles; the mesh moved as --object-file
    moves it); None where the parts are not known."""
    if not object_config.file:
        return part_surface(catalog.generate(object_config.category, object_config.instance).parts)
    path = Path(object_config.file).expanduser()
    roles_file = path.with_suffix(".parts.npz")
    if path.suffix.lower() != ".obj" or not roles_file.is_file():
        return None
    mesh, _ = read_user_mesh(path, object_config.units, object_config.up, object_config.scale, process=False)
    mesh.apply_translation(recentred(mesh, catalog.mean_box_centre(object_config.category)).bounds[0] - mesh.bounds[0])
    with np.load(roles_file) as data:
        return face_role_surface(mesh, data["face_roles"])


def on_handles(surface: PartSurface, grasps_O: dict[str, np.ndarray]) -> dict[str, bool]:
    """Whether each hand's grasp origin (in O, m) lies on its own handle (within ON_HANDLE_M of its part's surface):
    {"left": ..., "right": ...}."""
    roles = {"left": PartRole.LEFT_HANDLE, "right": PartRole.RIGHT_HANDLE}
    on = {}
    for hand, role in roles.items():
        handle = surface.points_O[surface.roles == role]
        distance = np.min(np.linalg.norm(handle - grasps_O[hand], axis=1)) if len(handle) else np.inf
        on[hand] = bool(distance <= ON_HANDLE_M)
    return on
