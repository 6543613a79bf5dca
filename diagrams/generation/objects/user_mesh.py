"""A user's mesh file as it comes: read in metres with z up, its units and up axis detected or given.

Files from CAD tools, scanners and model shops come in millimetres, centimetres or metres, z up (CAD, ROS) or y up
(glTF, many artists' tools), in one piece or many, watertight or not. The units are read from the model's size
(systems/shape_space/units.likely_units: the unit that makes it an object two hands lift); the up axis from how it
rests: of z and y, the axis whose lowest face holds its centre of mass farther inside (a can stands on its base, a
drill on its battery; on its side either rolls or tips). Right on all 14 generated cans and drills tried, z up and
turned y up (2026-12-03). Either
can be given (ObjectConfig.units / .up, the scripts' --mesh-units / --mesh-up), and what was read is said, so a
wrong guess is seen at once.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import ConvexHull, QhullError

from systems.shape_space.units import (
    MESH_UNITS,
    MESH_UP_AXES,
    UNIT_NAMES,
    check_metres,
    largest_extent,
    likely_units,
    metres_per_unit,
)

# m: the vertices this near a mesh's lowest one along an axis are its base when it stands on that axis's face
BASE_BAND_M = 0.003
# The rotation that turns a y-up mesh z up: y -> z, z -> -y, x kept (the category's functional axis).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@dataclass
class MeshReading:
    """How a mesh file was read."""

    units: str  # m, cm, mm or in
    up: str  # z or y
    units_detected: bool  # read from the size (else given)
    up_detected: bool  # read from how it rests (else given)
    extent: float  # its largest extent in its file's units (after the scale)

    def describe(self, name: str) -> str:
        """One sentence for the log: what was read and how to say otherwise."""
        units = f"{UNIT_NAMES[self.units]} ({'read from its size, ' if self.units_detected else ''}"
        units += f"{self.extent:.4g} units across)"
        up = f"{self.up} up{' (the face it stands on)' if self.up_detected else ''}"
        hint = " (--mesh-units / --mesh-up say otherwise)" if self.units_detected or self.up_detected else ""
        return f"{name}: read in {units}, {up}{hint}"


def read_user_mesh(
    path: Path, units: str = "auto", up: str = "auto", scale: float = 1.0, process: bool = True
) -> tuple[trimesh.Trimesh, MeshReading]:
    """The mesh of an OBJ/PLY/STL/GLB file (all its pieces as one mesh) in metres, z up, and how it was read.

    scale: a factor applied first (ObjectConfig.scale); units: MESH_UNITS; up: MESH_UP_AXES; process: False keeps
    the file's faces in order (for per-face data beside it).

    Raises:
        ValueError: no triangles in the file, an unknown unit or axis, or a size no unit makes an object's.
    """
    if units not in MESH_UNITS or up not in MESH_UP_AXES:
        raise ValueError(f"mesh units {units!r} / up {up!r}: units one of {MESH_UNITS}, up one of {MESH_UP_AXES}")
    try:
        mesh = trimesh.load(path, force="mesh", process=process)
    except Exception as error:  # trimesh raises many kinds for a file it cannot parse
        raise ValueError(f"{path} could not be read as a mesh: {error}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"{path} holds no triangle mesh")
    if not np.all(np.isfinite(mesh.vertices)):
        raise ValueError(f"{path} has vertices that are not finite numbers")
    mesh.apply_scale(scale)
    extent = largest_extent(mesh.vertices)
    try:
        read_units = likely_units(extent) if units == "auto" else units
    except ValueError as error:
        raise ValueError(f"{path} (scaled by {scale:g}) {error}") from None
    mesh.apply_scale(metres_per_unit(read_units))
    check_metres(mesh.vertices, f"{path} (read in {UNIT_NAMES[read_units]}, scaled by {scale:g})")
    read_up = standing_axis(mesh) if up == "auto" else up
    if read_up == "y":
        transform = np.eye(4)
        transform[:3, :3] = Y_UP_TO_Z_UP
        mesh.apply_transform(transform)
    return mesh, MeshReading(read_units, read_up, units == "auto", up == "auto", extent)


def standing_margin(mesh: trimesh.Trimesh, axis: int) -> float:
    """How far inside the outline of the mesh's base (its vertices within BASE_BAND_M of the lowest along `axis`)
    its centre of mass lies, seen along that axis, m; negative outside, -inf where the base is a line or a point.
    The centre of mass is the solid's where the mesh is one, else its surface's."""
    heights = mesh.vertices[:, axis]
    across = [a for a in range(3) if a != axis]
    base = mesh.vertices[heights <= heights.min() + BASE_BAND_M][:, across]
    centre = (mesh.center_mass if mesh.is_volume else mesh.centroid)[across]
    try:
        hull = ConvexHull(base)
    except (QhullError, ValueError):  # fewer than 3 points, or all on a line
        return -np.inf
    return float(-np.max(hull.equations[:, :2] @ centre + hull.equations[:, 2]))


def standing_axis(mesh: trimesh.Trimesh) -> str:
    """The up axis of a mesh read from how it rests: y where its lowest y face holds its centre of mass farther
    inside than its lowest z face does, else z."""
    return "y" if standing_margin(mesh, 1) > standing_margin(mesh, 2) else "z"
