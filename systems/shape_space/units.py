"""Checks that a model's or a cloud's coordinates are in metres, as every stage expects.

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


def largest_extent(points: np.ndarray) -> float:
    """The largest side (in the points' units) of the axis-aligned box around the finite points."""
    finite = np.asarray(points, float)
    finite = finite[np.all(np.isfinite(finite), axis=1)]
    if len(finite) == 0:
        raise ValueError("no finite points")
    return float(np.ptp(finite, axis=0).max())


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
