"""Finds the model file (and, when known, the ground truth) of the object a scenario names.

Generated instances live under sdf/objects/<category>/<instance>/ (model.sdf and
info.yaml); `extra_<seed>`, `wide_<seed>` and `shop_<seed>` instances are generated into a cache on first use. A
user's own model is an SDF/URDF used as is, or a mesh (.obj/.ply/.stl) that is
recentred (origin at the centre of its bottom face), scaled, decomposed into
convex pieces with CoACD and written as an SDF into the cache.
"""

import hashlib
import logging
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from pydrake.common.yaml import yaml_load_typed

from diagrams.generation.objects import catalog
from diagrams.generation.objects.instance import ObjectInfo, export_obj, object_sdf
from diagrams.generation.objects.user_mesh import read_user_mesh
from systems.paths import cache_dir

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".glb", ".gltf")
MODEL_SUFFIXES = (".sdf", ".urdf")
# The cache folder of the on-demand generated instances: renamed whenever what is written of them changes, so that
# an old cache is not read as new (v2: info.yaml holds the tool frame).
GENERATED_CACHE = "objects_v2"
# m: a mesh thinner than this everywhere across (its oriented box's least extent) is a sheet, not a body to simulate
MIN_THICKNESS_M = 0.002


@dataclass
class ObjectModel:
    """A model file the parser can load, and what is known about it."""

    model_file: Path
    # Ground truth (grasp frames, mass): None for a user's model without an info file.
    info: ObjectInfo | None
    # World yaw of the object frame at the category's presentation pose, rad.
    presentation_yaw: float


def load_info(path: Path) -> ObjectInfo:
    try:
        return yaml_load_typed(schema=ObjectInfo, data=path.read_text())
    except Exception as error:
        raise ValueError(f"invalid object info file {path}: {error}") from error


def resolve_object(config) -> ObjectModel:
    """Resolves a scenario's ObjectConfig to a model file.

    Raises:
        ValueError: unknown category or instance name, or unsupported file type.
        FileNotFoundError: the named file does not exist.
    """
    yaw = catalog.presentation_yaw(config.category)
    if config.file:
        return _user_model(Path(config.file), config, yaw)
    directory = generated_instance_directory(config.category, config.instance)
    return ObjectModel(directory / "model.sdf", load_info(directory / "info.yaml"), yaw)


def generated_instance_directory(category: str, name: str) -> Path:
    """The folder of a generated instance; on-demand ones (extra_, wide_, shop_<seed>) are generated into the cache on
    first use.

    Raises:
        ValueError: unknown category or impossible instance name.
        FileNotFoundError: a fixed instance's files are missing from the repository.
    """
    split, _ = catalog.parse_instance_name(name)
    directory = catalog.instance_directory(category, name)
    if (directory / "model.sdf").is_file():
        return directory
    if split not in catalog.ON_DEMAND:
        catalog.generate(category, name)  # raises a clear error for names that cannot exist (e.g. test_9)
        raise FileNotFoundError(f"{directory / 'model.sdf'} is missing; run scripts/generate_objects.py")
    directory = cache_dir() / GENERATED_CACHE / category / name
    if not (directory / "model.sdf").is_file():
        logging.info("generating %s/%s into %s", category, name, directory)
        written_whole(directory, catalog.generate(category, name).write)
    return directory


def written_whole(directory: Path, write) -> None:
    """Fills a cache folder by `write(folder)` in a temporary sibling, then renames it into place: another process
    (parallel evaluation workers making the same instance) never reads it half written. Where one got there first,
    its folder stands; a folder left incomplete (no model.sdf: a run killed while writing) is replaced."""
    directory.parent.mkdir(parents=True, exist_ok=True)
    partial = Path(tempfile.mkdtemp(dir=directory.parent, prefix=f".{directory.name}."))
    try:
        write(partial)
        if directory.is_dir() and not (directory / "model.sdf").is_file():
            shutil.rmtree(directory, ignore_errors=True)
        try:
            partial.rename(directory)
        except OSError:
            if not (directory / "model.sdf").is_file():
                raise
    finally:
        shutil.rmtree(partial, ignore_errors=True)


def _user_model(path: Path, config, yaw: float) -> ObjectModel:
    path = path.expanduser().resolve()
    if not path.is_file():
        raise FileNotFoundError(f"object file not found: {path}")
    suffix = path.suffix.lower()
    info_file = next((p for p in (path.with_suffix(".info.yaml"), path.parent / "info.yaml") if p.is_file()), None)
    info = load_info(info_file) if info_file else None
    if suffix in MODEL_SUFFIXES:
        return ObjectModel(path, info, yaw)
    if suffix not in MESH_SUFFIXES:
        raise ValueError(f"unsupported object file {path.name}: use one of {MODEL_SUFFIXES + MESH_SUFFIXES}")
    sdf = mesh_to_sdf(path, config.mass, config.scale, config.category, config.units, config.up)
    return ObjectModel(sdf, info, yaw)


