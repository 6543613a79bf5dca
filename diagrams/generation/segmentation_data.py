"""Synthetic segmentation datasets: frames of randomised scenes at the network's input size.

A dataset file (.npz) holds `rgb` (N x H x W x 3 uint8), `labels` (N x H x W uint8 class ids),
`classes` (their names, background first; by default synthetic_scenes.CLASSES) and `instances`
(the objects in each frame). Rendered with parts, also each placed object's window as the part network sees it
(systems/perception/part_crop.py, cut at camera resolution): `part_rgb` (M x S x S x 3 uint8), `part_labels`
(M x S x S uint8: each pixel's functional part, systems/perception/parts.py's PartRole, of whichever object it
shows; NONE off the objects, UNKNOWN_PART on an object whose parts are not known, e.g. a taught category's) and
`part_instances` (the object each window is about).
The colour is what the scenario's RGB-D sensor model (camera_noise) reports: the network
learns on the images the robot will see.
"""

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from diagrams.generation.objects import catalog
from diagrams.generation.part_labels import PartSurface, part_image, part_surface
from diagrams.generation.synthetic_scenes import CLASSES, Frame, SyntheticScene
from diagrams.paths import REPO_ROOT
from diagrams.scenario import Scenario
from systems.perception import part_crop, segmenter_training
from systems.perception.rgbd_noise import noisy_color, sensor_model
from systems.perception.segmentation_network import INPUT_SIZE, resize_to_input

DEFAULT_DATASET = REPO_ROOT / "data" / "segmentation" / "train.npz"
DEFAULT_FRAMES = 800
FRAMES_PER_SCENE = 25
VALIDATION_SEED = 1000  # the seed of validation frames: no training set is drawn from it
DATASET_KEYS = ("rgb", "labels", "instances")  # every dataset's frames
PART_KEYS = ("part_rgb", "part_labels", "part_instances")  # ... and its part windows, where rendered with parts
MIN_PART_PIXELS = 400  # px at camera resolution: an object seen less is no part window
UNKNOWN_PART = segmenter_training.UNKNOWN_LABEL  # a part label: an object pixel whose part is not known


def resize_frame(rgb: np.ndarray, labels: np.ndarray):
    """Camera-resolution colour and labels -> the network's input size."""
    return resize_to_input(rgb), resize_labels(labels)


def resize_labels(labels: np.ndarray) -> np.ndarray:
    """A camera-resolution label image (class ids, part roles) at the network's input size."""
    return cv2.resize(labels, INPUT_SIZE, interpolation=cv2.INTER_NEAREST)


@dataclass(frozen=True)
class SceneJob:
    """One random scene and the frames rendered from it: a unit of work for a worker process or a Ray task."""

    scenario: Scenario
    split: str
    seed: int  # the dataset's seed
    index: int  # the scene's place in the dataset; with `seed`, its random stream
    frames: int
    classes: tuple[str, ...] = CLASSES  # label ids: background, then the categories placed
    crowded: bool = False  # cluttered tables (SyntheticScene's `crowded`)
    instances: tuple[str, ...] | None = None  # these generated instances instead of the split's
    parts: bool = False  # also each object's part window (the dataset's PART_KEYS)


def scene_jobs(
    scenario: Scenario,
    frames: int,
    frames_per_scene: int,
    split: str,
    seed: int,
    classes=CLASSES,
    crowded=False,
    instances: tuple[str, ...] | None = None,
    parts: bool = False,
) -> list[SceneJob]:
    """`frames` frames as ceil(frames / frames_per_scene) scenes, each with a random stream of its own."""
    starts = range(0, frames, frames_per_scene)
    return [
        SceneJob(scenario, split, seed, k, min(frames_per_scene, frames - s), tuple(classes), crowded, instances, parts)
        for k, s in enumerate(starts)
    ]


