"""Benchmarks shape-space registration on single-view clouds of the unseen test instances, and CPD vs pycpd.

Each trial renders one test can or drill at the paper's experiment poses (yaw -0.25, 0
or +0.25 about the presentation, plus uniform +-0.2 rad noise) on a random background,
takes its depth points (true mask) as the RGB-D sensor model reports them (--sensor, by default
kinect_v2: flying pixels, dropouts, axial noise; --no-noise: the renderer's depth with 2 mm Gaussian
noise, as before the sensor model), starts from the PoseEstimator's initial pose and registers,
knowing the camera's position. Errors are against the generator's ground truth: grasp frames (mean
over the four control poses), the symmetric Chamfer distance from the reconstruction to the true
mesh (surface distances both ways), and whether the object was registered end for end (its rotation over
90 deg off). A poor fit (Registration.poor_fit: the pick would stop, named) is counted.

python scripts/benchmark_registration.py --trials 30 --json registration.json
python scripts/benchmark_registration.py --trials 48 --instances extra_101 extra_102 ... --cpd-sizes  # others
python scripts/benchmark_registration.py --trials 30 --no-noise --cpd-sizes                          # perfect depth
python scripts/benchmark_registration.py --trials 18 --annotation canonical --cpd-sizes  # the user's path, 1 annotated

With --pick-frames the views are instead the first frames that evaluate.py's campaign of the same objects, yaws,
seed and --scenario_text would see, pick by pick (the object's mass changes how it settles, so the frame): the
station's camera and sensor model, the segmenter's mask, the pose estimator and the paper's +-0.2 rad registration
yaw noise. Each pick is simulated only until perception latches that frame (a few seconds instead of a whole pick;
the pick registers it once itself on the way), and the frame is registered to the category perception gave it, as
the pick does, with the benchmark's spaces (--space-dir, --part-prior):

python scripts/benchmark_registration.py --pick-frames --category watering_can --object-files cans/*.obj \
    --scenario_text "{object: {mass: 0.9}}"
python scripts/benchmark_registration.py --pick-frames --trials 3 --json F   # the test instances, as evaluate.py
python scripts/benchmark_registration.py --pick-frames --category drill --instances shop_100 shop_101 \
    --frames-cache /tmp/frames      # the first frames kept: a second run registers them again in seconds
"""

import argparse
import dataclasses
import logging
import tempfile
from pathlib import Path

from diagrams.benchmarks import cpd, registration
from diagrams.benchmarks.pick_frames import pick_frame_trials
from diagrams.cli import add_sensor_option, with_sensor, write_json
from diagrams.evaluation import PAPER_YAWS, file_objects
from diagrams.generation.objects import catalog
from diagrams.scenario import load_scenario, overlay_scenario
from systems.perception.rgbd_noise import sensor_model
from systems.shape_space.folder import folder_copies


def parse_args() -> tuple[argparse.ArgumentParser, argparse.Namespace]:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--trials", type=int, help="rendered views in all (default 30); with --pick-frames, per object and yaw (1)"
    )
    parser.add_argument(
        "--seed", type=int, help="default 7; with --pick-frames, the scenario's (as evaluate.py: pick n has seed + n)"
    )
    parser.add_argument(
        "--pick-frames",
        action="store_true",
        help="register the first frames the autonomous picks of evaluate.py's campaign would see (the station's "
        "camera, the segmenter's mask, the paper's +-0.2 rad yaw noise) instead of rendered views with true masks",
    )
    parser.add_argument("--yaws", type=float, nargs="+", help="with --pick-frames (rad; default the paper's three)")
    parser.add_argument(
        "--scenario_text", default="", help="with --pick-frames: YAML overlaid on the scenario, as evaluate.py's"
    )
    parser.add_argument(
        "--instances",
        nargs="+",
        default=list(registration.TEST_INSTANCES),
        help="instances of each category, taken in turn (e.g. extra_101 extra_102: generated on first use)",
    )
    parser.add_argument("--cpd-sizes", type=int, nargs="*", help="default 500 1000 2000; none with --pick-frames")
    parser.add_argument("--space-dir", type=Path, help="read shape_space_<category>.npz from here (default: models/)")
    parser.add_argument(
        "--part-prior",
        type=float,
        help="m: where the scaled fit is poor, also fit each handle's own offset with this prior (Registrar's "
        "part_prior, e.g. 0.03; the pick does not)",
    )
    parser.add_argument(
        "--fit-grasps",
        dest="part_grasps",
        action="store_false",
        help="with --pick-frames: judge the fit's own grasps, not those the pick builds on the handles it saw",
    )
    parser.add_argument(
        "--frames-cache",
        dest="frames_cache",
        type=Path,
        help="with --pick-frames: a folder that keeps each first frame (keyed by the scenario and the networks' "
        "weights, not perception's code: empty it after changing that), so later runs skip the simulation",
    )
    parser.add_argument(
        "--annotation",
        choices=("canonical", "all"),
        help="build the spaces first, as a user's folder of the 8 training meshes with only the canonical model "
        "(their medoid) annotated, or all 8 (default: the spaces in models/, 48 generated and annotated models)",
    )
    parser.add_argument(
        "--object-files",
        dest="object_files",
        type=Path,
        nargs="+",
        help="your own meshes of --category instead (each with <name>.info.yaml beside it: the true grasps)",
    )
    parser.add_argument(
        "--category",
        choices=tuple(catalog.CATEGORIES),
        help="the category of --object-files; with --pick-frames alone, the one category of --instances",
    )
    parser.add_argument(
        "--scaled-copies",
        type=int,
        help="with --annotation: stretched copies of each of the 8 meshes in the spaces (default: "
        "build_shape_space.py's for a folder)",
    )
    add_sensor_option(parser, default="kinect_v2")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    if bool(args.object_files) != bool(args.category) and not (args.pick_frames and args.category):
        parser.error("--object-files and --category go together (--category alone with --pick-frames)")
    if args.scaled_copies is not None and not args.annotation:
        parser.error("--scaled-copies needs --annotation (it builds the spaces from the training meshes)")
    if args.scaled_copies is not None and args.scaled_copies < 0:
        parser.error(f"--scaled-copies must be 0 or more, got {args.scaled_copies}")
    if not args.pick_frames and (args.yaws or args.scenario_text):
        parser.error("--yaws and --scenario_text go with --pick-frames")
    if args.frames_cache and not args.pick_frames:
        parser.error("--frames-cache goes with --pick-frames")
    if args.part_prior is not None and not args.part_prior > 0:
        parser.error(f"--part-prior must be a positive distance in metres, got {args.part_prior}")
    if args.trials is not None and args.trials < 1:
        parser.error(f"--trials must be 1 or more, got {args.trials}")
    if args.cpd_sizes is None:
        args.cpd_sizes = [] if args.pick_frames else [500, 1000, 2000]
    return parser, args


