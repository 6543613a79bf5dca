"""Draws what part perception makes of one view: the part network's labels, and the grasp frames built on the
handles it saw, beside the object's true grasps (green: for judging only, never used by the pick).

python scripts/draw_part_grasps.py --object watering_can --instance shop_104 --out docs/part_grasps.png
python scripts/draw_part_grasps.py --object drill --instance shop_101 --yaw 0.25 --out drill_parts.png
"""

import argparse
from pathlib import Path

from diagrams.benchmarks.part_drawing import draw_part_view
from diagrams.benchmarks.part_perception import perceive_view
from diagrams.benchmarks.registration import true_grasps
from diagrams.scenario import load_scenario


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--object", default="watering_can", help="category: watering_can or drill")
    parser.add_argument("--instance", default="shop_104", help="a generated instance (default: a shop can, unseen)")
    parser.add_argument("--yaw", type=float, default=0.0, help="rad, from the category's presentation")
    parser.add_argument("--seed", type=int, default=3, help="the scene's and the sensor noise's seed")
    parser.add_argument("--out", type=Path, default=Path("part_grasps.png"))
    args = parser.parse_args()
    view = perceive_view(load_scenario(), args.object, args.instance, args.yaw, args.seed)
    print(view.grasps.message)
    title = f"{args.object}/{args.instance}, yaw {args.yaw:+.2f} rad, kinect_v2 sensor model, seed {args.seed}"
    draw_part_view(view, true_grasps(args.object, args.instance), args.object, title, args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
