"""Draws one single-view registration of an object outside the shape space's family: the seen points, the latent fit
alone, the fit with the shape's scale, and the pick's (each grasp also moved across its handle onto the one seen:
handle_centring), with their grasp frames beside the true ones.

python scripts/make_unfamiliar_objects.py --out held_out
python scripts/draw_unfamiliar_fit.py held_out/watering_can/held_out_squat_can.obj --out docs/unfamiliar_fit.png
python scripts/draw_unfamiliar_fit.py held_out/watering_can/held_out_slim_can.obj --pick-frame --yaw 0.25 --seed 12 \
    --mass 0.9 --out docs/handle_centring.png      # the first frame of evaluate.py's pick 12 of the held-out cans
"""

import argparse
import dataclasses
import textwrap
from pathlib import Path
from unittest import mock

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from diagrams.benchmarks.pick_frames import first_pick_frame  # noqa: E402
from diagrams.cli import with_sensor  # noqa: E402
from diagrams.evaluation import make_trials  # noqa: E402
from diagrams.generation.objects import catalog  # noqa: E402
from diagrams.generation.objects.library import load_info, mesh_to_sdf  # noqa: E402
from diagrams.generation.synthetic_scenes import SyntheticScene  # noqa: E402
from diagrams.perception import MakePoseEstimator  # noqa: E402
from diagrams.scenario import load_scenario  # noqa: E402
from systems.messages import Segmentation  # noqa: E402
from systems.perception.rgbd_noise import noisy_depth, sensor_model  # noqa: E402
from systems.perception.shape_registrar import scale_prior, shape_space_file  # noqa: E402
from systems.shape_space import grasp_placement  # noqa: E402
from systems.shape_space.registration import Registrar  # noqa: E402
from systems.shape_space.space import GRASP_NAMES, ShapeSpace  # noqa: E402

XY = (0.73, 0.0)  # m, where the scenario puts the object


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("mesh", type=Path, help="an OBJ with <name>.info.yaml beside it (its true grasps)")
    parser.add_argument("--category", default="watering_can")
    parser.add_argument("--yaw", type=float, default=0.0, help="about the presentation, rad")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument(
        "--pick-frame",
        action="store_true",
        help="register the first frame an autonomous pick of the object sees (the segmenter's mask, the paper's "
        "registration yaw noise; as benchmark_registration.py --pick-frames) instead of a rendered view",
    )
    parser.add_argument("--mass", type=float, help="kg, the object's mass in the pick (with --pick-frame)")
    parser.add_argument("--out", type=Path, default=Path("unfamiliar_fit.png"))
    args = parser.parse_args()
    if args.mass is not None and not (args.pick_frame and args.mass > 0):
        parser.error("--mass is a positive mass in kg, with --pick-frame")

    if args.pick_frame:
        estimate, X_WO_true = pick_frame(args)
    else:
        estimate, X_WO_true = rendered_view(args)
    draw(args, estimate, X_WO_true)


def pick_frame(args):
    """The ObjectEstimate the pick's registrar gets for its first frame, and the object's pose X_WO then."""
    base = with_sensor(load_scenario(), "kinect_v2")
    base = dataclasses.replace(base, random_seed=args.seed)
    mass = {} if args.mass is None else {"mass": args.mass}
    objects = {args.mesh.stem: {"file": str(args.mesh), **mass}}
    (trial,) = make_trials(base, args.category, objects, 1, [args.yaw])
    return first_pick_frame(trial.scenario)


