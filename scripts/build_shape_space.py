"""Builds a category's latent shape space (CPD fields from a canonical instance + PCA-EM).

python scripts/build_shape_space.py --category watering_can          # models/shape_space_watering_can.npz
python scripts/build_shape_space.py --category drill --extra 8       # only 8 more generated instances (default 40)
python scripts/build_shape_space.py --folder my_cans/ --poses my_cans/poses.yaml --category my_cans
python scripts/build_shape_space.py --folder scans/ --poses scans/poses.yaml --category my_drills --align vertical

A folder holds one model per file: meshes (.obj, .ply, .stl, .glb; surface-sampled) or point
clouds (.ply, .pcd), in metres, centimetres or millimetres, z up or y up: read from the canonical
model (its size, and the face it stands on) and said, or given (--mesh-units, --mesh-up).
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
prior), unless that is under MIN_COPY_SPREAD (drills: none); --scaled-copies N sets the number. With 8 cans (one
annotated) the copies took unseen cans' grasps from 12.9 to 8.8 mm (docs/shape_space.md, "Stretched copies of a
few models").
"""

import argparse
import logging
import time
from pathlib import Path

from diagrams.cli import add_mesh_options
from diagrams.generation.objects.clouds import generated_instances
from diagrams.paths import MODELS_DIR
from systems.shape_space.drawing import draw_space
from systems.shape_space.folder import FOLDER_SCALED_COPIES, MIN_COPY_SPREAD, build_from_folder
from systems.shape_space.space import ALIGNMENTS, build_shape_space


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
    add_mesh_options(parser)
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
            units=args.mesh_units or "auto",
            up=args.mesh_up or "auto",
        )
    else:
        clouds, poses, tools = generated_instances(args.category, args.extra, args.wide)
        space = build_shape_space(
            args.category, clouds, poses, args.components, landmarks=not args.no_landmarks, tools=tools
        )
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
