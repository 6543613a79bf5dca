"""The part network: each pixel of the object to pick labelled with its functional part.

A RefineNet-style network (segmentation_network.RefineNetLite, its classes the PartRole values) reads the square
window about the object's mask (part_crop) at the camera's resolution or finer, so that handles a few pixels thick
at the segmenter's input size are 10-20 pixels thick here. Its scores, with the mirror image's (test-time flip),
are pasted back into the camera image; the object's pixels take the best part role (PartRole.NONE is never given
to an object pixel: the mask says what is the object, the part network only which part of it).
"""

from pathlib import Path

import numpy as np
import torch

from systems.paths import MODELS_DIR
from systems.perception import part_crop, segmentation_network
from systems.perception.parts import PartRole

DEFAULT_PART_WEIGHTS = MODELS_DIR / "part_segmenter.pt"


class PartSegmenter:
    """Labels an object's pixels with their functional parts (PartRole)."""

    def __init__(self, weights: Path = DEFAULT_PART_WEIGHTS, flip: bool = True):
        """Args:
        weights: the part network's (scripts/train_part_network.py).
        flip: also read the mirror image and sum the two score maps.

        Raises:
            FileNotFoundError: no such weights.
            ValueError: the weights are no part network's (their classes are not the PartRole names).
        """
        model, metadata = segmentation_network.load(weights)
        roles = tuple(metadata.get("classes", ()))
        if roles != tuple(role.name for role in PartRole):
            raise ValueError(f"{weights} is no part network: its classes are {roles}")
        self.model = model.to(memory_format=torch.channels_last)
        self.flip = flip
        self.metadata = metadata

    def scores(self, window_rgb: np.ndarray) -> np.ndarray:
        """The network's part scores (len(PartRole) x S x S) for one window (S x S x 3 uint8)."""
        x = segmentation_network.to_input(window_rgb)
        batch = torch.cat([x, x.flip(-1)]) if self.flip else x
        with torch.no_grad():
            out = self.model(batch.contiguous(memory_format=torch.channels_last))
        scores = out[0] + out[1].flip(-1) if self.flip else out[0]
        return scores.numpy()

    def parts_of(self, rgb: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """The part role of each of the object's pixels (H x W uint8 PartRole values; NONE off the mask).

        Args:
            rgb: the camera's colour image, H x W x 3 (or 4) uint8.
            mask: the object's pixels, H x W bool, the same size.
        """
        parts = np.zeros(mask.shape, np.uint8)
        window = part_crop.window_about(mask)
        if window is None:
            return parts
        scores = part_crop.pasted(self.scores(part_crop.cut(rgb[:, :, :3], window)), window, mask.shape)
        object_scores = scores[1:, mask]  # every role but NONE
        parts[mask] = (np.argmax(object_scores, axis=0) + 1).astype(np.uint8)
        return parts