def mesh_to_sdf(path: Path, mass: float, scale: float, category: str, units: str = "auto", up: str = "auto") -> Path:
    """Converts a mesh into a cached SDF with convex collision pieces; returns the SDF path.

    The mesh is read in metres with z up (user_mesh.read_user_mesh: `units` and `up` detected where "auto", and
    said), and taken as x along the category's functional axis (can: spout). Its frame is moved onto its bottom
    face, with the centre of its extent where the category's training instances have theirs
    (catalog.mean_box_centre): a scenario's object.xy then puts a user's can where it puts a generated one.

    Raises:
        ValueError: the file cannot be read as an object's mesh, or cannot be made convex pieces to simulate.
    """
    box_centre_xy = catalog.mean_box_centre(category)
    key = f"{mass}:{scale}:{category}:{box_centre_xy[0]:.6f}:{box_centre_xy[1]:.6f}:{units}:{up}"
    digest = hashlib.sha256(path.read_bytes() + key.encode()).hexdigest()[:16]
    directory = cache_dir() / "user_objects" / f"{path.stem}_{digest}"
    sdf_path = directory / "model.sdf"
    if sdf_path.is_file():
        return sdf_path
    mesh, reading = read_user_mesh(path, units, up, scale)
    logging.info(reading.describe(path.name))
    thickness = float(mesh.bounding_box_oriented.primitive.extents.min())
    if thickness < MIN_THICKNESS_M:
        raise ValueError(
            f"{path} cannot be simulated: it is {1000 * thickness:.2g} mm thick, a sheet rather than a solid "
            f"(at least {1000 * MIN_THICKNESS_M:g} mm)"
        )
    mesh = recentred(mesh, box_centre_xy)
    pieces = convex_decomposition(mesh)
    com, inertia = mass_properties(mesh, pieces, mass)

    def write(folder: Path):
        export_obj(mesh, folder / "visual.obj")
        for i, piece in enumerate(pieces):
            export_obj(piece, folder / f"collision_{i:02d}.obj")
        sdf = object_sdf(
            model_name=path.stem,
            visual_uri="visual.obj",
            collision_uris=[f"collision_{i:02d}.obj" for i in range(len(pieces))],
            mass=mass,
            com=com,
            inertia=inertia,
            color=(0.6, 0.6, 0.65),
        )
        (folder / "model.sdf").write_text(sdf)

    written_whole(directory, write)
    return sdf_path


def recentred(mesh: trimesh.Trimesh, box_centre_xy) -> trimesh.Trimesh:
    """A copy of the mesh moved onto its bottom face (z = 0), the centre of its extent in x, y at box_centre_xy."""
    lo, hi = mesh.bounds
    moved = mesh.copy()
    moved.apply_translation([box_centre_xy[0] - (lo[0] + hi[0]) / 2, box_centre_xy[1] - (lo[1] + hi[1]) / 2, -lo[2]])
    return moved


def convex_decomposition(mesh: trimesh.Trimesh) -> list[trimesh.Trimesh]:
    """Convex pieces of a (possibly non-convex) mesh, via CoACD.

    CoACD runs in a child process: on some valid meshes its default mode aborts the whole process (coacd 1.0.14:
    "unexpected code path was hit", on 3 of 6 watertight cans of scripts/make_unfamiliar_objects.py). Those are
    decomposed again with its manifold preprocessing on; a mesh that fails both ways is a clear error.
    """
    with tempfile.TemporaryDirectory() as folder:
        source, result = Path(folder) / "mesh.npz", Path(folder) / "pieces.npz"
        np.savez(source, vertices=mesh.vertices, faces=mesh.faces)
        for mode in ("auto", "on"):
            child = subprocess.run(
                [sys.executable, "-c", _COACD_CHILD, str(source), str(result), mode], capture_output=True, text=True
            )
            if child.returncode == 0:
                with np.load(result) as pieces:
                    count = int(pieces["count"])
                    return [
                        trimesh.Trimesh(vertices=pieces[f"v{i}"], faces=pieces[f"f{i}"]).convex_hull
                        for i in range(count)
                    ]
            logging.warning("CoACD (preprocess %s) failed on the mesh: %s", mode, child.stderr.strip()[-200:])
    raise ValueError("CoACD could not decompose the mesh into convex pieces (see the warnings above)")


# The child: reads the mesh, writes its pieces ({count, v<i>, f<i>}).
_COACD_CHILD = """
import sys
import coacd
import numpy as np
source, result, mode = sys.argv[1:]
with np.load(source) as mesh:
    vertices, faces = mesh["vertices"], mesh["faces"]
coacd.set_log_level("error")
parts = coacd.run_coacd(coacd.Mesh(vertices, faces), threshold=0.05, max_convex_hull=24, preprocess_mode=mode)
pieces = {"count": len(parts)}
for i, (v, f) in enumerate(parts):
    pieces[f"v{i}"], pieces[f"f{i}"] = v, f
np.savez(result, **pieces)
"""


def mass_properties(mesh, pieces, mass) -> tuple[np.ndarray, np.ndarray]:
    """Centre of mass and inertia about it, from the watertight mesh or else the pieces' union."""
    solid = mesh if mesh.is_volume else trimesh.util.concatenate(pieces).convex_hull
    solid_mass = solid.volume
    com = solid.center_mass
    inertia = solid.moment_inertia * (mass / solid_mass)
    return com, inertia
