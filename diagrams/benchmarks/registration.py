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
"""

import argparse
import dataclasses
import logging
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import pycpd
import trimesh
import yaml
from build_shape_space import build_from_folder, folder_copies, pose_entries, sample_mesh
from json_report import write_json
from pydrake.math import RigidTransform
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import Context, Diagram
from scenario_options import add_sensor_option, with_sensor
from scipy.spatial import cKDTree

from diagrams.autonomous_pick import PERCEIVE_AT_S, MakePickDiagram
from diagrams.evaluation import PAPER_YAWS, file_objects, make_trials
from diagrams.generation.objects import catalog
from diagrams.generation.objects.library import generated_instance_directory, load_info, mesh_to_sdf
from diagrams.generation.synthetic_scenes import SyntheticScene
from diagrams.perception import MakePoseEstimator
from diagrams.pick_simulation import object_body, station_plant
from diagrams.scenario import Scenario, load_scenario, overlay_scenario
from systems.messages import ObjectEstimate, Segmentation
from systems.perception.rgbd_noise import RgbdNoiseParameters, noisy_depth, sensor_model
from systems.perception.shape_registrar import registrar_of, shape_space_file, wider_shape_space_file
from systems.shape_space.cpd import deformable_cpd, thinned
from systems.shape_space.space import ShapeSpace, choose_canonical

NOMINAL_XY = (0.73, 0.0)  # m, where the scenario puts the object
DEPTH_NOISE = 0.002  # m, standard deviation
TEST_INSTANCES = ("test_0", "test_1", "test_2")
# grasp_*: the mean over the four control poses; grasp_frame_*: the two grasp frames alone.
METRICS = (
    "grasp_translation_error_m",
    "grasp_frame_translation_error_m",
    "grasp_across_handle_max_m",
    "grasp_angle_error_rad",
    "chamfer_m",
    "registration_s",
)
# grasp_off: a grasp frame more than GRASP_OFF_M from the truth; handed_on_off: so, and not named a poor fit (the
# pick would go on with it).
COUNTS = ("flipped", "poor_fit", "grasp_off", "handed_on_off")
GRASP_OFF_M = 0.02
FRAME_POLL_S = 0.01  # s: the pick's simulation steps while it waits for its first frame


def true_grasps(category: str, instance: str):
    return load_info(generated_instance_directory(category, instance) / "info.yaml").control_poses()


def pose_errors(X_est, X_true) -> tuple[float, float]:
    translation = float(np.linalg.norm(X_est.translation() - X_true.translation()))
    angle = float(X_est.rotation().InvertAndCompose(X_true.rotation()).ToAngleAxis().angle())
    return translation, angle


def handle_offsets(X_est, X_true) -> tuple[float, float]:
    """How far (m) a grasp frame's origin is from the true one along the true handle's axis x_G, and across it."""
    offset = X_est.translation() - X_true.translation()
    axis = X_true.rotation().matrix()[:, 0]
    along = float(offset @ axis)
    return abs(along), float(np.linalg.norm(offset - along * axis))


def chamfer_to_mesh(points: np.ndarray, mesh: trimesh.Trimesh, samples: int = 20000) -> float:
    """Symmetric Chamfer distance (m) between points and a true surface: the mean of the points' distances
    to the surface and of a dense even sampling of the surface's distances to the points."""
    to_surface = trimesh.proximity.closest_point(mesh, points)[1].mean()
    dense = trimesh.sample.sample_surface_even(mesh, samples, seed=0)[0]
    return 0.5 * float(to_surface + cKDTree(points).query(dense)[0].mean())


def space_files(category: str, space_dir: Path | None) -> tuple[Path, Path | None]:
    """The category's space and wider space: models/' (the wider one where shipped), or those in `space_dir`."""
    if space_dir is None:
        return shape_space_file(category), wider_shape_space_file(category)
    return space_dir / shape_space_file(category).name, wider_shape_space_file(category, space_dir)


