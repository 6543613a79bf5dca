"""Builds a category's latent shape space (CPD fields from a canonical instance + PCA-EM).

python scripts/build_shape_space.py --category watering_can          # models/shape_space_watering_can.npz
python scripts/build_shape_space.py --category drill --extra 8       # only 8 more generated instances (default 40)
python scripts/build_shape_space.py --folder my_cans/ --poses my_cans/poses.yaml --category my_cans

A folder holds one model per file: meshes (.obj, .ply, .stl; surface-sampled) or point
clouds (.ply, .pcd). The poses YAML names the canonical model and its control poses
in that model's frame (metres, degrees):

  canonical: can_a.obj
  poses:
    left_pregrasp:  {translation: [0.0, 0.05, 0.40], rpy_deg: [145, 0, 0]}
    left_grasp:     {translation: [0.0, 0.0, 0.32], rpy_deg: [145, 0, 0]}
    right_pregrasp: {...}
    right_grasp:    {...}
  others:           # optional: other models' control poses, each in its own file's frame
    can_b.obj: {left_pregrasp: {...}, left_grasp: {...}, right_pregrasp: {...}, right_grasp: {...}}

Where other models' poses are given, they guide those models' CPD fields (landmarks: handle
onto handle) and are learnt as their grasp frames; the transferred grasps then come out
much closer (a folder of 6 cans, 4 components: 32-39 mm with the canonical's poses alone,
14-21 mm with all six models' poses; see tests/test_build_shape_space_cli.py).
"""

import argparse
import logging
import time
from pathlib import Path

import numpy as np
import open3d as o3d
import trimesh
import yaml
from pydrake.math import RigidTransform, RollPitchYaw

from diagrams.objects import catalog
from diagrams.objects.library import generated_instance_directory, load_info
from diagrams.paths import MODELS_DIR
from systems.shape_space.space import POSE_NAMES, build_shape_space

CLOUD_POINTS = 8000  # per model: all of them for the canonical surface, a thinned 2000 as CPD's target
MESH_SUFFIXES = {".obj", ".stl", ".ply"}
CLOUD_SUFFIXES = {".pcd", ".ply"}


def sample_mesh(path: Path, count: int = CLOUD_POINTS) -> np.ndarray:
    mesh = trimesh.load(path, force="mesh")
    points, _ = trimesh.sample.sample_surface_even(mesh, count, seed=0)
    return np.asarray(points)


def load_model_points(path: Path) -> np.ndarray:
    """Surface points of a mesh file, or the points of a point-cloud file (thinned to CLOUD_POINTS)."""
    if path.suffix.lower() in CLOUD_SUFFIXES:
        cloud = np.asarray(o3d.io.read_point_cloud(str(path)).points)
        if len(cloud) > 0 and (path.suffix.lower() == ".pcd" or len(trimesh.load(path, force="mesh").faces) == 0):
            index = np.random.default_rng(0).choice(len(cloud), min(CLOUD_POINTS, len(cloud)), replace=False)
            return cloud[index]
    points = sample_mesh(path)
    if len(points) == 0:
        raise ValueError(f"{path}: no surface or points")
    return points


def generated_instances(category: str, extra: int):
    """Clouds and true control poses of the training instances (and `extra` more generated ones)."""
    names = [n for n in catalog.instance_names(category) if n.startswith("train")]
    names += [f"extra_{i}" for i in range(extra)]
    clouds, poses = {}, {}
    for name in names:
        directory = generated_instance_directory(category, name)
        clouds[name] = sample_mesh(directory / "visual.obj")
        poses[name] = load_info(directory / "info.yaml").control_poses()
    return clouds, poses


def folder_instances(folder: Path, poses_file: Path):
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
    for model, model_poses in (spec.get("others") or {}).items():
        poses[model] = parse_poses(model_poses, poses_file, model)
    names = sorted(p.name for p in files)
    unknown = sorted(set(poses) - set(names))
    if unknown:
        raise SystemExit(f"error: {poses_file} gives poses of {unknown}, not among the models {names}")
    clouds = {p.name: load_model_points(p) for p in files}
    return clouds, poses, spec["canonical"]


def parse_poses(spec: dict, poses_file: Path, model: str = "the canonical model") -> dict[str, RigidTransform]:
    """{POSE_NAMES entry: X_OG} from {name: {translation: [x, y, z] (m), rpy_deg: [r, p, y]}}."""
    missing = [n for n in POSE_NAMES if n not in (spec or {})]
    if missing:
        raise SystemExit(f"error: {poses_file}: {model} lacks poses {missing}")
    return {n: RigidTransform(RollPitchYaw(np.radians(spec[n]["rpy_deg"])), spec[n]["translation"]) for n in POSE_NAMES}


def main():
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--category", required=True, help="generated category, or the name of a folder's category")
    parser.add_argument("--extra", type=int, default=40, help="extra generated instances beyond train_0..7")
    parser.add_argument("--folder", type=Path, help="a folder of your own models (meshes or point clouds)")
    parser.add_argument("--poses", type=Path, help="with --folder: YAML with the canonical model's control poses")
    parser.add_argument("--components", type=int, default=8, help="latent dimensions (the paper: 8)")
    parser.add_argument(
        "--no-landmarks",
        action="store_true",
        help="plain CPD fields: ignore the control poses of instances other than the canonical one",
    )
    parser.add_argument("--out", type=Path, help="default: models/shape_space_<category>.npz")
    args = parser.parse_args()
    start = time.perf_counter()
    if args.folder:
        if not args.poses:
            parser.error("--folder needs --poses")
        clouds, poses, canonical = folder_instances(args.folder, args.poses)
        space = build_shape_space(
            args.category,
            clouds,
            poses,
            args.components,
            canonical=canonical,
            align=True,
            landmarks=not args.no_landmarks,
        )
    else:
        clouds, poses = generated_instances(args.category, args.extra)
        space = build_shape_space(args.category, clouds, poses, args.components, landmarks=not args.no_landmarks)
    out = args.out or MODELS_DIR / f"shape_space_{args.category}.npz"
    space.save(out)
    explained = space.pca.variances / space.pca.variances.sum()
    print(f"canonical: {space.canonical_name}; {len(clouds)} instances; {space.latent_size} components")
    print("variance explained per component: " + " ".join(f"{v:.2f}" for v in explained))
    print(f"wrote {out} ({out.stat().st_size / 1e3:.0f} kB) in {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
