"""A category's latent shape space from a user's folder of models (scripts/build_shape_space.py --folder,
scripts/add_category.py): reading and checking the models and their poses file, then build_shape_space.

A folder holds one model per file: meshes (.obj, .ply, .stl, .glb; surface-sampled) or point
clouds (.ply, .pcd), in metres, centimetres or millimetres, z up or y up: read from the canonical
model (file_frame.py: its size, and the face it stands on) and said, or given (units, up).
The models are taken as sharing one upright frame, kept as it is; --align vertical
turns each about z and shifts it in x, y onto the canonical model, bottom on bottom;
--align rigid moves each freely in 3D. A canonical model of fewer than 4000 points (a
sparse scan) is densified (a Poisson surface, kept near the scan): it is the surface every
reconstruction warps. The poses YAML names the canonical model and its control poses
in that model's file's frame and units (degrees):

  canonical: can_a.obj
  poses:
    left_pregrasp:  {translation: [0.0, 0.05, 0.40], rpy_deg: [145, 0, 0]}
    left_grasp:     {translation: [0.0, 0.0, 0.32], rpy_deg: [145, 0, 0]}
    right_pregrasp: {...}
    right_grasp:    {...}
  others:           # optional: other models' control poses, each in its own file's frame
    can_b.obj: {left_pregrasp: {...}, left_grasp: {...}, right_pregrasp: {...}, right_grasp: {...}}
  tool: {tip: [0.25, 0.0, 0.21], axis: [0.8, 0.0, 0.6]}   # optional: the canonical model's tool frame

Every other model's grasp frames guide its CPD field (landmarks: handle onto handle) and are
learnt as its grasp frames. Where the YAML does not give them, they are carried from the
canonical model (systems/shape_space/propagation.py: the canonical surface about each grasp,
placed by ICP and a local CPD): one annotated model is enough. A folder of 6 cans, 4
components, grasps transferred to an unseen can: 13-21 mm with the canonical's poses alone
(12-37 mm where the fields carry them), 8-10 mm with all six models' poses (see
tests/test_build_shape_space_cli.py). A folder's models are also each copied FOLDER_SCALED_COPIES times,
stretched along their axes as far as the registrar lets the category's shape scale beyond its space (its scale
prior), unless that is under MIN_COPY_SPREAD (drills: none); scaled_copies sets the number. With 8 cans (one
annotated) the copies took unseen cans' grasps from 12.9 to 8.8 mm (docs/shape_space.md, "Stretched copies of a
few models").
"""

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import open3d as o3d
import trimesh
import yaml
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from systems.perception.shape_registrar import scale_prior
from systems.shape_space.densify import densified
from systems.shape_space.file_frame import FileReading, read_file_frame
from systems.shape_space.space import POSE_NAMES, build_shape_space, tool_surface
from systems.shape_space.tool_frame import ToolFrame
from systems.shape_space.units import UNIT_NAMES, check_metres, metres_per_unit

CLOUD_POINTS = 8000  # per model: all of them for the canonical surface, a thinned 2000 as CPD's target
MESH_SUFFIXES = {".obj", ".stl", ".ply", ".glb", ".gltf"}
CLOUD_SUFFIXES = {".pcd", ".ply"}
# A canonical model with fewer points than this (a sparse scan) is densified: its points are the surface
# every reconstruction warps.
DENSE_POINTS = 4000
# A folder's few models are each copied this often, stretched along C's axes with the spread of the category's scale
# prior (the registrar's: how far its shape may scale beyond its space), unless that spread is below MIN_COPY_SPREAD:
# such copies nearly repeat their model (docs/history/registration_parameters.md).
FOLDER_SCALED_COPIES = 4
MIN_COPY_SPREAD = 0.05
# Centres of extent farther apart than this share of the canonical's size suggest models in different frames.
FRAME_OFFSET_WARNING = 0.25


def sample_mesh(path: Path, count: int = CLOUD_POINTS) -> np.ndarray:
    """`count` points spread evenly over a mesh file's surface (its units), the same on every call."""
    mesh = trimesh.load(path, force="mesh")
    points, _ = trimesh.sample.sample_surface_even(mesh, count, seed=0)
    return np.asarray(points)