def judged_row(result, X_WO_initial, X_WO_true, true: dict, mesh: trimesh.Trimesh) -> dict:
    """A registration judged on ground truth: its grasps against the true control poses (`true`, X_OG by name), its
    reconstruction against the true surface (`mesh`, in O), its initial and final pose against X_WO_true."""
    rotation_error = pose_errors(result.X_WO, X_WO_true)[1]  # (over 90 deg: registered end for end)
    reconstructed_O = X_WO_true.inverse().multiply(result.reconstructed_W.T).T
    errors = {name: pose_errors(result.grasp_poses_W[name], X_WO_true @ X_OG) for name, X_OG in true.items()}
    row = {
        "xyz": X_WO_true.translation().tolist(),  # where the object stood (W, m)
        "initial_translation_error_m": pose_errors(X_WO_initial, X_WO_true)[0],
        "initial_yaw_error_rad": pose_errors(X_WO_initial, X_WO_true)[1],
        "grasp_translation_error_m": float(np.mean([e[0] for e in errors.values()])),
        "grasp_angle_error_rad": float(np.mean([e[1] for e in errors.values()])),
        "grasp_frame_translation_error_m": float(np.mean([errors[n][0] for n in ("left_grasp", "right_grasp")])),
        "grasp_frame_errors_m": {n: errors[n][0] for n in ("left_grasp", "right_grasp")},
        "chamfer_m": chamfer_to_mesh(reconstructed_O, mesh),
        "rotation_error_rad": rotation_error,
        "flipped": rotation_error > np.pi / 2,
        "poor_fit": bool(result.poor_fit),
        "inlier_share": result.inlier_share,
        "grasp_support": {name: share for name, share in result.grasp_support.items()},
    }
    # Across its handle (off the true handle's axis x_G) a grasp misses; along it, it may still hold.
    across = [handle_offsets(result.grasp_poses_W[n], X_WO_true @ true[n])[1] for n in ("left_grasp", "right_grasp")]
    row["grasp_across_handle_m"] = dict(zip(("left_grasp", "right_grasp"), across, strict=True))
    row["grasp_across_handle_max_m"] = max(across)
    row["grasp_off"] = max(errors[n][0] for n in ("left_grasp", "right_grasp")) > GRASP_OFF_M
    row["handed_on_off"] = row["grasp_off"] and not row["poor_fit"]
    return row


def log_row(trial: int, row: dict, result) -> None:
    logging.info(
        "%2d %-12s %s  grasp %.1f mm %.1f deg  chamfer %.1f mm  %.2f s%s",
        trial,
        row["category"],
        row["instance"],
        1000 * row["grasp_translation_error_m"],
        np.degrees(row["grasp_angle_error_rad"]),
        1000 * row["chamfer_m"],
        row["registration_s"],
        ("  FLIPPED" if row["flipped"] else "") + ("  " + result.poor_fit if result.poor_fit else ""),
    )
    frames, across = row["grasp_frame_errors_m"], row["grasp_across_handle_m"]
    logging.info(
        "   inliers %.0f%%; grasp frames %.1f / %.1f mm (across the handle %.1f / %.1f mm)",
        100 * result.inlier_share,
        1000 * frames["left_grasp"],
        1000 * frames["right_grasp"],
        1000 * across["left_grasp"],
        1000 * across["right_grasp"],
    )


