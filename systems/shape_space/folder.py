"""Builds a category's latent shape space (CPD fields from a canonical instance + PCA-EM).

python scripts/build_shape_space.py --category watering_can          # models/shape_space_watering_can.npz
python scripts/build_shape_space.py --category drill --extra 8       # only 8 more generated instances (default 40)
python scripts/build_shape_space.py --folder my_cans/ --poses my_cans/poses.yaml --category my_cans
python scripts/build_shape_space.py --folder scans/ --poses scans/poses.yaml --category my_drills --align vertical

A folder holds one model per file: meshes (.obj, .ply, .stl; surface-sampled) or point
clouds (.ply, .pcd), in metres (a model 1000 times too large is an error naming the unit).
The models are taken as sharing one upright frame (z up), kept as it is; --align vertical
turns each about z and shifts it in x, y onto the canonical model, bottom on bottom;
--align rigid moves each freely in 3D. A canonical model of fewer than 4000 points (a
sparse scan) is densified (a Poisson surface, kept near the scan): it is the surface every
reconstruction warps. The poses YAML names the canonical model and its control poses
in that model's frame (metres, degrees):

  canonical: can_a.obj
  poses:
    left_pregrasp:  {translation: [0.0, 0.05, 0.40], rpy_deg: [145, 0, 0]}
    left_grasp:     {translation: [0.0, 0.0, 0.32], rpy_deg: [145, 0, 0]}
    right_pregrasp: {...}
    right_grasp:    {...}
  others:           # optional: other models' control poses, each in its own file's frame
    can_b.obj: {left_pregrasp: {...}, left_grasp: {...}, right_pregrasp: {...}, right_grasp: {...}}

Every other model's grasp frames guide its CPD field (landmarks: handle onto handle) and are
learnt as its grasp frames. Where the YAML does not give them, they are carried from the
canonical model (systems/shape_space/propagation.py: the canonical surface about each grasp,
placed by ICP and a local CPD): one annotated model is enough. A folder of 6 cans, 4
components, grasps transferred to an unseen can: 13-21 mm with the canonical's poses alone
(12-37 mm where the fields carry them), 8-10 mm with all six models' poses (see
tests/test_build_shape_space_cli.py). A folder's models are also each copied FOLDER_SCALED_COPIES times,
stretched along their axes as far as the registrar lets the category's shape scale beyond its space (its scale
prior), unless that is under MIN_COPY_SPREAD (drills: none); --scaled-copies N sets the number. With 8 cans (one
annotated) the copies took unseen cans' grasps from 12.9 to 8.8 mm (docs/shape_space.md, "Stretched copies of a
few models").
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

from diagrams.generation.objects import catalog
from diagrams.generation.objects.library import generated_instance_directory, load_info
from diagrams.paths import MODELS_DIR
from systems.perception.shape_registrar import scale_prior
from systems.shape_space.densify import densified
from systems.shape_space.space import ALIGNMENTS, POSE_NAMES, build_shape_space
from systems.shape_space.units import check_metres

CLOUD_POINTS = 8000  # per model: all of them for the canonical surface, a thinned 2000 as CPD's target
MESH_SUFFIXES = {".obj", ".stl", ".ply"}
CLOUD_SUFFIXES = {".pcd", ".ply"}
# A canonical model with fewer points than this (a sparse scan) is densified: its points are the surface
# every reconstruction warps.
DENSE_POINTS = 4000
# A folder's few models are each copied this often, stretched along C's axes with the spread of the category's scale
# prior (the registrar's: how far its shape may scale beyond its space), unless that spread is below MIN_COPY_SPREAD:
# such copies nearly repeat their model. 8 training meshes, one annotated, kinect_v2, validation range extra_201-208
# (24 views per category): cans (0.2) 12.4 -> 9.7 mm grasps, Chamfer 5.3 -> 5.8 mm, grasps over 2 cm off handed on
# 9 -> 2; drills (0.03) 7.9 -> 8.1 mm, Chamfer 3.8 -> 4.2 mm (and with 0.1, the earlier fixed spread, 7.8 -> 9.8 mm).
FOLDER_SCALED_COPIES = 4
MIN_COPY_SPREAD = 0.05
# Centres of extent farther apart than this share of the canonical's size suggest models in different frames.
FRAME_OFFSET_WARNING = 0.25


def sample_mesh(path: Path, count: int = CLOUD_POINTS) -> np.ndarray:
    mesh = trimesh.load(path, force="mesh")
    points, _ = trimesh.sample.sample_surface_even(mesh, count, seed=0)
    return np.asarray(points)


def load_model_points(path: Path) -> np.ndarray:
    """Surface points of a mesh file, or the points of a point-cloud file (thinned to CLOUD_POINTS), in metres.

    Raises SystemExit naming the file if it holds nothing or is not in metres.
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
    try:
        check_metres(points, str(path))
    except ValueError as error:
        raise SystemExit(f"error: {error}") from None
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


def generated_instances(category: str, extra: int, wide: int = 0):
    """Clouds and true control poses of the training instances, `extra` more of their family (extra_0..) and
    `wide` of the generator's wider family (wide_0..)."""
    names = [n for n in catalog.instance_names(category) if n.startswith("train")]
    names += [f"extra_{i}" for i in range(extra)] + [f"wide_{i}" for i in range(wide)]
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
    canonical = spec["canonical"]
    if len(clouds[canonical]) < DENSE_POINTS:
        logging.info("%s has %d points: densifying its surface", canonical, len(clouds[canonical]))
        clouds[canonical] = densified(clouds[canonical], CLOUD_POINTS)
    return clouds, poses, canonical


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
):
    """The shape space of a folder of models (see the module's doc); models without poses get propagated ones.
    scaled_copies: stretched copies of each model beside it (build_shape_space, with the spread of the category's
    scale prior); None: folder_copies(category)."""
    spread = scale_prior(category)
    if scaled_copies is None:
        scaled_copies = folder_copies(category)
    if scaled_copies:
        logging.info("%s: %d stretched copies of each model (spread %.2f)", category, scaled_copies, spread)
    clouds, poses, canonical = folder_instances(folder, poses_file)
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
    )


