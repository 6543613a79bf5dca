"""The part benchmark: how well the part network labels each object pixel with its functional part
(scripts/benchmark_perception.py --parts).

Each object (the generated test instances, and the models of the folders given: a held-out family written by
make_unfamiliar_objects.py or make_shop_held_out.py, with each OBJ's `.parts.npz` face roles) stands on the table
where a pick finds it, at each of the paper's yaws, seen from the chest camera's nominal pose through the RGB-D
sensor model. The Segmenter runs as in the pick (named the object's category, with the part network); its parts are
compared with the true part image (diagrams/generation/part_labels.py) over the true object's pixels: per role, the
intersection over union of the pixels given that role and those that have it.
"""

import dataclasses
import logging
import time
from pathlib import Path

import numpy as np
import torch
import trimesh
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.sensors import CameraInfo, ImageDepth32F, ImageRgba8U

from diagrams.benchmarks.registration import NOMINAL_XY
from diagrams.generation.objects import catalog
from diagrams.generation.objects.library import mesh_to_sdf
from diagrams.generation.part_labels import PartSurface, face_role_surface, part_image, part_surface
from diagrams.generation.synthetic_scenes import SyntheticScene
from diagrams.perception import MakePoseEstimator, MakeSegmenter
from diagrams.scenario import Scenario
from systems.messages import GraspPoses, ObjectEstimate, PartRole, Segmentation
from systems.parallel import THREADS
from systems.perception.images import to_depth_image, to_rgba_image
from systems.perception.part_segmenter import PartSegmenter
from systems.perception.parts import part_name
from systems.perception.rgbd_noise import noisy_color, noisy_depth, sensor_model
from systems.perception.shape_registrar import ShapeRegistrar

PAPER_YAWS = (0.25, 0.0, -0.25)  # rad, about the category's presentation
ROLES = (PartRole.BODY, PartRole.LEFT_HANDLE, PartRole.RIGHT_HANDLE, PartRole.TOOL)


@dataclasses.dataclass(frozen=True)
class Subject:
    """An object the benchmark shows the camera: its family, category, name, model and true part surface."""

    family: str
    category: str
    name: str
    model_file: Path | None  # a user's SDF (None: a generated instance)
    surface: PartSurface


def generated_subjects(names=("test_0", "test_1", "test_2")) -> list[Subject]:
    """The generated categories' instances `names` (the unseen test instances by default)."""
    return [
        Subject("test", category, name, None, part_surface(catalog.generate(category, name).parts))
        for category in catalog.CATEGORIES
        for name in names
    ]


def folder_subjects(folder: Path) -> list[Subject]:
    """The models of a held-out family's folder (<category>/<name>.obj with <name>.parts.npz beside each)."""
    subjects = []
    for category in catalog.CATEGORIES:
        for path in sorted((folder / category).glob("*.obj")):
            roles_file = path.with_suffix(".parts.npz")
            if not roles_file.is_file():
                raise FileNotFoundError(f"{roles_file}: no part roles beside {path.name} (write the family again)")
            mesh = trimesh.load(path, force="mesh", process=False)
            with np.load(roles_file) as data:
                surface = face_role_surface(mesh, data["face_roles"])
            sdf = mesh_to_sdf(path, 1.0, 1.0, category)
            subjects.append(Subject(folder.name, category, path.stem, sdf, surface))
    return subjects


@dataclasses.dataclass
class PerceivedView:
    """One kinect_v2 view of an object through the pick's perception (see perceive_view)."""

    X_WO: RigidTransform  # the object's true pose (for judging only)
    rgb: np.ndarray  # the colour image the segmenter read (H x W x 3, uint8)
    X_WC: RigidTransform  # the depth camera's pose (its images are registered to the colour camera's)
    intrinsics: CameraInfo
    segmentation: Segmentation
    estimate: ObjectEstimate
    grasps: GraspPoses


def perceive_view(
    scenario: Scenario, category: str, instance: str, yaw: float, seed: int = 3, model_file: Path | None = None
) -> PerceivedView:
    """A frame of the generated instance (or of the model file, an SDF: a user's mesh through mesh_to_sdf) where a
    pick finds it (NOMINAL_XY, `yaw` from its presentation), with the sensor model's noise, through the pick's
    segmenter (with its part network), pose estimator and shape registrar, as LeafSystems."""
    scene = SyntheticScene(
        scenario,
        np.random.default_rng(seed),
        cameras=1,
        camera_jitter=False,
        instances=None if model_file else (instance,),
        classes=("background", category),
        models={category: [(instance, model_file)]} if model_file else None,
    )
    frame = scene.render(placement=(category, instance, catalog.presentation_yaw(category) + yaw, np.array(NOMINAL_XY)))
    sensor, noise = sensor_model("kinect_v2"), np.random.default_rng(seed)
    depth_camera = scenario.camera.MakeCameras()[1].core()
    depth = noisy_depth(frame.depth, frame.rgb, depth_camera.intrinsics(), sensor, noise)
    rgb = noisy_color(frame.rgb, sensor, noise)
    segmentation = _evaluated(MakeSegmenter(scenario, category=category), {"color_image": to_rgba_image(rgb)})
    inputs = {"segmentation": segmentation, "depth_image": to_depth_image(depth), "camera_pose": frame.X_WC}
    estimate = _evaluated(MakePoseEstimator(scenario), inputs, "estimate")
    grasps = _evaluated(ShapeRegistrar((category,)), {"estimate": estimate}, "grasp_poses")
    X_WC = frame.X_WC @ depth_camera.sensor_pose_in_camera_body()
    return PerceivedView(frame.objects[0][2], rgb, X_WC, depth_camera.intrinsics(), segmentation, estimate, grasps)


