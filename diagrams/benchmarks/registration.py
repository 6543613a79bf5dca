"""The registration benchmark (scripts/benchmark_registration.py): shape-space registration of single-view clouds
of the unseen test instances, judged on the generator's ground truth.

Each trial renders one test can or drill at the paper's experiment poses (yaw -0.25, 0 or +0.25 about the
presentation, plus uniform +-0.2 rad noise) on a random background, takes its depth points (true mask) as the RGB-D
sensor model reports them (kinect_v2 by default: flying pixels, dropouts, axial noise; None: the renderer's depth
with 2 mm Gaussian noise, as before the sensor model), starts from the PoseEstimator's initial pose and registers,
knowing the camera's position. Errors are against the generator's ground truth: grasp frames (mean over the four
control poses), the symmetric Chamfer distance from the reconstruction to the true mesh (surface distances both
ways), and whether the object was registered end for end (its rotation over 90 deg off). A poor fit
(Registration.poor_fit: the pick would stop, named) is counted. The picks' own first frames are
diagrams/benchmarks/pick_frames.py's; CPD beside pycpd is diagrams/benchmarks/cpd.py's.
"""

import logging
import shutil
import time
from pathlib import Path

import numpy as np
import trimesh
import yaml
from scipy.spatial import cKDTree

from diagrams.generation.objects import catalog
from diagrams.generation.objects.instance import ObjectInfo
from diagrams.generation.objects.library import generated_instance_directory, load_info, mesh_to_sdf
from diagrams.generation.synthetic_scenes import SyntheticScene
from diagrams.perception import MakePoseEstimator
from diagrams.scenario import load_scenario
from systems.messages import Segmentation
from systems.perception.rgbd_noise import RgbdNoiseParameters, noisy_depth
from systems.perception.shape_registrar import registrar_of, shape_space_file, wider_shape_space_file
from systems.shape_space.cpd import thinned
from systems.shape_space.folder import build_from_folder, pose_entries, sample_mesh
from systems.shape_space.space import choose_canonical
from systems.shape_space.tool_frame import ToolFrame

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
    "tool_tip_error_m",
    "tool_axis_error_rad",
)
# grasp_off: a grasp frame more than GRASP_OFF_M from the truth; handed_on_off: so, and not named a poor fit (the
# pick would go on with it).
COUNTS = ("flipped", "poor_fit", "grasp_off", "handed_on_off")
GRASP_OFF_M = 0.02


def true_grasps(category: str, instance: str):
    """A generated instance's true control poses, {name: X_OG}."""
    return true_info(category, instance).control_poses()


def true_info(category: str, instance: str) -> ObjectInfo:
    """What the generator knows of a generated instance (its true control poses and tool frame, in O)."""
    return load_info(generated_instance_directory(category, instance) / "info.yaml")


def pose_errors(X_est, X_true) -> tuple[float, float]:
    """How far a pose is from the true one: translation (m) and rotation angle (rad)."""
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


def judged_row(
    result,
    X_WO_initial,
    X_WO_true,
    true: dict,
    mesh: trimesh.Trimesh,
    grasps_W: dict | None = None,
    handed: bool | None = None,
    true_tool: ToolFrame | None = None,
) -> dict:
    """A registration judged on ground truth: its grasps against the true control poses (`true`, X_OG by name), its
    reconstruction against the true surface (`mesh`, in O), its initial and final pose against X_WO_true, its tool
    frame against `true_tool` (in O; None: not judged, the errors None).
    grasps_W: the grasps judged where they are not the registration's (those built on the seen parts:
    seen_part_grasps); handed: whether the pick hands them on (default: unless the fit is poor)."""
    rotation_error = pose_errors(result.X_WO, X_WO_true)[1]  # (over 90 deg: registered end for end)
    reconstructed_O = X_WO_true.inverse().multiply(result.reconstructed_W.T).T
    grasps_W = grasps_W or result.grasp_poses_W
    handed = not result.poor_fit if handed is None else handed
    errors = {name: pose_errors(grasps_W[name], X_WO_true @ X_OG) for name, X_OG in true.items()}
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
        "handed_on": handed,
        "inlier_share": result.inlier_share,
        "grasp_support": {name: share for name, share in result.grasp_support.items()},
    }
    # Across its handle (off the true handle's axis x_G) a grasp misses; along it, it may still hold.
    across = [handle_offsets(grasps_W[n], X_WO_true @ true[n])[1] for n in ("left_grasp", "right_grasp")]
    row["grasp_across_handle_m"] = dict(zip(("left_grasp", "right_grasp"), across, strict=True))
    row["grasp_across_handle_max_m"] = max(across)
    row["grasp_off"] = max(errors[n][0] for n in ("left_grasp", "right_grasp")) > GRASP_OFF_M
    row["handed_on_off"] = row["grasp_off"] and handed
    tool_errors = (None, None)
    if true_tool is not None and result.tool_W is not None:
        tool_errors = result.tool_W.errors(true_tool.moved(X_WO_true))
    row["tool_tip_error_m"], row["tool_axis_error_rad"] = tool_errors
    return row


