"""Trains the part network (each object pixel's functional part) on rendered part windows; writes
models/part_segmenter.pt.

The shipped network, in two stages (about 12 and 20 min on 2 cores; the data about 15 min):

python scripts/generate_segmentation_data.py --split parts --parts --frames 1200 --seed 4 --jobs 2 --out parts1.npz
python scripts/generate_segmentation_data.py --split parts --parts --crowded --frames 400 --seed 5 --jobs 2 \
    --out parts1_crowded.npz
python scripts/train_part_network.py --data parts1.npz parts1_crowded.npz --out part_v1.pt    # 128 px windows then
python scripts/generate_segmentation_data.py --split parts --parts --frames 2400 --seed 6 --jobs 2 --out parts.npz
python scripts/generate_segmentation_data.py --split parts --parts --crowded --frames 800 --seed 7 --jobs 2 \
    --out parts_crowded.npz
python scripts/train_part_network.py --data parts.npz parts_crowded.npz --init part_v1.pt --epochs 16 \
    --learning-rate 1e-3                                                                   # 192 px windows

(The first stage's windows were 128 px: part_crop.PART_INPUT was 128 then; it is 192 now.)

The network starts from the segmenter's weights (its encoder and decoder; a fresh classifier of the PartRole
classes). Training windows hold the training members of every generated family (train_*, WIDE_TRAINING,
SHOP_TRAINING); validation windows the test instances and the families' validation members (PART_VALIDATION).
"""

import argparse
import json
import logging
from pathlib import Path

import torch

from diagrams.cli import add_sensor_option, with_sensor
from diagrams.generation.part_network_training import train_part_network
from diagrams.paths import MODELS_DIR
from diagrams.scenario import load_scenario
from systems.perception.segmenter import DEFAULT_WEIGHTS


def main():
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", type=Path, nargs="+", required=True, help="datasets rendered with --parts")
    parser.add_argument(
        "--init", type=Path, default=DEFAULT_WEIGHTS, help="the segmenter whose trunk starts it, or a part network"
    )
    parser.add_argument("--epochs", type=int, default=30)
    parser.add_argument("--learning-rate", dest="learning_rate", type=float, default=2e-3, help="the peak rate")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    parser.add_argument("--validation-frames", type=int, default=120, help="validation frames per table kind")
    parser.add_argument("--out", type=Path, default=MODELS_DIR / "part_segmenter.pt")
    add_sensor_option(parser)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    metadata = train_part_network(
        with_sensor(load_scenario(), args.sensor),
        args.data,
        args.init,
        args.out,
        epochs=args.epochs,
        learning_rate=args.learning_rate,
        seed=args.seed,
        validation_frames=args.validation_frames,
    )
    print(json.dumps(metadata, indent=2))
    print(f"wrote {args.out} ({args.out.stat().st_size / 1e6:.1f} MB)")


if __name__ == "__main__":
    main()