def load_model_points(path: Path) -> np.ndarray:
    """Surface points of a mesh file, or the points of a point-cloud file (thinned to CLOUD_POINTS), in its units.

    Raises SystemExit naming the file if it holds nothing.
    """
    points = None
    if path.suffix.lower() in CLOUD_SUFFIXES:
        cloud = np.asarray(o3d.io.read_point_cloud(str(path)).points)
        if len(cloud) > 0 and (path.suffix.lower() == ".pcd" or len(trimesh.load(path, force="mesh").faces) == 0):
            index = np.random.default_rng(0).choice(len(cloud), min(CLOUD_POINTS, len(cloud)), replace=False)
            points = cloud[np.sort(index)]
    if points is None:
        points = sample_mesh(path)
    points = points[np.all(np.isfinite(points), axis=1)]
    if len(points) == 0:
        raise SystemExit(f"error: {path}: no surface or points")
    return points


def frame_warnings(clouds: dict[str, np.ndarray], canonical: str) -> list[str]:
    """Models whose extent lies far from the canonical's: their frames are probably not the canonical's."""
    lo, hi = clouds[canonical].min(axis=0), clouds[canonical].max(axis=0)
    warnings = []
    for name, cloud in clouds.items():
        offset = np.linalg.norm((cloud.min(axis=0) + cloud.max(axis=0)) / 2 - (lo + hi) / 2)
        if offset > FRAME_OFFSET_WARNING * np.max(hi - lo):
            warnings.append(f"{name}'s extent is centred {100 * offset:.0f} cm from {canonical}'s")
    return warnings


@dataclass
class FolderModels:
    """A folder of a category's models, read."""

    clouds: dict[str, np.ndarray]  # {file name: N x 3 model points, m}; the canonical one's densified where sparse
    poses: dict[str, dict[str, RigidTransform]]  # the poses file's control poses {file name: {name: X_OG}}, m
    canonical: str  # the canonical model's file name
    tool: ToolFrame | None  # the canonical model's tool frame (m, in its frame), None where the poses file has none
    reading: FileReading  # how the files' coordinates were read (units, up axis): the clouds are in metres, z up


def folder_instances(folder: Path, poses_file: Path, units: str = "auto", up: str = "auto") -> FolderModels:
    """A folder's models and the control poses its poses file gives, in metres with z up: the files' units and up
    axis (MESH_UNITS, MESH_UP_AXES) as given, or read from the canonical model where "auto" (they share one frame).

    Raises SystemExit naming the problem: not a folder, fewer than 2 models, a poses file that lacks something, a
    model no unit makes an object's, or one whose size in the canonical's units is not an object's.
    """
    if not folder.is_dir():
        raise SystemExit(f"error: {folder} is not a folder")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in MESH_SUFFIXES | CLOUD_SUFFIXES)
    if len(files) < 2:
        raise SystemExit(f"error: {folder} holds {len(files)} model files; a shape space needs at least 2")
    spec = yaml.safe_load(poses_file.read_text())
    if not isinstance(spec, dict) or "canonical" not in spec or "poses" not in spec:
        raise SystemExit(f"error: {poses_file} needs 'canonical' (a model's file name) and its 'poses'")
    # The pose file is checked before any model is sampled: a mistake in it costs nothing.
    poses = {spec["canonical"]: parse_poses(spec["poses"], poses_file)}
    tool = parse_tool(spec.get("tool"), poses_file)
    for model, model_poses in (spec.get("others") or {}).items():
        poses[model] = parse_poses(model_poses, poses_file, model)
    names = sorted(p.name for p in files)
    unknown = sorted(set(poses) - set(names))
    if unknown:
        raise SystemExit(f"error: {poses_file} gives poses of {unknown}, not among the models {names}")
    clouds = {p.name: load_model_points(p) for p in files}
    canonical = spec["canonical"]
    try:
        reading = read_file_frame(clouds[canonical], clouds[canonical].mean(axis=0), units, up, canonical)
        for name, points in clouds.items():
            clouds[name] = points @ reading.matrix()[:3, :3].T
            check_metres(clouds[name], f"{name} (read in {UNIT_NAMES[reading.units]}, as {canonical} is)")
    except ValueError as error:
        raise SystemExit(f"error: {error}") from None
    logging.info("%s (and every model of %s)", reading.describe(canonical), folder)
    X_MF = RigidTransform(RotationMatrix(reading.rotation()), np.zeros(3))  # the files' frame F in metres, z up
    scale = metres_per_unit(reading.units)
    for name, model_poses in poses.items():
        poses[name] = {n: X_MF @ RigidTransform(X.rotation(), scale * X.translation()) for n, X in model_poses.items()}
    if tool is not None:
        tool = ToolFrame(scale * tool.tip, tool.axis).moved(X_MF)
        try:
            tool_surface(clouds[canonical], tool)
        except ValueError as error:
            raise SystemExit(f"error: {poses_file}: {error} ({canonical}, read as said above)") from None
    if len(clouds[canonical]) < DENSE_POINTS:
        logging.info("%s has %d points: densifying its surface", canonical, len(clouds[canonical]))
        clouds[canonical] = densified(clouds[canonical], CLOUD_POINTS)
    return FolderModels(clouds, poses, canonical, tool, reading)


