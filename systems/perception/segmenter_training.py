"""Training and evaluation of the segmentation network on synthetic frames (CPU, seeded)."""

import numpy as np
import torch
from torch.nn import functional as F
from tqdm import tqdm

from systems.perception.parts import PartRole
from systems.perception.segmentation_network import RefineNetLite, to_input

# Background pixels dominate; weigh them down so thin spouts and handles count (every object class 1.0).
BACKGROUND_WEIGHT = 0.4
UNKNOWN_LABEL = 255  # a pixel whose label is not known (a part of a taught category's object): no loss


def augment(rgb: torch.Tensor, labels: torch.Tensor, generator: torch.Generator):
    """Colour and geometric jitter of a batch (N x 3 x H x W in [-0.5, 0.5], N x H x W)."""
    n = rgb.shape[0]
    flip = torch.rand(n, generator=generator) < 0.5
    rgb[flip] = rgb[flip].flip(-1)
    labels[flip] = labels[flip].flip(-1)
    # Any object colour: permute and rescale the colour channels, shift brightness and contrast.
    for i in range(n):
        rgb[i] = rgb[i, torch.randperm(3, generator=generator)]
    gain = 0.7 + 0.6 * torch.rand(n, 3, 1, 1, generator=generator)
    shift = 0.2 * (torch.rand(n, 1, 1, 1, generator=generator) - 0.5)
    noise = 0.02 * torch.randn(rgb.shape, generator=generator)
    return (rgb * gain + shift + noise).clamp(-0.5, 0.5), labels


def train(
    rgb: np.ndarray,
    labels: np.ndarray,
    num_classes: int,
    epochs: int,
    seed: int,
    batch_size: int = 8,
    learning_rate: float = 3e-3,
) -> tuple[RefineNetLite, list[float]]:
    """Trains a RefineNetLite from scratch; returns it (eval mode) and the mean loss of each epoch."""
    torch.manual_seed(seed)
    return fit(RefineNetLite(num_classes), rgb, labels, epochs, seed, batch_size, learning_rate)


def fit(
    model: RefineNetLite,
    rgb: np.ndarray,
    labels: np.ndarray,
    epochs: int,
    seed: int,
    batch_size: int = 8,
    learning_rate: float = 3e-3,
    description: str = "training the segmenter",
    class_weights: tuple[float, ...] | None = None,
) -> tuple[RefineNetLite, list[float]]:
    """Trains `model` (fresh, or a trained one to fine-tune: see segmentation_network.with_classes) on the
    frames (N x H x W x 3 uint8, N x H x W class ids); returns it (eval mode) and each epoch's mean loss.
    class_weights: each class's weight in the loss (default: BACKGROUND_WEIGHT for class 0, 1 for the others)."""
    generator = torch.Generator().manual_seed(seed)
    num_classes = model.num_classes
    optimizer = torch.optim.AdamW(model.parameters(), lr=learning_rate, weight_decay=1e-4)
    steps = epochs * int(np.ceil(len(rgb) / batch_size))
    schedule = torch.optim.lr_scheduler.OneCycleLR(optimizer, learning_rate, total_steps=steps, pct_start=0.15)
    weights = torch.tensor(class_weights or [BACKGROUND_WEIGHT] + [1.0] * (num_classes - 1))
    history = []
    bar = tqdm(range(epochs), unit="epoch", desc=description, dynamic_ncols=True)
    for _ in bar:
        model.train()
        order = torch.randperm(len(rgb), generator=generator).numpy()
        losses = []
        for first in range(0, len(order), batch_size):
            batch = order[first : first + batch_size]
            x, y = augment(to_input(rgb[batch]), torch.from_numpy(labels[batch]).long(), generator)
            loss = F.cross_entropy(model(x), y, weight=weights, ignore_index=UNKNOWN_LABEL)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            schedule.step()
            losses.append(loss.item())
        history.append(float(np.mean(losses)))
        bar.set_postfix(loss=f"{history[-1]:.4f}")
    model.eval()
    return model, history


@torch.no_grad()
def predict_labels(model: RefineNetLite, rgb: np.ndarray, batch_size: int = 16) -> np.ndarray:
    """Per-pixel argmax classes of N x H x W x 3 uint8 images at the network's input size.

    The raw network, for the training record; the Segmenter system adds flip averaging and
    camera-resolution upsampling, measured by scripts/benchmark_perception.py.
    """
    out = [model(to_input(rgb[i : i + batch_size])).argmax(1).numpy() for i in range(0, len(rgb), batch_size)]
    return np.concatenate(out).astype(np.uint8)


def class_iou(model: RefineNetLite, rgb: np.ndarray, labels: np.ndarray, classes) -> dict[str, float]:
    """{class name: IoU} of the raw network (predict_labels) on frames with their true labels."""
    iou = intersection_over_union(predict_labels(model, rgb), labels, len(classes))
    return dict(zip(classes, iou.tolist(), strict=True))


def training_record(classes, epochs: int, seed: int, frames: int, sensor: str, seconds: float, history) -> dict:
    """What is saved beside trained weights (segmentation_network.save): the classes and how they were learnt."""
    return {
        "classes": list(classes),
        "epochs": epochs,
        "seed": seed,
        "training_frames": frames,
        "sensor": sensor,
        "training_s": round(seconds, 1),
        "final_loss": history[-1],
    }


def intersection_over_union(predicted: np.ndarray, truth: np.ndarray, num_classes: int) -> np.ndarray:
    """IoU of each class over all pixels of all frames (NaN for a class absent from both)."""
    iou = np.full(num_classes, np.nan)
    for c in range(num_classes):
        union = np.count_nonzero((predicted == c) | (truth == c))
        if union:
            iou[c] = np.count_nonzero((predicted == c) & (truth == c)) / union
    return iou


def part_iou(model: RefineNetLite, rgb: np.ndarray, parts: np.ndarray) -> dict[str, float]:
    """{role name: IoU} of the part network's roles over the object pixels of part windows (N x S x S x 3 uint8,
    N x S x S PartRole values; pixels of no known part, 255, left out): the roles the network gives an object
    pixel are those of its scores without NONE, as the pick reads them (part_segmenter)."""
    with torch.no_grad():
        scores = torch.cat([model(to_input(rgb[i : i + 16])) for i in range(0, len(rgb), 16)]).numpy()
    on_object = (parts != PartRole.NONE) & (parts != UNKNOWN_LABEL)
    predicted = np.argmax(scores[:, 1:], axis=1) + 1
    iou = intersection_over_union(predicted[on_object], parts[on_object], len(PartRole))
    return {role.name: float(iou[role]) for role in PartRole if role != PartRole.NONE}
