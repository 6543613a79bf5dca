"""The units of a model's or a cloud's coordinates: checked to be metres, as every stage expects, or read from
the model's size.

An object two hands pick up spans a few centimetres to a metre or so. A file written in
millimetres spans a thousand times that: left unchecked it is accepted and fails later in
ways that do not say why (a registration "fit error" of 153 m).
"""

import numpy as np

MIN_EXTENT_M = 0.01  # smaller than this, in metres, is no object a hand holds
MAX_EXTENT_M = 3.0  # larger than this neither
TYPICAL_EXTENT_M = 0.3  # where several units would do, the likeliest makes the object about this size
# Units a file may have been written in, and what one of them is in metres.
UNIT_SCALES = {"millimetres": 1e-3, "centimetres": 1e-2, "inches": 0.0254}
# The units a mesh file may be given in (--mesh-units): short name, and its name in UNIT_SCALES or metres.
UNIT_NAMES = {"m": "metres", "cm": "centimetres", "mm": "millimetres", "in": "inches"}
# The units read from a model's size. Not inches: an inch is 2.54 cm, closer than objects differ in size (an
# 18 cm can in centimetres is a 46 cm one in inches), so inches are only taken when given.
DETECTED_UNITS = ("m", "cm", "mm")
# What a user may say of a mesh file: its units and its up axis ("auto": read from the mesh).
MESH_UNITS = ("auto", *UNIT_NAMES)
MESH_UP_AXES = ("auto", "z", "y")


def metres_per_unit(unit: str) -> float:
    """One `unit` (a UNIT_NAMES key: m, cm, mm, in) in metres."""
    return 1.0 if unit == "m" else UNIT_SCALES[UNIT_NAMES[unit]]


def largest_extent(points: np.ndarray) -> float:
    """The largest side (in the points' units) of the axis-aligned box around the finite points."""
    finite = np.asarray(points, float)
    finite = finite[np.all(np.isfinite(finite), axis=1)]
    if len(finite) == 0:
        raise ValueError("no finite points")
    return float(np.ptp(finite, axis=0).max())


def likely_units(extent: float) -> str:
    """The unit (a DETECTED_UNITS entry) of coordinates whose largest extent is `extent`: metres where that is an
    object's size in metres (MIN_EXTENT_M to MAX_EXTENT_M), else the one of centimetres and millimetres that makes
    it one, the size nearer TYPICAL_EXTENT_M where both do (below 95 units: centimetres).

    Raises:
        ValueError: no unit makes it an object's size.
    """
    fits = [unit for unit in DETECTED_UNITS if MIN_EXTENT_M <= extent * metres_per_unit(unit) <= MAX_EXTENT_M]
    if "m" in fits:
        return "m"
    if not fits:
        raise ValueError(
            f"spans {extent:.4g} units: in none of {', '.join(UNIT_NAMES[u] for u in DETECTED_UNITS)} is that an "
            f"object two hands lift ({MIN_EXTENT_M:g}-{MAX_EXTENT_M:g} m)"
        )
    return min(fits, key=lambda unit: abs(np.log(extent * metres_per_unit(unit) / TYPICAL_EXTENT_M)))


def check_metres(points: np.ndarray, what: str) -> None:
    """Raises ValueError, naming `what` and the likely unit, unless the points' extent is an object's in metres."""
    extent = largest_extent(points)
    if MIN_EXTENT_M <= extent <= MAX_EXTENT_M:
        return
    fits = [unit for unit, scale in UNIT_SCALES.items() if MIN_EXTENT_M <= extent * scale <= MAX_EXTENT_M]
    fits.sort(key=lambda unit: abs(np.log(extent * UNIT_SCALES[unit] / TYPICAL_EXTENT_M)))
    if extent > MAX_EXTENT_M and fits:
        hint = f"; it looks like {fits[0]}: scale it by {UNIT_SCALES[fits[0]]:g} to metres"
    elif extent < MIN_EXTENT_M:
        hint = "; was it written in a larger unit than metres?"
    else:
        hint = ""
    raise ValueError(
        f"{what} spans {extent:.4g} units, but coordinates must be in metres "
        f"(an object is {MIN_EXTENT_M:g}-{MAX_EXTENT_M:g} m across){hint}"
    )