def rendered_view(args):
    """A view of the object rendered at the scenario's place with true masks and the kinect_v2 sensor model, its
    ObjectEstimate from the pose estimator, and the object's pose X_WO."""
    scenario = load_scenario()
    rng = np.random.default_rng(args.seed)
    sdf = mesh_to_sdf(args.mesh, 1.0, 1.0, args.category)
    scene = SyntheticScene(
        scenario, rng, cameras=1, camera_jitter=False, classes=("background", args.category),
        models={args.category: [(args.mesh.stem, sdf)]},
    )  # fmt: skip
    yaw = catalog.presentation_yaw(args.category) + args.yaw
    frame = scene.render(placement=(args.category, args.mesh.stem, yaw, np.array(XY)))
    X_WO_true = frame.objects[0][2]
    intrinsics = scenario.camera.MakeCameras()[1].core().intrinsics()
    depth = noisy_depth(frame.depth, frame.rgb, intrinsics, sensor_model("kinect_v2"), rng)
    mask = frame.labels > 0
    estimate = MakePoseEstimator(scenario).estimate(
        Segmentation(True, args.category, mask, int(mask.sum())), depth, frame.X_WC
    )
    return estimate, X_WO_true


def draw(args, estimate, X_WO_true):
    """The three fits of the estimate's points beside each other, side and top views in O."""
    space = ShapeSpace.load(shape_space_file(args.category))
    fits = {  # title: (registrar, grasps centred on their handles)
        "latent fit alone": (Registrar(space, scale_prior=None), False),
        "with the shape's scale": (Registrar(space, scale_prior=scale_prior(args.category)), False),
        "and each grasp centred on its handle": (Registrar(space, scale_prior=scale_prior(args.category)), True),
    }
    truth = {n: X_WO_true @ X for n, X in load_info(args.mesh.with_suffix(".info.yaml")).control_poses().items()}
    to_O = X_WO_true.inverse()
    seen_O = to_O.multiply(estimate.points_W.T).T

    figure, axes = plt.subplots(2, 3, figsize=(16, 8.5))
    for column, (title, (registrar, centred)) in enumerate(fits.items()):
        centring = grasp_placement.handle_centring if centred else lambda *args: np.zeros(3)
        with mock.patch.object(grasp_placement, "handle_centring", centring):
            result = registrar.register(estimate.points_W, estimate.X_WO, estimate.viewpoint_W, estimate.view)
        shape_O = to_O.multiply(result.reconstructed_W.T).T
        errors = [np.linalg.norm(result.grasp_poses_W[n].translation() - truth[n].translation()) for n in GRASP_NAMES]
        verdict = result.poor_fit or "grasps handed on"
        for row, (i, j, plane) in enumerate(((0, 2, "x-z (side)"), (0, 1, "x-y (top)"))):
            ax = axes[row, column]
            ax.scatter(shape_O[::3, i], shape_O[::3, j], s=1, c="0.7", label="fitted shape")
            ax.scatter(seen_O[::2, i], seen_O[::2, j], s=1, c="tab:blue", label="seen points")
            for name in GRASP_NAMES:
                fitted = to_O.multiply(result.grasp_poses_W[name].translation())
                true = to_O.multiply(truth[name].translation())
                ax.plot(*fitted[[i, j]], "x", c="tab:red", ms=10, mew=2)
                ax.plot(*true[[i, j]], "o", c="tab:green", ms=9, mfc="none", mew=2)
            ax.set_aspect("equal")
            ax.set_xlabel(f"{plane}, object frame (m)")
            if row == 0:
                ax.set_title(
                    f"{title}\n{100 * result.inlier_share:.0f}% inliers, grasps {1000 * errors[0]:.0f} / "
                    f"{1000 * errors[1]:.0f} mm off; scale {np.round(result.scale, 2).tolist()}\n"
                    + "\n".join(textwrap.wrap(verdict, 70)[:3]),
                    fontsize=9,
                )
    axes[0, 0].plot([], [], "x", c="tab:red", label="fitted grasp")
    axes[0, 0].plot([], [], "o", c="tab:green", mfc="none", label="true grasp")
    axes[0, 0].legend(loc="lower left", fontsize=8, markerscale=3)
    view = "the pick's first frame" if args.pick_frame else "one view"
    figure.suptitle(f"{args.mesh.stem}, {view} (kinect_v2 sensor model), yaw {args.yaw:+.2f} rad", fontsize=11)
    figure.tight_layout()
    figure.savefig(args.out, dpi=80)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
