"""Teaches the robot a new familiar category from a folder of your own models, one of them annotated.

python scripts/add_category.py --folder my_pots/ --poses my_pots/poses.yaml --name pot --symmetric
python scripts/pick.py --object pot --object-file new_pot.obj                 # then pick an unseen one
python scripts/evaluate.py --category pot --object-files pots/test/*.obj --trials 1

The folder and the poses file are build_shape_space.py's (meshes or point clouds sharing one frame, in
metres, centimetres or millimetres, z or y up: read and said, or given by --mesh-units / --mesh-up; the poses
YAML names the canonical model and its control poses, and its tool frame where it has one, in its file's frame
and units). The steps:

  1. the models are read and checked (units, frames); the category's frame O is the folder's frame moved
     so that the canonical model's bottom face is at z = 0 and its extent centred on x = y = 0;
  2. the shape space is built, every model's grasps carried from the canonical one, and drawn (.png);
  3. the canonical model is written as the pose estimator's template and every model as a visual-only
     SDF (point clouds get a Poisson surface) to render from;
  4. synthetic frames of scenes holding every known category are rendered and the segmenter in use is
     fine-tuned with the new class (its classifier widened; the old classes keep their weights), then
     checked on frames of another seed;
  5. the new segmenter and the category's record are written: from then on every pick knows the class.

Everything lands in systems.categories.categories_dir() ($DUALARM_CATEGORIES, default
~/.local/share/dualarm/categories): <name>/ and segmenter.pt. --symmetric: the models look the same turned
half a turn about z (a pot, a crate); the pose then keeps the left grasp on the robot's left.
"""

import argparse
import logging
from pathlib import Path

import torch

from diagrams.cli import add_mesh_options, add_sensor_option
from diagrams.generation.teaching import check_name, teach_category
from systems.shape_space.space import ALIGNMENTS


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--folder", type=Path, required=True, help="one model per file (meshes or point clouds)")
    parser.add_argument("--poses", type=Path, required=True, help="the canonical model's control poses (YAML)")
    parser.add_argument("--name", required=True, help="the category's name (lower case letters, digits, _)")
    parser.add_argument("--symmetric", action="store_true", help="the models look the same turned pi about z")
    parser.add_argument(
        "--presentation-yaw", dest="presentation_yaw", type=float, default=0.0,
        help="world yaw of O at the presentation the grasps are meant for, rad (0: x_O away from the robot)",
    )  # fmt: skip
    parser.add_argument("--components", type=int, default=8, help="latent dimensions (at most models - 1)")
    parser.add_argument("--align", choices=ALIGNMENTS, default="none", help="as build_shape_space.py's")
    parser.add_argument("--frames", type=int, default=800, help="synthetic frames to fine-tune the segmenter on")
    parser.add_argument("--frames-per-scene", dest="frames_per_scene", type=int, default=25)
    parser.add_argument("--epochs", type=int, default=10, help="fine-tuning epochs")
    parser.add_argument("--validation-frames", dest="validation_frames", type=int, default=40)
    parser.add_argument(
        "--keep-segmenter", dest="keep_segmenter", action="store_true",
        help="re-teach the shape space and grasps only: the segmenter in use knows the class already",
    )  # fmt: skip
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    add_mesh_options(parser)
    add_sensor_option(parser)
    args = parser.parse_args(argv)
    try:
        check_name(args.name)
    except ValueError as error:
        parser.error(str(error))
    if min(args.frames, args.frames_per_scene, args.epochs, args.validation_frames) < 1:
        parser.error("--frames, --frames-per-scene, --epochs and --validation-frames must be positive")
    return args


def main(argv=None) -> int:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    args = parse_args(argv)
    torch.set_num_threads(args.threads)
    teach_category(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
