"""Synthetic segmentation datasets: frames of randomised scenes at the network's input size.

A dataset file (.npz) holds `rgb` (N x H x W x 3 uint8), `labels` (N x H x W uint8
class ids, see synthetic_scenes.CLASSES) and `instances` (the objects in each frame).
"""

import logging
import time
from pathlib import Path

import cv2
import numpy as np

from diagrams.paths import REPO_ROOT
from diagrams.scenario import Scenario
from diagrams.synthetic_scenes import CLASSES, SyntheticScene
from systems.segmentation_network import INPUT_SIZE, resize_to_input

DEFAULT_DATASET = REPO_ROOT / "data" / "segmentation" / "train.npz"
DEFAULT_FRAMES = 800
FRAMES_PER_SCENE = 25


def resize_frame(rgb: np.ndarray, labels: np.ndarray):
    """Camera-resolution colour and labels -> the network's input size."""
    return resize_to_input(rgb), cv2.resize(labels, INPUT_SIZE, interpolation=cv2.INTER_NEAREST)


def generate(scenario: Scenario, frames: int, frames_per_scene: int, split: str, seed: int) -> dict[str, np.ndarray]:
    """Renders `frames` frames from ceil(frames / frames_per_scene) random scenes of `split`'s instances."""
    rng = np.random.default_rng(seed)
    width, height = INPUT_SIZE
    rgb = np.empty((frames, height, width, 3), np.uint8)
    labels = np.empty((frames, height, width), np.uint8)
    instances = []
    start = time.perf_counter()
    scene = None
    for i in range(frames):
        if i % frames_per_scene == 0:
            scene = SyntheticScene(scenario, rng, split=split)
        frame = scene.render()
        rgb[i], labels[i] = resize_frame(frame.rgb, frame.labels)
        instances.append(",".join(f"{category}/{name}" for category, name, _ in frame.objects))
        if (i + 1) % 50 == 0 or i + 1 == frames:
            logging.info("rendered %d/%d frames (%.0f s)", i + 1, frames, time.perf_counter() - start)
    return {"rgb": rgb, "labels": labels, "instances": np.array(instances), "classes": np.array(CLASSES)}


def save(path: Path, dataset: dict[str, np.ndarray]):
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **dataset)


def load(path: Path) -> dict[str, np.ndarray]:
    """Raises FileNotFoundError naming the script that makes the file."""
    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: no dataset; run scripts/generate_segmentation_data.py")
    with np.load(path) as data:
        return {key: data[key] for key in data.files}