def parse_poses(spec: dict, poses_file: Path, model: str = "the canonical model") -> dict[str, RigidTransform]:
    """{POSE_NAMES entry: X_OG} from {name: {translation: [x, y, z] (m), rpy_deg: [r, p, y]}}."""
    missing = [n for n in POSE_NAMES if n not in (spec or {})]
    if missing:
        raise SystemExit(f"error: {poses_file}: {model} lacks poses {missing}")
    return {n: RigidTransform(RollPitchYaw(np.radians(spec[n]["rpy_deg"])), spec[n]["translation"]) for n in POSE_NAMES}


def build_from_folder(
    folder: Path,
    poses_file: Path,
    category: str,
    components: int = 8,
    align: str = "none",
    landmarks: bool = True,
    scaled_copies: int | None = None,
    units: str = "auto",
    up: str = "auto",
):
    """The shape space of a folder of models (see the module's doc); models without poses get propagated ones.
    scaled_copies: stretched copies of each model beside it (build_shape_space, with the spread of the category's
    scale prior); None: folder_copies(category). units, up: the files' (folder_instances)."""
    spread = scale_prior(category)
    if scaled_copies is None:
        scaled_copies = folder_copies(category)
    if scaled_copies:
        logging.info("%s: %d stretched copies of each model (spread %.2f)", category, scaled_copies, spread)
    models = folder_instances(folder, poses_file, units, up)
    clouds, poses, canonical = models.clouds, models.poses, models.canonical
    if align == "none":
        for warning in frame_warnings(clouds, canonical):
            logging.warning("warning: %s; if the models do not share one frame, pass --align vertical", warning)
    return build_shape_space(
        category,
        clouds,
        poses,
        components,
        canonical=canonical,
        align=align,
        landmarks=landmarks,
        scaled_copies=scaled_copies,
        copy_spread=spread,
        tools={canonical: models.tool} if models.tool else None,
    )


def folder_copies(category: str) -> int:
    """How many stretched copies of each of a folder's models its space gets by default: FOLDER_SCALED_COPIES, none
    where the category's scale prior is below MIN_COPY_SPREAD."""
    return FOLDER_SCALED_COPIES if scale_prior(category) >= MIN_COPY_SPREAD else 0


def parse_tool(spec: dict | None, poses_file: Path) -> ToolFrame | None:
    """The canonical model's tool frame from {tip: [x, y, z], axis: [x, y, z]} (its file's frame and units), None
    where not given."""
    if spec is None:
        return None
    try:
        return ToolFrame(spec["tip"], spec["axis"])
    except (KeyError, TypeError, ValueError) as error:
        raise SystemExit(
            f"error: {poses_file}: tool needs a tip [x, y, z] and a non-zero axis [x, y, z] ({error})"
        ) from None


def pose_entries(poses: dict[str, RigidTransform]) -> dict:
    """Control poses as the poses YAML holds them (the inverse of parse_poses)."""
    return {
        name: {
            "translation": X.translation().tolist(),
            "rpy_deg": np.degrees(RollPitchYaw(X.rotation()).vector()).tolist(),
        }
        for name, X in poses.items()
    }
