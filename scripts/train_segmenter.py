"""Trains the segmenter from scratch on synthetic frames (CPU, seeded) and writes models/segmenter.pt.

python scripts/train_segmenter.py                       # renders data/segmentation/train.npz first if missing
python scripts/train_segmenter.py --data data/segmentation/train.npz data/segmentation/crowded.npz   # both sets
python scripts/train_segmenter.py --epochs 2 --out /tmp/seg.pt
python scripts/train_segmenter.py --data train.npz crowded.npz wide.npz --init W.pt --epochs 10 --learning-rate 5e-4

Training frames may hold the training instances (train_*) and the wider family's training members (WIDE_TRAINING);
the validation frames hold the test instances and the wider family's validation members (WIDE_VALIDATION).
"""

import argparse
import json
import logging
import time
from pathlib import Path

import numpy as np
import torch

from diagrams.cli import add_sensor_option, with_sensor
from diagrams.generation import segmentation_data
from diagrams.generation.synthetic_scenes import CLASSES, WIDE_TRAINING, WIDE_VALIDATION
from diagrams.paths import MODELS_DIR
from diagrams.scenario import load_scenario
from systems.perception import segmentation_network, segmenter_training

VALIDATION_FRAMES = 60


def main():
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--data",
        type=Path,
        nargs="+",
        default=[segmentation_data.DEFAULT_DATASET],
        help="training frames (.npz files, taken together)",
    )
    parser.add_argument(
        "--frames", type=int, default=segmentation_data.DEFAULT_FRAMES, help="frames to render if --data does not exist"
    )
    parser.add_argument("--epochs", type=int, default=40)
    parser.add_argument(
        "--init", type=Path, help="start from these weights (fine-tuning; default: from scratch, at the default rate)"
    )
    parser.add_argument("--learning-rate", dest="learning_rate", type=float, default=3e-3, help="the peak rate")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    parser.add_argument("--out", type=Path, default=MODELS_DIR / "segmenter.pt")
    add_sensor_option(parser)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    scenario = with_sensor(load_scenario(), args.sensor)
    if args.data == [segmentation_data.DEFAULT_DATASET] and not args.data[0].is_file():
        logging.info("%s missing: rendering %d training frames", args.data[0], args.frames)
        segmentation_data.save(
            args.data[0],
            segmentation_data.generate(scenario, args.frames, segmentation_data.FRAMES_PER_SCENE, "train", args.seed),
        )
    parts = [segmentation_data.load(path) for path in args.data]
    data = {key: np.concatenate([part[key] for part in parts]) for key in ("rgb", "labels", "instances")}
    names = {name.split("/")[1] for row in data["instances"] for name in row.split(",") if name}
    unseen = sorted(name for name in names if not name.startswith("train") and name not in WIDE_TRAINING)
    if unseen:
        raise SystemExit(f"{args.data} hold instances kept for validation or tests ({unseen[:4]}); refusing to train")

    start = time.perf_counter()
    if args.init:
        model, metadata = segmentation_network.load(args.init)
        if tuple(metadata["classes"]) != CLASSES:
            raise SystemExit(f"{args.init} knows {metadata['classes']}, not {CLASSES}")
        model, history = segmenter_training.fit(
            model, data["rgb"], data["labels"], args.epochs, args.seed, learning_rate=args.learning_rate
        )
    else:
        model, history = segmenter_training.train(
            data["rgb"], data["labels"], len(CLASSES), args.epochs, args.seed, learning_rate=args.learning_rate
        )
    train_s = time.perf_counter() - start

    logging.info(
        "validating on %d frames each: unseen (test) instances, crowded ones, the wider family's", VALIDATION_FRAMES
    )
    seed = segmentation_data.VALIDATION_SEED
    metadata = segmenter_training.training_record(
        CLASSES, args.epochs, args.seed, len(data["rgb"]), scenario.camera_noise.preset, train_s, history
    )
    metadata |= {"initial_weights": str(args.init) if args.init else "", "learning_rate": args.learning_rate}
    sets = {
        "validation": (False, None),
        "validation_crowded": (True, None),
        "validation_wide": (False, WIDE_VALIDATION),
    }
    for key, (crowded, instances) in sets.items():
        validation = segmentation_data.generate(
            scenario, VALIDATION_FRAMES, 20, "test", seed, crowded=crowded, instances=instances
        )
        metadata[key] = {
            "frames": VALIDATION_FRAMES,
            "seed": seed,
            "iou": segmenter_training.class_iou(model, validation["rgb"], validation["labels"], CLASSES),
        }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    segmentation_network.save(model, args.out, metadata)
    print(json.dumps(metadata, indent=2))
    print(f"wrote {args.out} ({args.out.stat().st_size / 1e6:.1f} MB) after {train_s:.0f} s of training")


if __name__ == "__main__":
    main()
