"""The held-out shop family: hand-made cans and drills with the handles people's own have, written as a user
brings them (scripts/make_shop_held_out.py). No parameter of the pipeline is chosen on them.

Cans (shop_held_out_cans.py): a metal garden can and a plastic can with their top handles across the body, a
straight bar on posts, one loop curving from the lid to the back, a small indoor can (20 cm long), a cone.
Drills (shop_held_out_drills.py): a rotary hammer's D-shaped rear grip, a side handle 45 degrees from the
vertical, a carry bar on top, a corded drill with its side handle swept forward, a side handle 30 degrees from
the vertical, a D grip with a top arch.

Files per design, standing in the category's frame O where `--object-file` puts a mesh (its bottom face on
z = 0, the centre of its extent where the category's training instances have theirs: library.recentred):
  <name>.obj         the mesh (the union of its parts, watertight), with normals, in metres
  <name>.info.yaml   its true grasps and mass (ObjectInfo): for judging, never read by the pick
  <name>.parts.npz   face_roles: the PartRole of each face of the OBJ (uint8, the file's face order);
                     face_centres: each face's centroid (m, float32), to match faces where a reader reorders them
"""

from pathlib import Path

import numpy as np
from pydrake.common.schema import Transform
from pydrake.common.yaml import yaml_dump_typed
from pydrake.math import RigidTransform

from diagrams.generation.objects import catalog, shop_held_out_cans, shop_held_out_drills
from diagrams.generation.objects.instance import ObjectInstance, export_obj
from diagrams.generation.objects.library import recentred
from diagrams.generation.part_labels import face_roles, part_surface

DESIGNS = {"watering_can": shop_held_out_cans.DESIGNS, "drill": shop_held_out_drills.DESIGNS}
PREFIX = "shop_held_out_"


def instances(category: str) -> list[ObjectInstance]:
    """The category's held-out designs, each moved (parts and grasps) to where `--object-file` puts its mesh."""
    out = []
    for design in DESIGNS[category]:
        instance = design(PREFIX + design.__name__)
        mesh = instance.visual_mesh()
        shift = recentred(mesh, catalog.mean_box_centre(category)).bounds[0] - mesh.bounds[0]
        for part in instance.parts:
            part.mesh = part.mesh.copy()
            part.mesh.apply_translation(shift)
            part.collision = [piece.copy().apply_translation(shift) for piece in part.collision]
        X_shift = RigidTransform(shift)
        for grasp in instance.grasps.values():
            grasp.pregrasp = Transform(X_shift @ grasp.pregrasp.GetDeterministicValue())
            grasp.grasp = Transform(X_shift @ grasp.grasp.GetDeterministicValue())
        out.append(instance)
    return out


def write(category: str, folder: Path) -> list[Path]:
    """Writes the category's held-out designs into `folder` (<name>.obj, .info.yaml, .parts.npz); returns the
    OBJ files."""
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for instance in instances(category):
        mesh = instance.visual_mesh()
        path = folder / f"{instance.name}.obj"
        export_obj(mesh, path)
        path.with_suffix(".info.yaml").write_text(yaml_dump_typed(instance.info()))
        roles = face_roles(mesh, part_surface(instance.parts))
        np.savez_compressed(
            path.with_suffix(".parts.npz"), face_roles=roles, face_centres=mesh.triangles_center.astype(np.float32)
        )
        written.append(path)
    return written
