"""A user's mesh file as it comes: read in metres with z up, its units and up axis detected or given.

Files from CAD tools, scanners and model shops come in millimetres, centimetres or metres, z up or y up, in one
piece or many, watertight or not. systems/shape_space/file_frame.py reads the units from the model's size and the
up axis from how it rests (right on all 14 generated cans and drills tried, z up and turned y up, 2026-12-03).
Either can be given (ObjectConfig.units / .up, the scripts' --mesh-units / --mesh-up), and what was read is said.
"""

from pathlib import Path

import numpy as np
import trimesh

from systems.shape_space.file_frame import FileReading, read_file_frame


def read_user_mesh(
    path: Path, units: str = "auto", up: str = "auto", scale: float = 1.0, process: bool = True
) -> tuple[trimesh.Trimesh, FileReading]:
    """The mesh of an OBJ/PLY/STL/GLB file (all its pieces as one mesh) in metres, z up, and how it was read.

    scale: a factor applied first (ObjectConfig.scale); units: MESH_UNITS; up: MESH_UP_AXES; process: False keeps
    the file's faces in order (for per-face data beside it).

    Raises:
        ValueError: no triangles in the file, an unknown unit or axis, or a size no unit makes an object's.
    """
    try:
        mesh = trimesh.load(path, force="mesh", process=process)
    except Exception as error:  # trimesh raises many kinds for a file it cannot parse
        raise ValueError(f"{path} could not be read as a mesh: {error}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"{path} holds no triangle mesh")
    if not np.all(np.isfinite(mesh.vertices)):
        raise ValueError(f"{path} has vertices that are not finite numbers")
    mesh.apply_scale(scale)
    centre = mesh.center_mass if mesh.is_volume else mesh.centroid
    reading = read_file_frame(mesh.vertices, centre, units, up, f"{path} (scaled by {scale:g})")
    mesh.apply_transform(reading.matrix())
    return mesh, reading