def folder_copies(category: str) -> int:
    """How many stretched copies of each of a folder's models its space gets by default: FOLDER_SCALED_COPIES, none
    where the category's scale prior is below MIN_COPY_SPREAD."""
    return FOLDER_SCALED_COPIES if scale_prior(category) >= MIN_COPY_SPREAD else 0


def pose_entries(poses: dict[str, RigidTransform]) -> dict:
    """Control poses as the poses YAML holds them (the inverse of parse_poses)."""
    return {
        name: {
            "translation": X.translation().tolist(),
            "rpy_deg": np.degrees(RollPitchYaw(X.rotation()).vector()).tolist(),
        }
        for name, X in poses.items()
    }


def draw_space(space, path: Path, components: int = 3, spread: float = 2.0):
    """A figure of the space: the mean shape and each of the first components at -spread, +spread standard
    deviations, seen from the front (x_O right, z_O up) and from above, with the grasp frames' origins."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = min(components, space.latent_size)
    rows = [("mean", np.zeros(space.latent_size))]
    for k in range(shown):
        for sign in (-1, 1):
            latent = np.zeros(space.latent_size)
            latent[k] = sign * spread * np.sqrt(space.pca.variances[k])
            rows.append((f"component {k + 1}: {sign * spread:+.0f} sd", latent))
    size = (2.2 * len(rows), 4.6)
    figure, axes = plt.subplots(2, len(rows), figsize=size, squeeze=False, sharex="row", sharey="row")
    for column, (title, latent) in enumerate(rows):
        surface = space.reconstruct(latent)
        grasps = np.array([X.translation() for X in space.control_poses_at(latent).values()])
        for row, (u, v) in enumerate(((0, 2), (0, 1))):
            ax = axes[row, column]
            ax.scatter(surface[:, u], surface[:, v], s=0.2, c="0.4")
            ax.scatter(grasps[:, u], grasps[:, v], s=12, c=["tab:blue", "tab:blue", "tab:red", "tab:red"])
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
        axes[0, column].set_title(title, fontsize=8)
    axes[0, 0].set_ylabel("front (x, z)")
    axes[1, 0].set_ylabel("above (x, y)")
    title = f"{space.category}: mean and first components; control poses left blue, right red (outer: pre-grasps)"
    figure.suptitle(title, fontsize=9)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def main():
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--category", required=True, help="generated category, or the name of a folder's category")
    parser.add_argument("--extra", type=int, default=40, help="extra generated instances beyond train_0..7")
    parser.add_argument(
        "--wide", type=int, default=0, help="generated instances of the wider family (wide_0..) beside them"
    )
    parser.add_argument("--folder", type=Path, help="a folder of your own models (meshes or point clouds)")
    parser.add_argument("--poses", type=Path, help="with --folder: YAML with the canonical model's control poses")
    parser.add_argument(
        "--align",
        choices=ALIGNMENTS,
        default="none",
        help="with --folder: none (default): the models share one upright frame, kept as it is; vertical: each "
        "has its own heading and origin, z up; rigid: each has a frame of its own",
    )
    parser.add_argument("--components", type=int, default=8, help="latent dimensions (the paper: 8)")
    parser.add_argument(
        "--scaled-copies",
        type=int,
        help=f"with --folder: stretched copies of each model beside it (default {FOLDER_SCALED_COPIES}, none where "
        f"the category's scale prior is under {MIN_COPY_SPREAD}: drills; see docs/shape_space.md)",
    )
    parser.add_argument(
        "--no-landmarks",
        action="store_true",
        help="plain CPD fields carry the canonical poses: other models' poses are neither used nor propagated",
    )
    parser.add_argument(
        "--out", type=Path, help="default: models/shape_space_<category>.npz (and a figure of it beside, .png)"
    )
    args = parser.parse_args()
    if args.scaled_copies is not None and not args.folder:
        parser.error("--scaled-copies needs --folder (the generated spaces have enough models)")
    if args.scaled_copies is not None and args.scaled_copies < 0:
        parser.error(f"--scaled-copies must be 0 or more, got {args.scaled_copies}")
    start = time.perf_counter()
    if args.folder:
        if not args.poses:
            parser.error("--folder needs --poses")
        space = build_from_folder(
            args.folder,
            args.poses,
            args.category,
            args.components,
            args.align,
            landmarks=not args.no_landmarks,
            scaled_copies=args.scaled_copies,
        )
    else:
        clouds, poses = generated_instances(args.category, args.extra, args.wide)
        space = build_shape_space(args.category, clouds, poses, args.components, landmarks=not args.no_landmarks)
    out = args.out or MODELS_DIR / f"shape_space_{args.category}.npz"
    space.save(out)
    explained = space.pca.variances / space.pca.variances.sum()
    print(f"canonical: {space.canonical_name}; {len(space.instance_names)} instances; {space.latent_size} components")
    print("variance explained per component: " + " ".join(f"{v:.2f}" for v in explained))
    draw_space(space, out.with_suffix(".png"))
    print(
        f"wrote {out} ({out.stat().st_size / 1e3:.0f} kB) and a figure of it, {out.with_suffix('.png')}, in "
        f"{time.perf_counter() - start:.1f} s"
    )


if __name__ == "__main__":
    main()
