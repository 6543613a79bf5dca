"""A bowl (a distractor on cluttered tables, a container to pour into) and a plant pot as meshes: surfaces of revolution
with a wall of some thickness."""

from pathlib import Path

import numpy as np
import trimesh

from diagrams.generation.objects.instance import export_obj
from systems.paths import cache_dir

WALL_M = 0.006  # m
SECTIONS = 48


def bowl_mesh(diameter: float, height: float, pot: bool = False) -> trimesh.Trimesh:
    """A bowl (pot: a plant pot, its wall straight and steep) of rim `diameter` and `height` (m), standing on its
    base at z = 0 with its axis along z."""
    rim, base = 0.5 * diameter, (0.38 if pot else 0.3) * diameter
    # The wall's profile (radius, z): outside from the base's edge up to the rim, inside back down.
    s = np.linspace(0.0, 1.0, 8)
    outside = np.column_stack([base + (rim - base) * (s if pot else np.sqrt(s)), height * s])
    inside = np.column_stack([outside[::-1, 0] - WALL_M, np.maximum(outside[::-1, 1], WALL_M)])
    profile = np.vstack([[0.0, 0.0], outside, inside, [0.0, WALL_M]])
    return trimesh.creation.revolve(profile, sections=SECTIONS)


def bowl_file(diameter: float, height: float, pot: bool = False) -> Path:
    """The bowl's (pot: the plant pot's) OBJ in the cache, written on first use (m)."""
    kind = "pot" if pot else "bowl"
    path = cache_dir() / "clutter" / f"{kind}_{diameter * 1000:.0f}x{height * 1000:.0f}mm_v2.obj"
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_suffix(".partial.obj")
        export_obj(bowl_mesh(diameter, height, pot), partial)
        partial.replace(path)
    return path
