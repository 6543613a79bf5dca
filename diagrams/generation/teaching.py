"""Teaches the robot a new familiar category from a folder of the user's models, one of them annotated
(scripts/add_category.py).

The folder and the poses file are build_shape_space.py's (meshes or point clouds sharing one frame, in
metres, centimetres or millimetres, z or y up: read and said, or given by --mesh-units / --mesh-up; the poses
YAML names the canonical model and its control poses, and its tool frame where it has one, in its file's frame
and units). The steps:

  1. the models are read and checked (units, frames); the category's frame O is the folder's frame moved
     so that the canonical model's bottom face is at z = 0 and its extent centred on x = y = 0;
  2. the shape space is built, every model's grasps carried from the canonical one, and drawn (.png);
  3. the canonical model is written as the pose estimator's template and every model as a visual-only
     SDF (point clouds get a Poisson surface) to render from;
  4. synthetic frames of scenes holding every known category are rendered and the segmenter in use is
     fine-tuned with the new class (its classifier widened; the old classes keep their weights), then
     checked on frames of another seed;
  5. the new segmenter and the category's record are written: from then on every pick knows the class.

Everything lands in systems.categories.categories_dir() ($DUALARM_CATEGORIES, default
~/.local/share/dualarm/categories): <name>/ and segmenter.pt. The functions take add_category.py's options
(`args`: an argparse.Namespace).
"""

import json
import logging
import os
import re
import shutil
import time
from pathlib import Path

import numpy as np
import trimesh
from pydrake.math import RigidTransform

from diagrams.cli import with_sensor
from diagrams.generation import segmentation_data
from diagrams.generation.objects.instance import export_obj, object_sdf
from diagrams.generation.objects.library import recentred
from diagrams.scenario import load_scenario
from systems import categories
from systems.perception import segmentation_network, segmenter_training
from systems.shape_space.densify import surface_mesh
from systems.shape_space.drawing import draw_space
from systems.shape_space.file_frame import FileReading
from systems.shape_space.folder import folder_instances, frame_warnings
from systems.shape_space.space import build_shape_space

FINE_TUNE_LEARNING_RATE = 1e-3


def check_name(name: str) -> None:
    """Raises ValueError where `name` cannot name a taught category (the message names --name)."""
    if not re.fullmatch(r"[a-z][a-z0-9_]*", name):
        raise ValueError(f"--name {name!r}: use lower case letters, digits and _ (starting with a letter)")
    if name in categories.GENERATED or name == "background":
        raise ValueError(f"--name {name!r} is taken by a built-in class")


def model_mesh(path: Path, points: np.ndarray, reading: FileReading) -> trimesh.Trimesh:
    """The file's triangle mesh read as `reading` says (metres, z up), or a Poisson surface through its points
    (already so) where it is a point cloud."""
    if path.suffix.lower() != ".pcd":
        mesh = trimesh.load(path, force="mesh")
        if isinstance(mesh, trimesh.Trimesh) and len(mesh.faces):
            mesh.apply_transform(reading.matrix())
            return mesh
    logging.info("%s is a point cloud: its surface is reconstructed for rendering", path.name)
    return surface_mesh(points)


def visual_sdf(mesh: trimesh.Trimesh, directory: Path, name: str) -> Path:
    """A free body with the mesh as its only (visual) geometry: what segmentation frames render."""
    export_obj(mesh, directory / f"{name}.obj")
    box = trimesh.primitives.Box(extents=np.maximum(mesh.extents, 1e-3))
    inertia = box.moment_inertia / box.volume  # of a unit mass filling the model's box: rendering needs no more
    path = directory / f"{name}.sdf"
    path.write_text(object_sdf(name, f"{name}.obj", [], 1.0, mesh.centroid, inertia, (0.6, 0.6, 0.65)))
    return path


def write_models(args, directory: Path):
    """Steps 1-3: the category's shape space, template and training models in `directory`; its record."""
    models = folder_instances(args.folder, args.poses, args.mesh_units or "auto", args.mesh_up or "auto")
    clouds, poses, canonical = models.clouds, models.poses, models.canonical
    if args.align == "none":
        for warning in frame_warnings(clouds, canonical):
            logging.warning("warning: %s; if the models do not share one frame, pass --align vertical", warning)
    lo, hi = clouds[canonical].min(axis=0), clouds[canonical].max(axis=0)
    X_OF = RigidTransform([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])  # the folder's frame F in O
    folder_clouds, clouds = clouds, {name: X_OF.multiply(points.T).T for name, points in clouds.items()}
    poses = {name: {pose: X_OF @ X for pose, X in model_poses.items()} for name, model_poses in poses.items()}
    box_centre = np.mean([(c.min(axis=0) + c.max(axis=0))[:2] / 2 for c in clouds.values()], axis=0)

    logging.info("[2/5] the shape space of %d models (%d annotated)", len(clouds), len(poses))
    tools = {canonical: models.tool.moved(X_OF)} if models.tool else None
    space = build_shape_space(
        args.name, clouds, poses, args.components, canonical=canonical, align=args.align, tools=tools
    )
    space.save(directory / "shape_space.npz")
    draw_space(space, directory / "shape_space.png")

    logging.info("[3/5] the template and %d training models for rendering", len(clouds))
    (directory / "training").mkdir()
    for name in sorted(clouds):
        path = args.folder / name
        mesh = model_mesh(path, folder_clouds[name], models.reading)  # in the folder's frame, metres
        if name == canonical:
            template = mesh.copy()
            template.apply_transform(X_OF.GetAsMatrix4())
            export_obj(template, directory / "template.obj")
        visual_sdf(recentred(mesh, box_centre), directory / "training", Path(name).stem)
    return categories.CategoryRecord(
        name=args.name,
        presentation_yaw=args.presentation_yaw,
        box_centre=[float(v) for v in box_centre],
        half_turn_symmetric=args.symmetric,
        models=sorted(clouds),
        annotated_models=len(poses),
    )


