"""A picture of part perception on one view (scripts/draw_part_grasps.py): the part network's labels over the
colour image, and the grasp frames built on the seen handles beside the true ones."""

import textwrap
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform

from diagrams.benchmarks.part_perception import PerceivedView
from systems.messages import PartRole
from systems.perception.parts import part_name

ROLE_COLOURS = {  # RGB in [0, 1]
    PartRole.BODY: (0.55, 0.55, 0.6),
    PartRole.LEFT_HANDLE: (0.95, 0.45, 0.1),
    PartRole.RIGHT_HANDLE: (0.6, 0.2, 0.85),
    PartRole.TOOL: (0.15, 0.7, 0.3),
}
MARGIN_PX = 30  # around the object's pixels
AXIS_M = 0.04  # drawn length of a grasp frame's axes


def draw_part_view(view: PerceivedView, true_O: dict[str, RigidTransform], category: str, title: str, out: Path):
    """Writes a two-panel PNG: the labels, then the grasp frames (x along the handle, orange; the approach, blue,
    drawn back from the grasp to where the hand comes from) with the true grasps' origins (green; true_O, X_OG by
    name: those it has)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows, cols = np.nonzero(view.segmentation.mask)
    top, bottom = max(rows.min() - MARGIN_PX, 0), min(rows.max() + MARGIN_PX, view.rgb.shape[0])
    left, right = max(cols.min() - MARGIN_PX, 0), min(cols.max() + MARGIN_PX, view.rgb.shape[1])
    rgb = view.rgb[:, :, :3].astype(float) / 255.0
    labelled = rgb.copy()
    if view.segmentation.parts is not None:
        for role, colour in ROLE_COLOURS.items():
            labelled[view.segmentation.parts == role] = 0.3 * rgb[view.segmentation.parts == role] + 0.7 * np.array(
                colour
            )
    figure, (labels_axes, frames_axes) = plt.subplots(1, 2, figsize=(11, 5.2))
    for axes, image in ((labels_axes, labelled), (frames_axes, 0.5 + 0.5 * rgb)):
        axes.imshow(image[top:bottom, left:right], extent=(left, right, bottom, top))
        axes.set_axis_off()
    for role, colour in ROLE_COLOURS.items():
        labels_axes.plot([], [], "s", color=colour, label=part_name(category, role))
    labels_axes.legend(loc="lower left", fontsize=8)
    labels_axes.set_title("the part network's labels", fontsize=10)

    def pixel(p_W):
        x, y, z = view.X_WC.inverse().multiply(p_W)
        K = view.intrinsics
        return K.focal_x() * x / z + K.center_x(), K.focal_y() * y / z + K.center_y()

    for hand in ("left", "right"):
        if f"{hand}_grasp" in true_O:  # (a user's mesh without an info.yaml has none)
            truth = (view.X_WO @ true_O[f"{hand}_grasp"]).translation()
            frames_axes.plot(*pixel(truth), "x", color=(0.1, 0.7, 0.1), markersize=10, mew=2)
        X_WG = view.grasps.poses_W.get(f"{hand}_grasp")
        if X_WG is None:
            continue
        origin, R = X_WG.translation(), X_WG.rotation().matrix()
        along = np.array([pixel(origin - AXIS_M * R[:, 0]), pixel(origin + AXIS_M * R[:, 0])])
        frames_axes.plot(along[:, 0], along[:, 1], "-", color=(1.0, 0.5, 0.0), lw=3)
        approach = np.array([pixel(origin - 1.5 * AXIS_M * R[:, 2]), pixel(origin)])
        frames_axes.annotate(
            "", xy=approach[1], xytext=approach[0], arrowprops={"arrowstyle": "->", "color": "b", "lw": 2}
        )
        frames_axes.plot(*pixel(origin), "o", color="k", markersize=5)
        frames_axes.annotate(hand, pixel(origin), textcoords="offset points", xytext=(6, 6), fontsize=9)
    frames_axes.set_title("grasp frames (orange: along the handle; blue: approach; green x: true)", fontsize=10)
    figure.suptitle("\n".join([title, *textwrap.wrap(view.grasps.message, 150)]), fontsize=9)
    figure.tight_layout()
    figure.savefig(out, dpi=110)
    plt.close(figure)
