"""Draws what part perception makes of one view: the part network's labels, and the grasp frames built on the
handles it saw, beside the object's true grasps (green: for judging only, never used by the pick).

python scripts/draw_part_grasps.py --object watering_can --instance shop_104 --out docs/part_grasps.png
python scripts/draw_part_grasps.py --object drill --instance shop_101 --yaw 0.25 --out drill_parts.png
python scripts/draw_part_grasps.py --object watering_can --object-file held_out/watering_can/held_out_slim_can.obj

A user's mesh (--object-file: OBJ/PLY/STL/GLB, its units and up axis read as a pick reads them) has its true grasps
drawn where an info.yaml lies beside it (make_unfamiliar_objects.py and make_shop_held_out.py write one).
"""

import argparse
from pathlib import Path

from diagrams.benchmarks.part_drawing import draw_part_view
from diagrams.benchmarks.part_perception import perceive_view
from diagrams.benchmarks.registration import true_grasps
from diagrams.generation.objects.library import resolve_object
from diagrams.scenario import ObjectConfig, load_scenario


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--object", default="watering_can", help="category: watering_can or drill")
    parser.add_argument("--instance", default="shop_104", help="a generated instance (default: a shop can, unseen)")
    parser.add_argument("--object-file", type=Path, help="a mesh of the category instead of a generated instance")
    parser.add_argument("--mesh-units", default="auto", choices=("auto", "m", "cm", "mm", "in"))
    parser.add_argument("--mesh-up", default="auto", choices=("auto", "z", "y"))
    parser.add_argument("--yaw", type=float, default=0.0, help="rad, from the category's presentation")
    parser.add_argument("--seed", type=int, default=3, help="the scene's and the sensor noise's seed")
    parser.add_argument("--out", type=Path, default=Path("part_grasps.png"))
    args = parser.parse_args()
    name, model = args.instance, None
    if args.object_file:
        if not args.object_file.is_file():
            parser.error(f"--object-file: no such file {args.object_file}")
        name = args.object_file.stem
        config = ObjectConfig(category=args.object, file=str(args.object_file), units=args.mesh_units, up=args.mesh_up)
        resolved = resolve_object(config)  # (the SDF a pick would simulate, and the info.yaml beside the mesh)
        model, true_O = resolved.model_file, resolved.info.control_poses() if resolved.info else {}
    else:
        true_O = true_grasps(args.object, args.instance)
    view = perceive_view(load_scenario(), args.object, name, args.yaw, args.seed, model)
    print(view.grasps.message)
    title = f"{args.object}/{name}, yaw {args.yaw:+.2f} rad, kinect_v2 sensor model, seed {args.seed}"
    draw_part_view(view, true_O, args.object, title, args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
