"""Writes watering cans and drills outside the generators' families as a user would bring them: plain OBJ meshes.

python scripts/make_unfamiliar_objects.py --out held_out                # held_out/<category>/*.obj, never tuned on
python scripts/make_unfamiliar_objects.py --out tuning --split tune     # stretched generator shapes, to tune on
python scripts/evaluate.py --category drill --object-files held_out/drill/*.obj --scenario_text "{object: {mass: 1.6}}"

Two splits, apart on purpose:
- held_out: six designs per category that no generator makes (docs/shape_space.md shows them): a box-bodied
  jerrycan, a bulbous can, a tall slim can with its spout at the foot, a squat can with a wide arch, a can with one
  handle from the lid round to the back, a bucket widening upwards; a long hammer drill, a compact drill with a
  thick grip, a drill whose side handle slopes down, a corded drill (no battery: a heel and a cable), a drill whose
  grip stands under the housing's middle, a drill on a big round battery pack. No parameter of the pipeline is
  chosen on them; they were changed only until the ground-truth pick could reach them.
- tune: the generators' own shapes with their parameters stretched past the generators' ranges (bigger, smaller,
  further out handles), for choosing the registrar's parameters.

The pipeline reaches these objects only through `--object-file` (and the benchmarks' `--object-files`). Each mesh
stands in the category's object frame O (origin at the centre of its bottom face, z up, x along the functional
axis: spout or chuck), already where `--object-file` recentres a mesh, so `<name>.info.yaml` beside it (its true
grasp frames and mass, for judging, never read by the pick) is in the frame the pick uses; `<name>.parts.npz` beside
it holds each face's functional part (face_roles, systems/messages.py's PartRole), for judging part perception.
"""

import argparse
from pathlib import Path

import numpy as np
from pydrake.common.yaml import yaml_dump_typed

from diagrams.generation.objects.instance import export_obj
from diagrams.generation.objects.unfamiliar import DESIGNS, instances, parts_surface
from diagrams.generation.part_labels import face_roles


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, required=True, help="folder to write <category>/*.obj into")
    parser.add_argument("--split", choices=("held_out", "tune"), default="held_out")
    args = parser.parse_args()
    for category in DESIGNS:
        folder = args.out / category
        folder.mkdir(parents=True, exist_ok=True)
        for instance in instances(category, args.split):
            mesh = instance.visual_mesh()
            export_obj(mesh, folder / f"{instance.name}.obj")
            (folder / f"{instance.name}.info.yaml").write_text(yaml_dump_typed(instance.info()))
            roles = face_roles(mesh, parts_surface(instance))
            np.savez_compressed(folder / f"{instance.name}.parts.npz", face_roles=roles)
            print(f"wrote {folder / instance.name}.obj ({instance.mass:.2f} kg)")


if __name__ == "__main__":
    main()
