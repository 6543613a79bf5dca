"""The fixed, seeded instances of each category, and instances on demand.

Every instance's shape comes from `numpy.random.default_rng([CATALOG_SEED, category id,
split id, index])`, so `train_3` is the same can on every machine. `extra_<seed>` instances are drawn
from the same family as train_* and test_*; `wide_<seed>` ones from each generator's wider family
(`sample_wide_parameters`: more of what real products vary in); `shop_<seed>` ones from its shop family
(`<category>_shop.py`: handles in every form and direction real products have them).
"""

import functools
import importlib
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import ConvexHull

from diagrams.generation.objects.hand_clearance import hands_fit
from diagrams.generation.objects.instance import ObjectInstance
from diagrams.paths import SDF_DIR
from systems import categories

CATALOG_SEED = 2018
# Each generated category's generator: the module of its name (the registry, systems/categories.py, lists
# them; taught categories are data). Their order seeds the instances: never reorder GENERATED.
CATEGORIES = {name: importlib.import_module(f"diagrams.generation.objects.{name}") for name in categories.GENERATED}
# Each generated category's shop family: the module `<name>_shop` (sample_shop_parameters, build).
SHOP_FAMILIES = {name: importlib.import_module(f"diagrams.generation.objects.{name}_shop") for name in CATEGORIES}
# The fixed instances: each split and how many it has.
SPLIT_SIZES = {"train": 8, "test": 3}
# On-demand instances, any number of each: the paper-like family, the wider one, the shop one. Never reorder.
ON_DEMAND = ("extra", "wide", "shop")
# The paper's test cans differ clearly from each other: one body style each.
TEST_CAN_STYLES = ("cylinder", "oval", "tapered")


def instance_names(category: str) -> list[str]:
    """The fixed instance names of a category: train_0..train_7, test_0..test_2."""
    category_module(category)
    return [f"{split}_{i}" for split, count in SPLIT_SIZES.items() for i in range(count)]


def category_module(category: str):
    """The generator of a generated category.

    Raises:
        ValueError: a taught category (it has no generated instances: name a model file) or an unknown one.
    """
    if category in CATEGORIES:
        return CATEGORIES[category]
    categories.load_record(category)  # names the known categories if this one is not among them
    raise ValueError(f"{category!r} is a taught category: it has no generated instances; give a model file instead")


def parse_instance_name(name: str) -> tuple[str, int]:
    """Splits 'train_3' into ('train', 3); 'extra_17', 'wide_17' and 'shop_17' name on-demand instances."""
    split, _, index = name.rpartition("_")
    if split not in (*SPLIT_SIZES, *ON_DEMAND) or not index.isdigit():
        raise ValueError(
            f"bad instance name {name!r}: expected train_<i>, test_<i>, extra_<seed>, wide_<seed> or shop_<seed>"
        )
    return split, int(index)


def generate(category: str, name: str) -> ObjectInstance:
    """Generates the named instance (train_i, test_i, or extra_<seed>, wide_<seed> and shop_<seed> for any number
    more)."""
    module = category_module(category)
    split, index = parse_instance_name(name)
    if split in SPLIT_SIZES and index >= SPLIT_SIZES[split]:
        raise ValueError(f"{category} has {SPLIT_SIZES[split]} {split} instances; {name!r} does not exist")
    split_id = (*SPLIT_SIZES, *ON_DEMAND).index(split)
    category_id = list(CATEGORIES).index(category)
    rng = np.random.default_rng([CATALOG_SEED, category_id, split_id, index])
    if split == "wide":
        return _standing_instance(category, name, rng, module.sample_wide_parameters, module.build)
    if split == "shop":
        shop = SHOP_FAMILIES[category]
        return _standing_instance(category, name, rng, shop.sample_shop_parameters, shop.build, hands_fit)
    if category == "watering_can" and split == "test":
        parameters = module.sample_parameters(rng, body_style=TEST_CAN_STYLES[index])
    else:
        parameters = module.sample_parameters(rng)
    return module.build(name, parameters)


# A wide or shop instance's centre of mass lies this far inside its footprint (m), or its shape is drawn again.
STANDING_MARGIN = 0.01


def _standing_instance(category: str, name: str, rng: np.random.Generator, sample, build, accept=None):
    """The first shape `build(name, sample(rng))` that stands on its base (a long, front-heavy drill on a small
    battery would tip over) and that `accept` takes (where given)."""
    for _ in range(100):
        instance = build(name, sample(rng))
        com, _ = instance.mass_properties()
        base = np.vstack([part.mesh.vertices for part in instance.parts])
        hull = ConvexHull(base[base[:, 2] < 1e-6][:, :2])
        if np.max(hull.equations @ [com[0], com[1], 1.0]) <= -STANDING_MARGIN and (accept is None or accept(instance)):
            return instance
    raise RuntimeError(f"no standing {category} found for {name} in 100 draws")


def instance_directory(category: str, name: str) -> Path:
    return SDF_DIR / "objects" / category / name


def presentation_yaw(category: str) -> float:
    """World yaw (rad) of a category's object frame at the paper's 0 rad presentation (a taught one's record)."""
    if category in CATEGORIES:
        return CATEGORIES[category].PRESENTATION_YAW
    return categories.load_record(category).presentation_yaw


def mean_box_centre(category: str) -> np.ndarray:
    """Mean over the training instances of the centre of their bounding box in O (x, y), metres.

    A category prior: where the object frame's origin sits relative to the object's extent.
    """
    if category in CATEGORIES:
        return _generated_box_centre(category)
    return np.array(categories.load_record(category).box_centre, dtype=float)


@functools.cache
def _generated_box_centre(category: str) -> np.ndarray:
    centres = []
    for name in instance_names(category):
        if name.startswith("train"):
            mesh = trimesh.load(instance_directory(category, name) / "visual.obj", force="mesh")
            centres.append(mesh.bounds.mean(axis=0)[:2])
    return np.mean(centres, axis=0)
