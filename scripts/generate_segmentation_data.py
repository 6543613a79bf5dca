"""Renders synthetic segmentation frames (randomised scenes, training instances only by default).

python scripts/generate_segmentation_data.py                         # data/segmentation/train.npz, 800 frames
python scripts/generate_segmentation_data.py --frames 400 --split test --out /tmp/test.npz
"""

import argparse
import logging
from pathlib import Path

from diagrams import segmentation_data
from diagrams.scenario import load_scenario


def main():
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--frames", type=int, default=segmentation_data.DEFAULT_FRAMES, help="number of frames (the paper used 400)"
    )
    parser.add_argument(
        "--frames-per-scene", type=int, default=segmentation_data.FRAMES_PER_SCENE, help="frames per random background"
    )
    parser.add_argument("--split", choices=("train", "test"), default="train", help="which object instances")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=segmentation_data.DEFAULT_DATASET)
    args = parser.parse_args()
    if args.frames < 1 or args.frames_per_scene < 1:
        parser.error("--frames and --frames-per-scene must be positive")
    dataset = segmentation_data.generate(load_scenario(), args.frames, args.frames_per_scene, args.split, args.seed)
    segmentation_data.save(args.out, dataset)
    print(f"wrote {args.out}: {args.frames} frames of {args.split} instances")


if __name__ == "__main__":
    main()
