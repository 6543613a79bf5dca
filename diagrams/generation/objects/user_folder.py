"""A folder of example user data for add_category.py (scripts/make_pot_models.py, make_trimmer_models.py): plain
meshes of one family, the first training model annotated."""

from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml
from pydrake.common.yaml import yaml_dump_typed

from diagrams.generation.objects.instance import ObjectInstance, export_obj
from systems.shape_space.folder import pose_entries


def write_folder(
    out: Path,
    category: str,
    sample_parameters: Callable[[np.random.Generator], dict[str, float]],
    build: Callable[[str, dict[str, float]], ObjectInstance],
    train: int = 8,
    test: int = 3,
    seed: int = 2018,
):
    """Writes <out>/train/<category>_train_<i>.obj with poses.yaml (the first one's control poses: the canonical
    model) and <out>/test/<category>_test_<i>.obj with <name>.info.yaml beside each (its true grasps and mass, for
    judging only). Model i of a split is drawn from the seed [seed, split, i] alone."""
    for split, count in (("train", train), ("test", test)):
        folder = out / split
        folder.mkdir(parents=True, exist_ok=True)
        for i in range(count):
            rng = np.random.default_rng([seed, ("train", "test").index(split), i])
            instance = build(f"{category}_{split}_{i}", sample_parameters(rng))
            export_obj(instance.visual_mesh(), folder / f"{instance.name}.obj")
            if split == "test":
                (folder / f"{instance.name}.info.yaml").write_text(yaml_dump_typed(instance.info()))
            elif i == 0:
                poses = {"canonical": f"{instance.name}.obj", "poses": pose_entries(instance.info().control_poses())}
                (folder / "poses.yaml").write_text(yaml.safe_dump(poses, sort_keys=False))
            print(f"wrote {folder / instance.name}.obj ({instance.mass:.2f} kg)")
