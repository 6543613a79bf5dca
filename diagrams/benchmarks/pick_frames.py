"""The registration benchmark's views of the picks' own first frames (scripts/benchmark_registration.py
--pick-frames): the first frame evaluate.py's pick of an object would see (the object's mass changes how it settles,
so the frame), through the station's camera and sensor model, the segmenter's mask, the pose estimator and the
paper's +-0.2 rad registration yaw noise. Each pick is simulated only until perception latches that frame (a few
seconds instead of a whole pick; the pick registers it once itself on the way), and the frame is registered to the
category perception gave it, as the pick does, with the benchmark's spaces.
"""

import functools
import hashlib
import logging
import pickle
import time
from pathlib import Path

import trimesh
from pydrake.common.yaml import yaml_dump_typed
from pydrake.math import RigidTransform
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import Context, Diagram

from diagrams.autonomous_pick import PERCEIVE_AT_S, MakePickDiagram
from diagrams.benchmarks.registration import judged_row, log_row, space_files, true_info
from diagrams.evaluation import make_trials
from diagrams.generation.objects import catalog
from diagrams.generation.objects.library import generated_instance_directory, load_info
from diagrams.pick_simulation import object_body, station_plant
from diagrams.scenario import Scenario
from systems import categories
from systems.messages import ObjectEstimate
from systems.perception.part_segmenter import DEFAULT_PART_WEIGHTS
from systems.perception.shape_registrar import fit_doubt, registrar_of, seen_part_grasps

FRAME_POLL_S = 0.01  # s: the pick's simulation steps while it waits for its first frame


def pick_frame_trials(
    base: Scenario,
    category: str,
    objects: dict[str, dict],
    trials: int,
    yaws,
    space_dir: Path | None = None,
    part_prior: float | None = None,
    part_grasps: bool = True,
    frames_cache: Path | None = None,
):
    """One row per pick of evaluate.py's campaign (make_trials: every object at every yaw, `trials` each, pick n
    with the seed base.random_seed + n): the registration of the first frame the autonomous pick itself takes
    (the station's camera and sensor model, the segmenter's mask, the pose estimator, the paper's registration
    yaw noise), without running the pick past it; with part_grasps, where the fit is poor and the frame has the
    object's parts, the grasps judged are those the pick builds on them (ShapeRegistrar's). objects: evaluate.py's
    (file_objects, or instances). A frame in which perception finds no object is a row with "found": False and the
    reason (the pick would stop there). frames_cache: a folder where each first frame is kept (cached_first_frame),
    so that the same frames are registered again in seconds while registration or the part rules are tuned."""
    # The pick registers the object to the category perception gives it (the network's, or the one the user named).
    registrars = {c: registrar_of(c, *space_files(c, space_dir), part_prior=part_prior) for c in catalog.CATEGORIES}
    rows, meshes = [], {}
    for n, trial in enumerate(make_trials(base, category, objects, trials, yaws)):
        scenario = trial.scenario
        estimate, X_WO_true = cached_first_frame(scenario, frames_cache) if frames_cache else first_pick_frame(scenario)
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
            info, mesh_file = load_info(path.with_suffix(".info.yaml")), path
        else:
            info = true_info(category, scenario.object.instance)
            mesh_file = generated_instance_directory(category, scenario.object.instance) / "visual.obj"
        if mesh_file not in meshes:
            meshes[mesh_file] = trimesh.load(mesh_file, force="mesh")
        start = time.perf_counter()
        result = registrars[estimate.category].register(
            estimate.points_W, estimate.X_WO, estimate.viewpoint_W, estimate.view
        )
        seconds = time.perf_counter() - start
        grasps_W, handed = None, None
        doubt = fit_doubt(estimate, result, part_grasps)
        if part_grasps and estimate.parts and doubt:
            grasps_W, message = seen_part_grasps(estimate, registrars[estimate.category], result, doubt)
            handed = grasps_W is not None
            logging.info("   on the seen parts: %s", message)
        row = judged_row(
            result,
            estimate.X_WO,
            X_WO_true,
            info.control_poses(),
            meshes[mesh_file],
            grasps_W,
            handed,
            info.tool_frame(),
        )
        rows.append({**pick, "found": True, "perceived_category": estimate.category, "registration_s": seconds, **row})
        log_row(n, rows[-1], result)
    return rows


def cached_first_frame(scenario: Scenario, folder: Path) -> tuple[ObjectEstimate, RigidTransform]:
    """first_pick_frame's (estimate, X_WO), read from `folder` where it was kept, else simulated and kept there. A
    frame is keyed by the whole scenario, the object's model file and the networks' weights (segmenter, part
    network); not by perception's code: empty the folder after changing it."""
    key = hashlib.sha256(yaml_dump_typed(scenario).encode())
    model_files = [categories.active_segmenter(), DEFAULT_PART_WEIGHTS]
    if scenario.object.file:
        model_files.append(Path(scenario.object.file))
    for model_file in model_files:
        stat = model_file.stat() if model_file.is_file() else None
        key.update(_file_digest(model_file, stat.st_size, stat.st_mtime_ns) if stat else b"")
    path = Path(folder) / f"{key.hexdigest()[:24]}.pkl"
    if path.is_file():
        with path.open("rb") as file:
            return pickle.load(file)
    frame = first_pick_frame(scenario)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_suffix(".partial")
    with temporary.open("wb") as file:
        pickle.dump(frame, file)
    temporary.replace(path)
    return frame


@functools.cache
def _file_digest(path: Path, size: int, mtime_ns: int) -> bytes:
    """The file's SHA-256, read once per version of it (its size and time stamp) in a run of many frames."""
    return hashlib.sha256(path.read_bytes()).digest()


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
