"""Renders synthetic segmentation frames (randomised scenes, training instances only by default).

python scripts/generate_segmentation_data.py                         # data/segmentation/train.npz, 800 frames
python scripts/generate_segmentation_data.py --frames 400 --split test --out /tmp/test.npz
python scripts/generate_segmentation_data.py --jobs 2                # scenes rendered in 2 worker processes
python scripts/generate_segmentation_data.py --ray auto --frames 8000  # each scene a task on a Ray cluster
python scripts/generate_segmentation_data.py --no-noise              # the renderer's colour, no sensor model
python scripts/generate_segmentation_data.py --split wide --frames 400 --seed 3 --out data/segmentation/wide.npz
                                                                     # the wider family's training members

Every scene draws from a random stream of its own ([seed, scene number]), so the frames are the same whether
they are rendered here, in worker processes or on Ray.
"""

import argparse
from pathlib import Path

from diagrams.campaign import fan_out
from diagrams.cli import add_sensor_option, with_sensor
from diagrams.generation import segmentation_data
from diagrams.scenario import load_scenario


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--frames", type=int, default=segmentation_data.DEFAULT_FRAMES, help="number of frames (the paper used 400)"
    )
    parser.add_argument(
        "--frames-per-scene", type=int, default=segmentation_data.FRAMES_PER_SCENE, help="frames per random background"
    )
    parser.add_argument(
        "--split",
        choices=("train", "test", "wide", "parts"),
        default="train",
        help="which object instances (wide: the wider family's training members, wide_0..15; parts: the train_, wide_ "
        "and shop_ training members, for the part network)",
    )
    parser.add_argument("--parts", action="store_true", help="also each object's part window, for the part network")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=segmentation_data.DEFAULT_DATASET)
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (or a local Ray's CPUs with --ray)")
    parser.add_argument(
        "--ray",
        nargs="?",
        const="",
        default=None,
        metavar="ADDRESS",
        help="render each scene as a Ray task: on a local Ray without ADDRESS, or on the cluster at ADDRESS ('auto')",
    )
    parser.add_argument(
        "--crowded", action="store_true", help="cluttered tables: up to 3 objects, distractors next to them (bowls too)"
    )
    add_sensor_option(parser)
    args = parser.parse_args()
    if args.frames < 1 or args.frames_per_scene < 1 or args.jobs < 1:
        parser.error("--frames, --frames-per-scene and --jobs must be positive")
    run_jobs = segmentation_data.render_here
    if args.ray is not None or args.jobs > 1:

        def run_jobs(jobs):
            return fan_out(segmentation_data.render_scene, jobs, args.jobs, args.ray)

    dataset = segmentation_data.generate(
        with_sensor(load_scenario(), args.sensor),
        args.frames,
        args.frames_per_scene,
        args.split,
        args.seed,
        run_jobs,
        crowded=args.crowded,
        parts=args.parts,
    )
    segmentation_data.save(args.out, dataset)
    print(f"wrote {args.out}: {args.frames} {'crowded ' if args.crowded else ''}frames of {args.split} instances")


if __name__ == "__main__":
    main()
