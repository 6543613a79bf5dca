"""How a user's model file's coordinates become metres with z up: its units read from its size, its up axis from
how it rests, or both as given.

Files from CAD tools, scanners and model shops come in millimetres, centimetres or metres, z up (CAD, ROS) or y up
(glTF, many artists' tools). The units are read from the model's size (units.likely_units: the unit that makes it
an object two hands lift); the up axis from how it rests: of z and y, the axis whose lowest face holds its centre
of mass farther inside (a can stands on its base, a drill on its battery; on its side either rolls or tips). What
was read is said (FileReading.describe), so a wrong guess is seen at once.
"""

from dataclasses import dataclass

import numpy as np
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

# m: the points this near a model's lowest one along an axis are its base when it stands on that axis's face
BASE_BAND_M = 0.003
# The rotation that turns a y-up model z up: y -> z, z -> -y, x kept (the category's functional axis).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@dataclass
class FileReading:
    """How a model file's coordinates were read."""

    units: str  # m, cm, mm or in
    up: str  # z or y
    units_detected: bool  # read from the size (else given)
    up_detected: bool  # read from how it rests (else given)
    extent: float  # its largest extent in its file's units

    def describe(self, name: str) -> str:
        """One sentence for the log: what was read and how to say otherwise."""
        units = f"{UNIT_NAMES[self.units]} ({'read from its size, ' if self.units_detected else ''}"
        units += f"{self.extent:.4g} units across)"
        up = f"{self.up} up{' (the face it stands on)' if self.up_detected else ''}"
        hint = " (--mesh-units / --mesh-up say otherwise)" if self.units_detected or self.up_detected else ""
        return f"{name}: read in {units}, {up}{hint}"

    def rotation(self) -> np.ndarray:
        """R_MF: the file's axes F in the model frame M (metres, z up)."""
        return Y_UP_TO_Z_UP if self.up == "y" else np.eye(3)

    def matrix(self) -> np.ndarray:
        """4x4 taking the file's coordinates to metres with z up (a scale, then the rotation)."""
        matrix = np.eye(4)
        matrix[:3, :3] = metres_per_unit(self.units) * self.rotation()
        return matrix


def read_file_frame(points: np.ndarray, centre: np.ndarray, units: str, up: str, what: str) -> FileReading:
    """How to read a model whose points (N x 3, in its file's coordinates) and centre of mass are given: `units`
    (MESH_UNITS) and `up` (MESH_UP_AXES) as given, or read where "auto".

    Raises:
        ValueError, naming `what`: an unknown unit or axis, or a size no unit makes an object's.
    """
    if units not in MESH_UNITS or up not in MESH_UP_AXES:
        raise ValueError(f"mesh units {units!r} / up {up!r}: units one of {MESH_UNITS}, up one of {MESH_UP_AXES}")
    extent = largest_extent(points)
    try:
        read_units = likely_units(extent) if units == "auto" else units
    except ValueError as error:
        raise ValueError(f"{what} {error}") from None
    scale = metres_per_unit(read_units)
    check_metres(scale * np.asarray(points), f"{what} (read in {UNIT_NAMES[read_units]})")
    read_up = standing_axis(scale * np.asarray(points), scale * np.asarray(centre)) if up == "auto" else up
    return FileReading(read_units, read_up, units == "auto", up == "auto", extent)


def standing_margin(points: np.ndarray, centre: np.ndarray, axis: int) -> float:
    """How far inside the outline of a model's base (its points within BASE_BAND_M of the lowest along `axis`, m)
    its centre of mass lies, seen along that axis, m; negative outside, -inf where the base is a line or a point."""
    heights = points[:, axis]
    across = [a for a in range(3) if a != axis]
    base = points[heights <= heights.min() + BASE_BAND_M][:, across]
    try:
        hull = ConvexHull(base)
    except (QhullError, ValueError):  # fewer than 3 points, or all on a line
        return -np.inf
    return float(-np.max(hull.equations[:, :2] @ np.asarray(centre)[across] + hull.equations[:, 2]))


def standing_axis(points: np.ndarray, centre: np.ndarray) -> str:
    """The up axis of a model (points and centre of mass in metres) read from how it rests: y where its lowest y face
    holds its centre of mass farther inside than its lowest z face does, else z."""
    return "y" if standing_margin(points, centre, 1) > standing_margin(points, centre, 2) else "z"