def pick_frame_rows(parser, args, categories, space_dir: Path | None) -> list[dict]:
    """--pick-frames: the rows of the picks' first frames (args.trials, .yaws and .seed set to what they were)."""
    args.trials, args.yaws = args.trials or 1, args.yaws or list(PAPER_YAWS)
    try:
        base = with_sensor(overlay_scenario(load_scenario(), args.scenario_text, "--scenario_text"), args.sensor)
    except ValueError as error:
        parser.error(str(error))
    if args.seed is not None:
        base = dataclasses.replace(base, random_seed=args.seed)
    args.seed = base.random_seed
    if args.object_files:
        objects = file_objects(args.object_files)
    else:
        objects = {name: {"instance": name, "file": ""} for name in args.instances}
    return [
        row
        for category in categories
        for row in pick_frame_trials(
            base,
            category,
            objects,
            args.trials,
            args.yaws,
            space_dir,
            args.part_prior,
            args.part_grasps,
            args.frames_cache,
        )
    ]


def settings(args, copies: dict, propagation: dict) -> dict:
    """The JSON's first keys: what the run was."""
    results = {"trials": args.trials, "seed": args.seed, "instances": args.instances, "sensor": args.sensor}
    results["views"] = "the picks' first frames (segmenter's masks)" if args.pick_frames else "rendered, true masks"
    if args.pick_frames:
        results["yaws"] = args.yaws
    results["annotation"] = args.annotation or "generated (48 models, all annotated)"
    results["scaled_copies"] = copies
    results["part_prior_m"] = args.part_prior
    results["part_grasps"] = args.part_grasps
    results["propagation"] = propagation
    if args.object_files:
        results["instances"] = [str(path) for path in args.object_files]
    return results


def main():
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    parser, args = parse_args()
    sensor = sensor_model(args.sensor)
    space_dir, propagation, copies = args.space_dir, {}, {}
    if args.annotation:
        space_dir = Path(tempfile.mkdtemp(prefix="folder_spaces_"))
        copies = {c: folder_copies(c) if args.scaled_copies is None else args.scaled_copies for c in catalog.CATEGORIES}
        propagation = registration.folder_spaces(args.annotation, space_dir, copies)
    categories = (args.category,) if args.category else tuple(catalog.CATEGORIES)
    if args.pick_frames:
        rows = pick_frame_rows(parser, args, categories, space_dir)
    else:
        args.trials = args.trials or 30
        args.seed = 7 if args.seed is None else args.seed
        rows = registration.registration_trials(
            args.trials,
            args.seed,
            args.instances,
            categories,
            space_dir=space_dir,
            sensor=sensor,
            files=args.object_files,
            part_prior=args.part_prior,
        )
    cpd_rows = cpd.cpd_comparison(args.cpd_sizes)
    results = registration.summarize(settings(args, copies, propagation), rows, cpd_rows, categories)
    registration.print_summary(results, categories, args.sensor)
    if cpd_rows:
        cpd.print_comparison(cpd_rows)
    if args.json:
        write_json(args.json, results)


if __name__ == "__main__":
    main()
