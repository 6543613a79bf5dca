"""Training the part network on rendered part windows, and its validation on unseen instances of every family."""

import logging
import time
from pathlib import Path

import numpy as np

from diagrams.generation import segmentation_data
from diagrams.generation.synthetic_scenes import PART_TRAINING, PART_VALIDATION
from diagrams.scenario import Scenario
from systems.perception import segmentation_network, segmenter_training
from systems.perception.parts import PartRole

PART_CLASSES = tuple(role.name for role in PartRole)
# The roles' weights in the loss (PartRole order): the handles and the tool are thin, a few per cent of a window's
# pixels, and they are what the grasps are built on.
PART_WEIGHTS = (0.3, 0.5, 2.0, 2.0, 1.5)


def load_windows(paths: list[Path]) -> dict[str, np.ndarray]:
    """The part windows of datasets rendered with parts (segmentation_data.PART_KEYS), taken together.

    Raises:
        SystemExit: a dataset without part windows, or one holding instances kept for validation.
    """
    windows = {key: [] for key in segmentation_data.PART_KEYS}
    for path in paths:
        data = segmentation_data.load(path)
        if "part_rgb" not in data:
            raise SystemExit(f"{path} holds no part windows: render it with generate_segmentation_data.py --parts")
        for key in windows:
            windows[key].append(data[key])
    windows = {key: np.concatenate(value) for key, value in windows.items()}
    unseen = sorted({name.split("/")[1] for name in windows["part_instances"]} - set(PART_TRAINING))
    if unseen:
        raise SystemExit(f"{paths} hold instances kept for validation ({unseen[:4]}); refusing to train")
    return windows


def validation_iou(scenario: Scenario, model, frames: int) -> dict[str, dict]:
    """Part IoU on windows of PART_VALIDATION (unseen instances of every family), single and crowded tables, by
    family (test_, wide_, shop_) and over all."""
    record = {}
    for crowded in (False, True):
        data = segmentation_data.generate(
            scenario,
            frames,
            20,
            "test",
            segmentation_data.VALIDATION_SEED,
            crowded=crowded,
            instances=PART_VALIDATION,
            parts=True,
        )
        families = np.array([name.split("/")[1].split("_")[0] for name in data["part_instances"]])
        table = "crowded" if crowded else "single"
        record[table] = {"windows": len(families), "all": segmenter_training.part_iou(model, *_windows(data))}
        for family in np.unique(families):
            chosen = families == family
            rgb, labels = _windows(data)
            record[table][str(family)] = segmenter_training.part_iou(model, rgb[chosen], labels[chosen])
    return record


def _windows(data):
    return data["part_rgb"], data["part_labels"]


def train_part_network(
    scenario: Scenario,
    data: list[Path],
    init: Path,
    out: Path,
    epochs: int,
    learning_rate: float,
    seed: int,
    validation_frames: int,
) -> dict:
    """Trains the part network on the datasets' part windows from `init` (a segmenter: its trunk; or a part network
    to train further), validates it and saves it to `out` with its record (returned)."""
    windows = load_windows(data)
    model, start_metadata = segmentation_network.load(init)
    if tuple(start_metadata.get("classes", ())) != PART_CLASSES:  # a segmenter: its trunk, a new classifier
        model = segmentation_network.with_new_classifier(model, len(PART_CLASSES), seed)
    start = time.perf_counter()
    model, history = segmenter_training.fit(
        model,
        windows["part_rgb"],
        windows["part_labels"],
        epochs,
        seed,
        learning_rate=learning_rate,
        description="training the part network",
        class_weights=PART_WEIGHTS,
    )
    seconds = time.perf_counter() - start
    metadata = segmenter_training.training_record(
        PART_CLASSES, epochs, seed, len(windows["part_rgb"]), scenario.camera_noise.preset, seconds, history
    )
    metadata |= {"initial_weights": str(init), "learning_rate": learning_rate, "class_weights": list(PART_WEIGHTS)}
    logging.info("validating on %d frames of unseen instances per table kind", validation_frames)
    metadata["validation"] = validation_iou(scenario, model, validation_frames)
    out.parent.mkdir(parents=True, exist_ok=True)
    segmentation_network.save(model, out, metadata)
    return metadata
