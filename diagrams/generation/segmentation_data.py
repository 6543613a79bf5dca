"""Synthetic segmentation datasets: frames of randomised scenes at the network's input size.

A dataset file (.npz) holds `rgb` (N x H x W x 3 uint8), `labels` (N x H x W uint8 class ids),
`classes` (their names, background first; by default synthetic_scenes.CLASSES) and `instances`
(the objects in each frame).
The colour is what the scenario's RGB-D sensor model (camera_noise) reports: the network
learns on the images the robot will see.
"""

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from diagrams.generation.synthetic_scenes import CLASSES, SyntheticScene
from diagrams.paths import REPO_ROOT
from diagrams.scenario import Scenario
from systems.perception.rgbd_noise import noisy_color, sensor_model
from systems.perception.segmentation_network import INPUT_SIZE, resize_to_input

DEFAULT_DATASET = REPO_ROOT / "data" / "segmentation" / "train.npz"
DEFAULT_FRAMES = 800
FRAMES_PER_SCENE = 25
VALIDATION_SEED = 1000  # the seed of validation frames: no training set is drawn from it


def resize_frame(rgb: np.ndarray, labels: np.ndarray):
    """Camera-resolution colour and labels -> the network's input size."""
    return resize_to_input(rgb), cv2.resize(labels, INPUT_SIZE, interpolation=cv2.INTER_NEAREST)


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


def scene_jobs(
    scenario: Scenario,
    frames: int,
    frames_per_scene: int,
    split: str,
    seed: int,
    classes=CLASSES,
    crowded=False,
    instances: tuple[str, ...] | None = None,
) -> list[SceneJob]:
    """`frames` frames as ceil(frames / frames_per_scene) scenes, each with a random stream of its own."""
    starts = range(0, frames, frames_per_scene)
    return [
        SceneJob(scenario, split, seed, k, min(frames_per_scene, frames - s), tuple(classes), crowded, instances)
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
    instances = []
    for i in range(job.frames):
        frame = scene.render()
        colour = frame.rgb if parameters is None else noisy_color(frame.rgb, parameters, noise)
        rgb[i], labels[i] = resize_frame(colour, frame.labels)
        instances.append(",".join(f"{category}/{name}" for category, name, _ in frame.objects))
    return {"rgb": rgb, "labels": labels, "instances": np.array(instances)}


def assemble(parts: list[dict[str, np.ndarray]], classes=CLASSES) -> dict[str, np.ndarray]:
    """The scenes' frames, in the jobs' order, as one dataset."""
    dataset = {key: np.concatenate([part[key] for part in parts]) for key in ("rgb", "labels", "instances")}
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
) -> dict[str, np.ndarray]:
    """Renders `frames` frames from ceil(frames / frames_per_scene) random scenes of `split`'s instances, or of the
    named generated `instances` (cluttered tables where `crowded`).

    run_jobs: renders the scene jobs, yielding (job number, frames) in any order (e.g. on worker processes or
        Ray); the dataset is the same whichever renders it.
    classes: the label ids (background first); their categories are the ones placed.
    """
    jobs = scene_jobs(scenario, frames, frames_per_scene, split, seed, classes, crowded, instances)
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