def log_row(trial: int, row: dict, result) -> None:
    """A view's errors, logged as two lines."""
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
    tool = row["tool_tip_error_m"] is not None
    logging.info(
        "   inliers %.0f%%; grasp frames %.1f / %.1f mm (across the handle %.1f / %.1f mm)%s",
        100 * result.inlier_share,
        1000 * frames["left_grasp"],
        1000 * frames["right_grasp"],
        1000 * across["left_grasp"],
        1000 * across["right_grasp"],
        f"; tool tip {1000 * row['tool_tip_error_m']:.1f} mm, axis {np.degrees(row['tool_axis_error_rad']):.1f} deg"
        if tool
        else "",
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
    # (category, instance) -> (what the generator knows of it: ObjectInfo, the folder of its visual.obj)
    models, truth = None, {}
    if files:
        (category,) = categories
        models = {category: [(path.stem, mesh_to_sdf(path, 1.0, 1.0, category)) for path in files]}
        instances = [path.stem for path in files]
        for path, (_, sdf) in zip(files, models[category], strict=True):
            truth[(category, path.stem)] = (load_info(path.with_suffix(".info.yaml")), sdf.parent)
    else:
        for category in categories:
            for instance in instances:
                directory = generated_instance_directory(category, instance)
                truth[(category, instance)] = (true_info(category, instance), directory)
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
        info = truth[(category, instance)][0]
        row = judged_row(
            result,
            estimate.X_WO,
            X_WO_true,
            info.control_poses(),
            meshes[(category, instance)],
            true_tool=info.tool_frame(),
        )
        rows.append({"category": category, "instance": instance, "yaw": float(yaw), "registration_s": seconds, **row})
        log_row(trial, rows[-1], result)
    return rows


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


def summarize(results: dict, rows: list[dict], cpd_rows: list[dict], categories) -> dict:
    """The run's settings (`results`, kept first) with, per category and over all, the medians of METRICS and the
    COUNTS over the views registered, the views in which perception found no object, CPD's comparison and every
    row."""
    results["not_found"] = {
        c: sum(1 for r in rows if r["category"] == c and not r.get("found", True)) for c in categories
    }
    all_rows, rows = rows, [r for r in rows if r.get("found", True)]
    for category in categories:
        subset = [r for r in rows if r["category"] == category]
        for key in METRICS:
            results.setdefault(key + "_median", {})[category] = median_of(subset, key)
        for key in COUNTS:
            results.setdefault(key, {})[category] = int(sum(r[key] for r in subset))
    for key in METRICS:
        results[key + "_median"]["all"] = median_of(rows, key)
    by_size = {r["points"]: r for r in cpd_rows}
    if 1000 in by_size:
        results["cpd_speedup_vs_pycpd_1000"] = by_size[1000]["speedup"]
    results["cpd"] = cpd_rows
    results["rows"] = all_rows
    return results


def median_of(rows: list[dict], key: str) -> float | None:
    """The median of the rows' `key` where they have one (a tool frame's errors only where both frames are known);
    None where none has."""
    values = [r[key] for r in rows if r.get(key) is not None]
    return float(np.median(values)) if values else None


def print_summary(results: dict, categories, sensor: str) -> None:
    """The medians and counts per category beside their targets, and what the views were."""
    print(f"\n{'metric (median)':37s}" + "".join(f" {c:>13s}" for c in categories) + "  target")
    for key, scale, unit, target in (
        ("grasp_translation_error_m", 1000, "mm", "<= 10 mm"),
        ("grasp_frame_translation_error_m", 1000, "mm", ""),
        ("grasp_across_handle_max_m", 1000, "mm", "(the worse grasp, off its handle's axis)"),
        ("grasp_angle_error_rad", 180 / np.pi, "deg", "<= 5 deg"),
        ("chamfer_m", 1000, "mm", "<= 5 mm (<= 6 mm with the sensor)"),
        ("registration_s", 1, "s", "<= 0.5 s"),
        ("tool_tip_error_m", 1000, "mm", "<= 10 mm (spout tip, bit tip)"),
        ("tool_axis_error_rad", 180 / np.pi, "deg", "<= 3 deg (the bit's axis)"),
    ):
        values = results[key + "_median"]
        label = f"{key} [{unit}]"
        cells = "".join(f" {'-':>13s}" if values[c] is None else f" {values[c] * scale:13.2f}" for c in categories)
        print(f"{label:37s}{cells}  {target}")
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
    print(f"(sensor: {sensor}; views: {results['views']}; annotated models: {results['annotation']}{copies})")