def render_scene(job: SceneJob) -> dict[str, np.ndarray]:
    """The job's frames, the same wherever they are rendered: every draw comes from the stream [seed, index]."""
    rng = np.random.default_rng([job.seed, job.index])
    scene = SyntheticScene(
        job.scenario, rng, split=job.split, classes=job.classes, crowded=job.crowded, instances=job.instances
    )
    sensor = job.scenario.camera_noise
    # The sensor's noise from a stream of its own: the scenes are those rendered without it.
    parameters = sensor_model(sensor.preset, sensor.overrides)
    noise = np.random.default_rng([job.seed, job.index, 1])
    width, height = INPUT_SIZE
    rgb = np.empty((job.frames, height, width, 3), np.uint8)
    labels = np.empty((job.frames, height, width), np.uint8)
    surfaces: dict[tuple[str, str], PartSurface | None] = {}
    windows = np.random.default_rng([job.seed, job.index, 2])  # the part windows' jitter, a stream of its own
    crops: dict[str, list] = {"part_rgb": [], "part_labels": [], "part_instances": []}
    instances = []
    for i in range(job.frames):
        frame = scene.render()
        colour = frame.rgb if parameters is None else noisy_color(frame.rgb, parameters, noise)
        rgb[i], labels[i] = resize_frame(colour, frame.labels)
        instances.append(",".join(f"{category}/{name}" for category, name, _ in frame.objects))
        if job.parts:
            roles = frame_parts(frame, job.scenario, surfaces)
            for (category, name, _), mask in zip(frame.objects, frame.object_masks, strict=True):
                if np.count_nonzero(mask) < MIN_PART_PIXELS:
                    continue
                window = part_crop.jittered(part_crop.window_about(mask), windows)
                crops["part_rgb"].append(part_crop.cut(colour, window))
                crops["part_labels"].append(part_crop.cut(roles, window, labels=True))
                crops["part_instances"].append(f"{category}/{name}")
    dataset = {"rgb": rgb, "labels": labels, "instances": np.array(instances)}
    if not job.parts:
        return dataset
    size = part_crop.PART_INPUT
    return dataset | {
        "part_rgb": np.array(crops["part_rgb"], np.uint8).reshape(-1, size, size, 3),
        "part_labels": np.array(crops["part_labels"], np.uint8).reshape(-1, size, size),
        "part_instances": np.array(crops["part_instances"], dtype=str),
    }


def frame_parts(frame: Frame, scenario: Scenario, surfaces: dict) -> np.ndarray:
    """The frame's part image at camera resolution (H x W uint8 PartRole values, UNKNOWN_PART on an object whose
    parts are not known). `surfaces`: each object's part surface by (category, name), filled as they are made."""
    depth_camera = scenario.camera.MakeCameras()[1].core()
    X_WC = frame.X_WC @ depth_camera.sensor_pose_in_camera_body()
    image = np.zeros(frame.labels.shape, np.uint8)
    for (category, name, X_WO), mask in zip(frame.objects, frame.object_masks, strict=True):
        key = (category, name)
        if key not in surfaces:
            generated = category in catalog.CATEGORIES
            surfaces[key] = part_surface(catalog.generate(category, name).parts) if generated else None
        if surfaces[key] is None:
            image[mask] = UNKNOWN_PART
        else:
            image[mask] = part_image(surfaces[key], X_WO, frame.depth, mask, depth_camera.intrinsics(), X_WC)[mask]
    return image


def assemble(parts: list[dict[str, np.ndarray]], classes=CLASSES) -> dict[str, np.ndarray]:
    """The scenes' frames, in the jobs' order, as one dataset."""
    keys = DATASET_KEYS + (PART_KEYS if all("part_rgb" in part for part in parts) else ())
    dataset = {key: np.concatenate([part[key] for part in parts]) for key in keys}
    return dataset | {"classes": np.array(classes)}


def render_here(jobs: list[SceneJob]) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
    """(job number, its frames), one job after another in this process."""
    for n, job in enumerate(jobs):
        yield n, render_scene(job)


def generate(
    scenario: Scenario,
    frames: int,
    frames_per_scene: int,
    split: str,
    seed: int,
    run_jobs: Callable[[list[SceneJob]], Iterable[tuple[int, dict[str, np.ndarray]]]] = render_here,
    classes=CLASSES,
    crowded: bool = False,
    instances: tuple[str, ...] | None = None,
    parts: bool = False,
) -> dict[str, np.ndarray]:
    """Renders `frames` frames from ceil(frames / frames_per_scene) random scenes of `split`'s instances, or of the
    named generated `instances` (cluttered tables where `crowded`).

    run_jobs: renders the scene jobs, yielding (job number, frames) in any order (e.g. on worker processes or
        Ray); the dataset is the same whichever renders it.
    classes: the label ids (background first); their categories are the ones placed.
    parts: also each object's part window (the dataset's PART_KEYS).
    """
    jobs = scene_jobs(scenario, frames, frames_per_scene, split, seed, classes, crowded, instances, parts)
    parts = [None] * len(jobs)
    with tqdm(total=frames, unit="frame", desc=f"rendering {split} frames", dynamic_ncols=True) as bar:
        for n, part in run_jobs(jobs):
            parts[n] = part
            bar.update(jobs[n].frames)
    return assemble(parts, classes)


def save(path: Path, dataset: dict[str, np.ndarray]):
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **dataset)


def load(path: Path) -> dict[str, np.ndarray]:
    """Raises FileNotFoundError naming the script that makes the file."""
    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: no dataset; run scripts/generate_segmentation_data.py")
    with np.load(path) as data:
        return {key: data[key] for key in data.files}
