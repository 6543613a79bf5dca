"""Benchmarks segmentation and pose estimation on held-out scenes with the unseen test instances.

Each scene is a new random background with one test can or drill at a random pose,
seen from the chest camera's nominal pose (the whole object in view), its colour and depth as the
RGB-D sensor model reports them (--sensor, by default kinect_v2; --no-noise: the renderer's perfect
images). The Segmenter and PoseEstimator systems run as they do in the pick diagram (FixValue / Eval).

With --scene clutter, seeded cluttered tables instead (diagrams/benchmarks/perception_in_clutter.py): the target
among others, and empty tables with distractors only.

python scripts/benchmark_perception.py --scenes 60 --json perception.json
python scripts/benchmark_perception.py --scenes 60 --no-noise
python scripts/benchmark_perception.py --scene clutter --scenes 30 --empty-tables 20 --json clutter_perception.json
python scripts/benchmark_perception.py --parts --json parts.json      # per-part IoU, the test instances
python scripts/benchmark_perception.py --parts --part-folders held_out shop_held_out --json parts.json
    # ... and the held-out families' models (make_unfamiliar_objects.py, make_shop_held_out.py folders)
"""

import argparse
import logging
from pathlib import Path

import torch

from diagrams.benchmarks import part_perception, perception, perception_in_clutter
from diagrams.cli import add_sensor_option, with_sensor, write_json
from diagrams.scenario import load_scenario
from systems.perception.segmenter import DEFAULT_WEIGHTS, TEST_TIME_FLIP


def main():
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=60)
    parser.add_argument("--seed", type=int, default=2024, help="held-out scenes' seed (training used others)")
    parser.add_argument("--weights", type=Path, default=DEFAULT_WEIGHTS)
    parser.add_argument(
        "--threads",
        type=int,
        help="torch's CPU threads (default: with --parts 1, as evaluate.py runs the pick: OpenMP on one thread, the "
        "image and its mirror image on two; else 2)",
    )
    add_sensor_option(parser, default="kinect_v2")
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument("--figure", type=Path, help="write a mosaic of the first 6 scenes here (.png)")
    parser.add_argument(
        "--scene",
        choices=("single", "clutter"),
        default="single",
        help="single: synthetic scenes with one object; clutter: --scenes cluttered tables per category",
    )
    parser.add_argument("--empty-tables", dest="empty_tables", type=int, default=20, help="with --scene clutter")
    parser.add_argument(
        "--flip",
        choices=("on", "off"),
        help=f"the segmenter's test-time flip (default: the pick's, {'on' if TEST_TIME_FLIP else 'off'})",
    )
    parser.add_argument("--parts", action="store_true", help="per-part IoU of the part network (part_perception.py)")
    parser.add_argument(
        "--part-folders", dest="part_folders", type=Path, nargs="*", default=[], help="with --parts: families' folders"
    )
    args = parser.parse_args()
    torch.set_num_threads(args.threads or (1 if args.parts else 2))
    if args.parts:
        subjects = part_perception.generated_subjects()
        for folder in args.part_folders:
            subjects += part_perception.folder_subjects(folder)
        results = part_perception.run(with_sensor(load_scenario(), args.sensor), subjects, args.seed, args.sensor)
        part_perception.print_table(results)
        if args.json:
            write_json(args.json, results)
        return
    if args.scene == "clutter":
        base = with_sensor(load_scenario(), args.sensor)
        results = perception_in_clutter.run(base, args.weights, args.scenes, args.empty_tables)
        results |= {"sensor": args.sensor, "torch_threads": torch.get_num_threads()}
        perception_in_clutter.print_table(results)
        if args.json:
            write_json(args.json, results)
        return
    flip = TEST_TIME_FLIP if args.flip is None else args.flip == "on"
    results, tiles = perception.run(args.scenes, args.seed, args.weights, args.sensor, flip, 6 if args.figure else 0)
    perception.print_table(results)
    if args.json:
        write_json(args.json, results)
    if args.figure and tiles:
        perception.write_mosaic(args.figure, tiles)


if __name__ == "__main__":
    main()
