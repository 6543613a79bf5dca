"""The command line shared by the scripts that write example user data for add_category.py (make_pot_models.py,
make_trimmer_models.py): a folder of plain meshes of one family, the first training model annotated."""

import argparse
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml
from build_shape_space import pose_entries
from pydrake.common.yaml import yaml_dump_typed

from diagrams.generation.objects.instance import ObjectInstance, export_obj


def main(
    doc: str,
    category: str,
    sample_parameters: Callable[[np.random.Generator], dict[str, float]],
    build: Callable[[str, dict[str, float]], ObjectInstance],
    argv=None,
):
    """Writes <out>/train/<category>_train_<i>.obj with poses.yaml (the first one's control poses: the canonical
    model) and <out>/test/<category>_test_<i>.obj with <name>.info.yaml beside each (its true grasps and mass, for
    judging only). Model i of a split is drawn from the seed [seed, split, i] alone."""
    parser = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, required=True, help="folder to write train/ and test/ into")
    parser.add_argument("--train", type=int, default=8, help="training models (the first one annotated)")
    parser.add_argument("--test", type=int, default=3, help="test models, with their true grasps beside them")
    parser.add_argument("--seed", type=int, default=2018)
    args = parser.parse_args(argv)
    for split, count in (("train", args.train), ("test", args.test)):
        folder = args.out / split
        folder.mkdir(parents=True, exist_ok=True)
        for i in range(count):
            rng = np.random.default_rng([args.seed, ("train", "test").index(split), i])
            instance = build(f"{category}_{split}_{i}", sample_parameters(rng))
            export_obj(instance.visual_mesh(), folder / f"{instance.name}.obj")
            if split == "test":
                (folder / f"{instance.name}.info.yaml").write_text(yaml_dump_typed(instance.info()))
            elif i == 0:
                poses = {"canonical": f"{instance.name}.obj", "poses": pose_entries(instance.info().control_poses())}
                (folder / "poses.yaml").write_text(yaml.safe_dump(poses, sort_keys=False))
            print(f"wrote {folder / instance.name}.obj ({instance.mass:.2f} kg)")