def registration_trials(
    trials: int,
    seed: int,
    instances=TEST_INSTANCES,
    categories=tuple(catalog.CATEGORIES),
    space_dir: Path | None = None,
    sensor: RgbdNoiseParameters | None = None,
    files: list[Path] | None = None,
    part_prior: float | None = None,
):
    """One row per trial. sensor: the RGB-D sensor model's parameters (None: 2 mm Gaussian depth noise). Its
    noise comes from a stream of its own, [seed, trial]: the scenes and poses are those of a run without it.
    files: a user's meshes of categories[0] (each with <name>.info.yaml beside it: the true grasps) instead of
    generated instances."""
    scenario = load_scenario()
    intrinsics = scenario.camera.MakeCameras()[1].core().intrinsics()
    rng = np.random.default_rng(seed)
    estimator = MakePoseEstimator(scenario)
    registrars = {c: registrar_of(c, *space_files(c, space_dir), part_prior=part_prior) for c in categories}
    # (category, instance) -> (its true control poses, the folder of its visual.obj)
    models, truth = None, {}
    if files:
        (category,) = categories
        models = {category: [(path.stem, mesh_to_sdf(path, 1.0, 1.0, category)) for path in files]}
        instances = [path.stem for path in files]
        for path, (_, sdf) in zip(files, models[category], strict=True):
            truth[(category, path.stem)] = (load_info(path.with_suffix(".info.yaml")).control_poses(), sdf.parent)
    else:
        for category in categories:
            for instance in instances:
                directory = generated_instance_directory(category, instance)
                truth[(category, instance)] = (true_grasps(category, instance), directory)
    meshes = {}
    rows = []
    scene = None
    for trial in range(trials):
        if trial % 10 == 0:
            scene = SyntheticScene(
                scenario,
                rng,
                cameras=1,
                camera_jitter=False,
                instances=instances,
                classes=("background", *categories),
                models=models,
            )
        category = categories[trial % len(categories)]
        instance = instances[(trial // len(categories)) % len(instances)]
        yaw = catalog.presentation_yaw(category) + rng.choice([-0.25, 0.0, 0.25]) + rng.uniform(-0.2, 0.2)
        xy = np.array(NOMINAL_XY) + rng.uniform(-0.03, 0.03, 2)
        frame = scene.render(placement=(category, instance, yaw, xy))
        X_WO_true = frame.objects[0][2]
        mask = frame.labels > 0
        if sensor is None:
            depth = frame.depth + rng.normal(0, DEPTH_NOISE, frame.depth.shape).astype(np.float32)
        else:
            depth = noisy_depth(frame.depth, frame.rgb, intrinsics, sensor, np.random.default_rng([seed, trial]))
        estimate = estimator.estimate(Segmentation(True, category, mask, int(mask.sum())), depth, frame.X_WC)
        start = time.perf_counter()
        result = registrars[category].register(estimate.points_W, estimate.X_WO, estimate.viewpoint_W, estimate.view)
        seconds = time.perf_counter() - start

        if (category, instance) not in meshes:
            meshes[(category, instance)] = trimesh.load(truth[(category, instance)][1] / "visual.obj", force="mesh")
        row = judged_row(result, estimate.X_WO, X_WO_true, truth[(category, instance)][0], meshes[(category, instance)])
        rows.append({"category": category, "instance": instance, "yaw": float(yaw), "registration_s": seconds, **row})
        log_row(trial, rows[-1], result)
    return rows


def pick_frame_trials(
    base: Scenario,
    category: str,
    objects: dict[str, dict],
    trials: int,
    yaws,
    space_dir: Path | None = None,
    part_prior: float | None = None,
):
    """One row per pick of evaluate.py's campaign (make_trials: every object at every yaw, `trials` each, pick n
    with the seed base.random_seed + n): the registration of the first frame the autonomous pick itself takes
    (the station's camera and sensor model, the segmenter's mask, the pose estimator, the paper's registration
    yaw noise), without running the pick past it. objects: evaluate.py's (file_objects, or instances). A frame in
    which perception finds no object is a row with "found": False and the reason (the pick would stop there)."""
    # The pick registers the object to the category perception gives it (the network's, or the one the user named).
    registrars = {c: registrar_of(c, *space_files(c, space_dir), part_prior=part_prior) for c in catalog.CATEGORIES}
    rows, meshes = [], {}
    for n, trial in enumerate(make_trials(base, category, objects, trials, yaws)):
        scenario = trial.scenario
        estimate, X_WO_true = first_pick_frame(scenario)
        pick = {"category": category, "instance": trial.name, "yaw": trial.yaw, "seed": scenario.random_seed}
        if not estimate.found:
            logging.warning(
                "%2d %s at yaw %+.2f: perception found no object (%s)", n, trial.name, trial.yaw, estimate.message
            )
            rows.append({**pick, "found": False, "message": estimate.message})
            continue
        if estimate.category not in registrars:  # (a taught category the network knows: no space here)
            message = f"perceived as {estimate.category!r}, a category this benchmark has no space for"
            logging.warning("%2d %s at yaw %+.2f: %s", n, trial.name, trial.yaw, message)
            rows.append({**pick, "found": False, "message": message})
            continue
        if scenario.object.file:
            path = Path(scenario.object.file)
            true, mesh_file = load_info(path.with_suffix(".info.yaml")).control_poses(), path
        else:
            true = true_grasps(category, scenario.object.instance)
            mesh_file = generated_instance_directory(category, scenario.object.instance) / "visual.obj"
        if mesh_file not in meshes:
            meshes[mesh_file] = trimesh.load(mesh_file, force="mesh")
        start = time.perf_counter()
        result = registrars[estimate.category].register(
            estimate.points_W, estimate.X_WO, estimate.viewpoint_W, estimate.view
        )
        seconds = time.perf_counter() - start
        row = judged_row(result, estimate.X_WO, X_WO_true, true, meshes[mesh_file])
        rows.append({**pick, "found": True, "perceived_category": estimate.category, "registration_s": seconds, **row})
        log_row(n, rows[-1], result)
    return rows


def first_pick_frame(scenario: Scenario) -> tuple[ObjectEstimate, RigidTransform]:
    """The ObjectEstimate the autonomous pick's registrar is given for its first frame (after the registration yaw
    noise), and the object's true pose X_WO then (as it settled)."""
    diagram, context = pick_at_first_frame(scenario)
    registrar = diagram.GetSubsystemByName("perception").GetSubsystemByName("shape_registrar")
    plant = station_plant(diagram)
    X_WO = object_body(plant).EvalPoseInWorld(plant.GetMyContextFromRoot(context))
    return registrar.GetInputPort("estimate").Eval(registrar.GetMyContextFromRoot(context)), X_WO


def pick_at_first_frame(scenario: Scenario) -> tuple[Diagram, Context]:
    """The pick diagram and its context, simulated until perception has latched its first frame."""
    diagram = MakePickDiagram(scenario)
    simulator = Simulator(diagram)
    ApplySimulatorConfig(scenario.simulator_config, simulator)
    perception = diagram.GetSubsystemByName("perception")
    context = simulator.get_mutable_context()
    frame_id = perception.GetOutputPort("frame_id")
    t = 0.0
    logging.disable(logging.WARNING)  # (the pick's own supervisor reports its registration of the frame too)
    try:
        while frame_id.Eval(perception.GetMyContextFromRoot(context))[0] < 1:
            if t > PERCEIVE_AT_S + 1.0:
                raise RuntimeError("the pick's perception latched no frame")
            t += FRAME_POLL_S
            simulator.AdvanceTo(t)
    finally:
        logging.disable(logging.NOTSET)
    return diagram, context  # (the context keeps its simulator alive)


def folder_spaces(annotation: str, directory: Path, scaled_copies: dict[str, int]) -> dict:
    """Builds each category's space through the user's path: its 8 training meshes exported to a folder, with
    only the canonical model (their medoid) annotated ("canonical") or all of them ("all"), into `directory`
    (with scaled_copies[category] stretched copies of each, build_shape_space.py's --scaled-copies).
    Returns how far the propagated grasp frames were from the true ones, per category (errors in m and rad)."""
    propagation = {}
    for category in catalog.CATEGORIES:
        folder = directory / category
        folder.mkdir(parents=True, exist_ok=True)
        names = [n for n in catalog.instance_names(category) if n.startswith("train")]
        for name in names:
            shutil.copy(generated_instance_directory(category, name) / "visual.obj", folder / f"{name}.obj")
        canonical = choose_canonical({n: thinned(sample_mesh(folder / f"{n}.obj"), 2000) for n in names})
        spec = {"canonical": f"{canonical}.obj", "poses": pose_entries(true_grasps(category, canonical))}
        if annotation == "all":
            spec["others"] = {f"{n}.obj": pose_entries(true_grasps(category, n)) for n in names if n != canonical}
        poses_file = directory / f"{category}_poses.yaml"
        poses_file.write_text(yaml.safe_dump(spec))
        logging.info("%s: 8 training meshes, annotated: %s", category, annotation)
        space = build_from_folder(folder, poses_file, category, scaled_copies=scaled_copies[category])
        space.save(directory / shape_space_file(category).name)
        errors = [  # the folder keeps the generated models' shared frame: C is every model's O
            pose_errors(poses[name], true_grasps(category, Path(model).stem)[name])
            for model, poses in space.propagated.items()
            for name in ("left_grasp", "right_grasp")
        ]
        if errors:
            translation, angle = np.array(errors).T
            propagation[category] = {
                "models": len(space.propagated),
                "translation_m_median": float(np.median(translation)),
                "translation_m_max": float(translation.max()),
                "angle_rad_median": float(np.median(angle)),
                "angle_rad_max": float(angle.max()),
            }
            logging.info(
                "%s: grasp frames propagated to %d models: %.1f mm (max %.1f), %.1f deg (max %.1f) from the truth",
                category,
                len(space.propagated),
                1000 * np.median(translation),
                1000 * translation.max(),
                np.degrees(np.median(angle)),
                np.degrees(angle.max()),
            )
    return propagation


def smooth_warp(points: np.ndarray) -> np.ndarray:
    return points + 0.02 * np.column_stack(
        [np.sin(8 * points[:, 1]), np.cos(7 * points[:, 0]) - 1, np.sin(6 * points[:, 2])]
    )


def cpd_comparison(sizes, beta: float = 0.1, lam: float = 2.0, iterations: int = 50):
    """Both implementations, the same problem, parameters and number of iterations."""
    space = ShapeSpace.load(shape_space_file("watering_can"))
    mesh_points = space.canonical_points
    rows = []
    for size in sizes:
        rng = np.random.default_rng(size)
        source = mesh_points[rng.choice(len(mesh_points), size, replace=len(mesh_points) < size)]
        source = source + rng.normal(0, 1e-3, source.shape)
        truth = smooth_warp(source)
        target = truth[rng.permutation(size)]
        start = time.perf_counter()
        ours = deformable_cpd(source, target, beta=beta, lam=lam, max_iterations=iterations, tolerance=0.0)
        ours_s = time.perf_counter() - start
        reference = pycpd.DeformableRegistration(
            X=target, Y=source, beta=beta, alpha=lam, max_iterations=iterations, tolerance=0.0
        )
        start = time.perf_counter()
        reference_points, _ = reference.register()
        reference_s = time.perf_counter() - start
        row = {
            "points": size,
            "iterations": iterations,
            "ours_s": ours_s,
            "pycpd_s": reference_s,
            "speedup": reference_s / ours_s,
            "ours_error_m": float(np.linalg.norm(ours.transformed - truth, axis=1).mean()),
            "pycpd_error_m": float(np.linalg.norm(reference_points - truth, axis=1).mean()),
        }
        rows.append(row)
        logging.info("CPD %d points: ours %.2f s, pycpd %.2f s (%.1fx)", size, ours_s, reference_s, row["speedup"])
    return rows


def main():
    logging.basicConfig(level=logging.INFO, format="%(message)s")
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
        default=list(TEST_INSTANCES),
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
    if args.part_prior is not None and not args.part_prior > 0:
        parser.error(f"--part-prior must be a positive distance in metres, got {args.part_prior}")
    if args.trials is not None and args.trials < 1:
        parser.error(f"--trials must be 1 or more, got {args.trials}")
    if args.cpd_sizes is None:
        args.cpd_sizes = [] if args.pick_frames else [500, 1000, 2000]
    sensor = sensor_model(args.sensor)
    space_dir, propagation, copies = args.space_dir, {}, {}
    if args.annotation:
        space_dir = Path(tempfile.mkdtemp(prefix="folder_spaces_"))
        copies = {c: folder_copies(c) if args.scaled_copies is None else args.scaled_copies for c in catalog.CATEGORIES}
        propagation = folder_spaces(args.annotation, space_dir, copies)
    categories = (args.category,) if args.category else tuple(catalog.CATEGORIES)
    if args.pick_frames:
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
        rows = [
            row
            for category in categories
            for row in pick_frame_trials(base, category, objects, args.trials, args.yaws, space_dir, args.part_prior)
        ]
    else:
        args.trials = args.trials or 30
        args.seed = 7 if args.seed is None else args.seed
        rows = registration_trials(
            args.trials,
            args.seed,
            args.instances,
            categories,
            space_dir=space_dir,
            sensor=sensor,
            files=args.object_files,
            part_prior=args.part_prior,
        )
    cpd_rows = cpd_comparison(args.cpd_sizes)
    results = {"trials": args.trials, "seed": args.seed, "instances": args.instances, "sensor": args.sensor}
    results["views"] = "the picks' first frames (segmenter's masks)" if args.pick_frames else "rendered, true masks"
    if args.pick_frames:
        results["yaws"] = args.yaws
    results["annotation"] = args.annotation or "generated (48 models, all annotated)"
    results["scaled_copies"] = copies
    results["part_prior_m"] = args.part_prior
    results["propagation"] = propagation
    if args.object_files:
        results["instances"] = [str(path) for path in args.object_files]
    results["not_found"] = {
        c: sum(1 for r in rows if r["category"] == c and not r.get("found", True)) for c in categories
    }
    all_rows, rows = rows, [r for r in rows if r.get("found", True)]
    for category in categories:
        subset = [r for r in rows if r["category"] == category]
        for key in METRICS:
            results.setdefault(key + "_median", {})[category] = float(np.median([r[key] for r in subset]))
        for key in COUNTS:
            results.setdefault(key, {})[category] = int(sum(r[key] for r in subset))
    for key in METRICS:
        results[key + "_median"]["all"] = float(np.median([r[key] for r in rows]))
    by_size = {r["points"]: r for r in cpd_rows}
    if 1000 in by_size:
        results["cpd_speedup_vs_pycpd_1000"] = by_size[1000]["speedup"]
    results["cpd"] = cpd_rows
    results["rows"] = all_rows

    print(f"\n{'metric (median)':37s}" + "".join(f" {c:>13s}" for c in categories) + "  target")
    for key, scale, unit, target in (
        ("grasp_translation_error_m", 1000, "mm", "<= 10 mm"),
        ("grasp_frame_translation_error_m", 1000, "mm", ""),
        ("grasp_across_handle_max_m", 1000, "mm", "(the worse grasp, off its handle's axis)"),
        ("grasp_angle_error_rad", 180 / np.pi, "deg", "<= 5 deg"),
        ("chamfer_m", 1000, "mm", "<= 5 mm (<= 6 mm with the sensor)"),
        ("registration_s", 1, "s", "<= 0.5 s"),
    ):
        values = results[key + "_median"]
        label = f"{key} [{unit}]"
        print(f"{label:37s}" + "".join(f" {values[c] * scale:13.2f}" for c in categories) + f"  {target}")
    for key, target in (
        ("flipped", "0 (end for end)"),
        ("poor_fit", "(named failures)"),
        ("grasp_off", f"(a grasp over {100 * GRASP_OFF_M:.0f} cm off)"),
        ("handed_on_off", "0 (such a grasp not named)"),
        ("not_found", "(perception found no object: not registered)"),
    ):
        values = results[key]
        print(f"{key + ' [trials]':37s}" + "".join(f" {values[c]:13d}" for c in categories) + f"  {target}")
    copies = "".join(f", {c}: {n} stretched copies of each" for c, n in results["scaled_copies"].items() if n)
    print(f"(sensor: {args.sensor}; views: {results['views']}; annotated models: {results['annotation']}{copies})")
    if not cpd_rows:
        if args.json:
            write_json(args.json, results)
        return
    header = ("CPD points", "ours s", "pycpd s", "speedup", "ours err mm", "pycpd err mm")
    print("\n" + " ".join(f"{h:>12s}" for h in header))
    for r in cpd_rows:
        print(
            f"{r['points']:12d} {r['ours_s']:12.3f} {r['pycpd_s']:12.3f} {r['speedup']:12.1f} "
            f"{1000 * r['ours_error_m']:12.2f} {1000 * r['pycpd_error_m']:12.2f}"
        )
    if args.json:
        write_json(args.json, results)


if __name__ == "__main__":
    main()