def _evaluated(system, inputs: dict, output: str = "segmentation"):
    """The system's output port `output` with its input ports fixed to `inputs` (images as they are, other values
    as abstract values)."""
    context = system.CreateDefaultContext()
    for name, value in inputs.items():
        port = system.GetInputPort(name)
        port.FixValue(context, value if isinstance(value, (ImageRgba8U, ImageDepth32F)) else AbstractValue.Make(value))
    return system.GetOutputPort(output).Eval(context)


def run(scenario: Scenario, subjects: list[Subject], seed: int, sensor_name: str | None) -> dict:
    """Per-part IoU by family and category over every subject at PAPER_YAWS, and the part network's time per frame
    as the pick runs it (bfloat16 where the CPU has it natively) beside float32's on the same frames."""
    sensor = sensor_model(sensor_name)
    depth_camera = scenario.camera.MakeCameras()[1].core()
    K, X_CB = depth_camera.intrinsics(), depth_camera.sensor_pose_in_camera_body()
    counts: dict[tuple[str, str], np.ndarray] = {}  # (family, category) -> roles x (intersection, union)
    rows, seconds, float32_seconds = [], [], []
    segmenters, float32, dtype = {}, PartSegmenter(bfloat16=False), "none"
    for k, subject in enumerate(subjects):
        rng = np.random.default_rng([seed, k])
        models = {subject.category: [(subject.name, subject.model_file)]} if subject.model_file else None
        scene = SyntheticScene(
            scenario,
            rng,
            cameras=1,
            camera_jitter=False,
            instances=None if models else (subject.name,),
            classes=("background", subject.category),
            models=models,
        )
        if subject.category not in segmenters:
            segmenters[subject.category] = MakeSegmenter(scenario, category=subject.category)
        segmenter = segmenters[subject.category]
        for j, yaw in enumerate(PAPER_YAWS):
            placement = (subject.category, subject.name, catalog.presentation_yaw(subject.category) + yaw)
            frame = scene.render(placement=(*placement, np.array(NOMINAL_XY)))
            mask = frame.object_masks[0]
            X_WC = frame.X_WC @ X_CB
            truth = part_image(subject.surface, frame.objects[0][2], frame.depth, mask, K, X_WC)
            rgb = frame.rgb
            if sensor is not None:  # (the segmenter reads colour alone)
                rgb = noisy_color(frame.rgb, sensor, np.random.default_rng([seed, k, j]))
            context = segmenter.CreateDefaultContext()
            segmenter.GetInputPort("color_image").FixValue(context, to_rgba_image(rgb))
            segmentation = segmenter.GetOutputPort("segmentation").Eval(context)
            predicted = np.zeros_like(truth) if segmentation.parts is None else segmentation.parts
            if segmentation.found and segmenter.part_segmenter is not None:
                started, dtype = time.perf_counter(), str(segmenter.part_segmenter.dtype).removeprefix("torch.")
                segmenter.part_segmenter.parts_of(rgb, segmentation.mask)
                seconds.append(time.perf_counter() - started)
                started = time.perf_counter()
                float32.parts_of(rgb, segmentation.mask)
                float32_seconds.append(time.perf_counter() - started)
            tally = counts.setdefault((subject.family, subject.category), np.zeros((len(ROLES), 2)))
            row = {"family": subject.family, "category": subject.category, "name": subject.name, "yaw": yaw}
            for i, role in enumerate(ROLES):
                given, has = mask & (predicted == role), mask & (truth == role)
                tally[i] += (np.count_nonzero(given & has), np.count_nonzero(given | has))
                row[role.name] = float(np.count_nonzero(given & has) / max(np.count_nonzero(given | has), 1))
            rows.append(row)
            logging.info(
                "%-10s %-12s %-28s yaw %+.2f  %s",
                subject.family,
                subject.category,
                subject.name,
                yaw,
                "  ".join(f"{part_name(subject.category, r)} {row[r.name]:.2f}" for r in ROLES),
            )
    iou = {
        f"{family}/{category}": {
            part_name(category, role): float(tally[i, 0] / tally[i, 1]) if tally[i, 1] else float("nan")
            for i, role in enumerate(ROLES)
        }
        for (family, category), tally in counts.items()
    }
    return {
        "seed": seed,
        "sensor": sensor_name,
        "views": len(rows),
        "iou": iou,
        "part_network_s_median": float(np.median(seconds)) if seconds else float("nan"),
        "part_network_dtype": dtype,
        "torch_threads": torch.get_num_threads(),
        "part_network_float32_s_median": float(np.median(float32_seconds)) if float32_seconds else float("nan"),
        "frames": rows,
    }


def print_table(results: dict) -> None:
    """Per-part IoU by family and category, beside the handles' target."""
    print()
    print(
        f"part IoU over the true object's pixels ({results['views']} views, sensor {results['sensor']}); handles >= 0.7"
    )
    for key, parts in results["iou"].items():
        print(f"  {key:32s} " + "  ".join(f"{name} {value:.3f}" for name, value in parts.items()))
    print(
        f"part network, median per frame: {1000 * results['part_network_s_median']:.1f} ms in "
        f"{results['part_network_dtype']} (target <= 15 ms); "
        f"float32 on the same frames {1000 * results['part_network_float32_s_median']:.1f} ms; torch's OpenMP on "
        f"{results['torch_threads']} thread(s), the image and its mirror image on {THREADS}"
    )