def fine_tune_segmenter(args, base_model, base: dict, classes: tuple[str, ...]):
    """Step 4: the segmenter in use (base_model, its metadata `base`), widened to `classes` and fine-tuned on
    frames of every class. Returns the new model and its metadata."""
    model = segmentation_network.with_classes(base_model, len(classes))
    scenario = with_sensor(load_scenario(), args.sensor)
    logging.info("[4/5] rendering %d frames of %s", args.frames, ", ".join(classes[1:]))
    data = segmentation_data.generate(scenario, args.frames, args.frames_per_scene, "train", args.seed, classes=classes)
    start = time.perf_counter()
    model, history = segmenter_training.fit(
        model, data["rgb"], data["labels"], args.epochs, args.seed, learning_rate=FINE_TUNE_LEARNING_RATE,
        description=f"fine-tuning the segmenter with {classes[-1]!r}",
    )  # fmt: skip
    train_s = time.perf_counter() - start
    seed = segmentation_data.VALIDATION_SEED
    validation = segmentation_data.generate(
        scenario, args.validation_frames, args.frames_per_scene, "test", seed, classes=classes
    )
    frames = validation["rgb"], validation["labels"]
    metadata = segmenter_training.training_record(
        classes, args.epochs, args.seed, len(data["rgb"]), scenario.camera_noise.preset, train_s, history
    )
    # The raw network at its input size (no flip averaging), on the generated categories' test instances and a
    # taught category's own training models (it has no others); beside it the segmenter it started from on the
    # same frames: what the fine-tuning cost the classes it knew.
    before = segmenter_training.class_iou(base_model, *frames, classes)
    metadata |= {
        "fine_tuned_from": base,
        "validation": {
            "frames": args.validation_frames,
            "seed": seed,
            "iou": segmenter_training.class_iou(model, *frames, classes),
            "iou_before": {name: before[name] for name in base["classes"]},
        },
    }
    return model, metadata


def teach(args, directory: Path, base_model, base: dict) -> categories.CategoryRecord:
    """Steps 1-5 into `directory` (and the segmenter beside it, unless --keep-segmenter)."""
    logging.info("[1/5] reading %s into %s", args.folder, directory)
    record = write_models(args, directory)
    if args.keep_segmenter:
        categories.save_record(record)
        print(f"taught {args.name!r} again: {len(record.models)} models, {record.annotated_models} annotated; "
              f"the segmenter kept ({categories.active_segmenter()})")  # fmt: skip
        return record
    known = tuple(base["classes"])
    classes = known if args.name in known else (*known, args.name)
    model, metadata = fine_tune_segmenter(args, base_model, base, classes)
    logging.info("[5/5] writing the segmenter (%d classes) and the record", len(classes))
    root = directory.parent
    partial = root / f"segmenter.{os.getpid()}.tmp.pt"
    segmentation_network.save(model, partial, metadata)
    os.replace(partial, root / "segmenter.pt")
    categories.save_record(record)  # last: until now the category was not known to any pick
    print(json.dumps(metadata["validation"], indent=2))
    print(
        f"taught {args.name!r}: {len(record.models)} models, {record.annotated_models} annotated; "
        f"segmenter IoU on it {metadata['validation']['iou'][args.name]:.3f}. Try: python scripts/pick.py "
        f"--object {args.name} --object-file <an unseen {args.name}>.obj"
    )
    return record


def teach_category(args) -> None:
    """Steps 1-5 into the categories folder (systems.categories.categories_dir()).

    Raises:
        SystemExit: --keep-segmenter with a segmenter that does not know the class, or a folder or poses file
            that cannot be read (naming the problem).
    """
    base_path = categories.active_segmenter()
    base_model, base = segmentation_network.load(base_path)
    base["path"] = str(base_path)
    if args.keep_segmenter and args.name not in base["classes"]:
        raise SystemExit(f"error: --keep-segmenter: {base_path} does not know {args.name!r}")
    root = categories.categories_dir()
    directory = root / args.name
    # A category taught before waits aside (out of known_categories' sight) until the new one is done: a run
    # that fails or is stopped puts it back.
    aside = root / ".previous" / args.name
    if directory.exists():
        logging.warning("%s is taught already: it is taught again (the old one is kept until then)", args.name)
        shutil.rmtree(aside, ignore_errors=True)
        aside.parent.mkdir(parents=True, exist_ok=True)
        directory.rename(aside)
    directory.mkdir(parents=True)
    try:
        teach(args, directory, base_model, base)
    except BaseException:
        shutil.rmtree(directory, ignore_errors=True)
        if aside.exists():
            aside.rename(directory)
        raise
    shutil.rmtree(aside, ignore_errors=True)
