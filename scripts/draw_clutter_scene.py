"""Draws what the pick saw of a cluttered table: the camera's image with the object it chose and the other objects
it found, and the scene the planner avoided (the points the camera saw, the space hidden behind them) beside the
object's reconstruction and the planned hand paths.

python scripts/draw_clutter_scene.py --object drill --clutter-index 3 --out docs/clutter_scene.png
"""

import argparse
import logging

import matplotlib
import numpy as np
from pydrake.systems.analysis import Simulator

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from diagrams.autonomous_pick import PERCEIVE_AT_S, MakePickDiagram  # noqa: E402
from diagrams.cli import add_scenario_options, scenario_from_args  # noqa: E402
from systems.perception.instances import object_instances  # noqa: E402


def main():
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scenario_options(parser)
    parser.add_argument("--out", default="clutter_scene.png", help="the figure (.png)")
    args = parser.parse_args()
    if args.scene == "single":
        args.scene = "clutter"
    scenario = scenario_from_args(args)
    diagram = MakePickDiagram(scenario)
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    # The first plan (the reach) exists once the planner's latency has passed after perception.
    simulator.AdvanceTo(PERCEIVE_AT_S + scenario.planning.latency_s + 0.1)
    perception = diagram.GetSubsystemByName("perception")
    seen_context = perception.GetMyContextFromRoot(context)
    latch = perception.GetSubsystemByName("camera_latch")
    latch_context = latch.GetMyContextFromRoot(context)
    rgb = np.asarray(latch.GetOutputPort("color_image").Eval(latch_context).data)[:, :, :3].copy()
    depth = np.asarray(latch.GetOutputPort("depth_image").Eval(latch_context).data)[:, :, 0]
    segmenter = perception.GetSubsystemByName("segmenter")
    segmenter_context = segmenter.GetMyContextFromRoot(context)
    labels = segmenter.GetOutputPort("labels").Eval(segmenter_context)
    chosen = segmenter.GetOutputPort("segmentation").Eval(segmenter_context)
    table_view = segmenter.table_view(latch.GetOutputPort("camera_pose").Eval(latch_context))
    instances = object_instances(
        labels, depth, segmenter.classes, segmenter.min_pixels, segmenter.intrinsics, table_view
    )
    scene = perception.GetOutputPort("scene_cloud_W").Eval(seen_context)
    reconstruction = perception.GetOutputPort("reconstructed_cloud_W").Eval(seen_context)
    planner = diagram.GetSubsystemByName("stomp_planner")
    plan = planner.GetOutputPort("plan").Eval(planner.GetMyContextFromRoot(context))

    figure = plt.figure(figsize=(14, 6))
    image = figure.add_subplot(1, 2, 1)
    tinted = rgb.astype(float)
    for instance in instances:  # every object found, outlined by a grey tint
        tinted[instance.mask] = 0.6 * tinted[instance.mask] + 0.4 * np.array([90, 90, 255])
    if chosen.found:
        tinted[chosen.mask] = 0.4 * tinted[chosen.mask] + 0.6 * np.array([40, 220, 40])
    image.imshow(tinted.astype(np.uint8))
    image.set_title(f"camera: {chosen.message}\n(green: the object picked; blue: the other objects found)", fontsize=9)
    image.axis("off")
    axes = figure.add_subplot(1, 2, 2, projection="3d")
    axes.scatter(*scene[::2].T, s=1, c=scene[::2, 2], cmap="Blues", label=f"scene the planner avoids ({len(scene)})")
    axes.scatter(*reconstruction[::3].T, s=1, c="tab:orange", label="the object (registered shape)")
    for side, path in (plan.grasp_paths_W or {}).items():
        axes.plot(*path.T, c="tab:green", lw=2, label=f"{side} hand's planned path")
    axes.view_init(elev=35, azim=-150)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_zlabel("z (m)")
    axes.set_title("the scene cloud (seen surfaces, and the space hidden behind them)", fontsize=9)
    axes.legend(loc="upper left", fontsize=8, markerscale=6)
    figure.tight_layout()
    figure.savefig(args.out, dpi=90)
    print(f"wrote {args.out}: {plan.message if plan.success else 'no plan: ' + plan.message}")


if __name__ == "__main__":
    main()
