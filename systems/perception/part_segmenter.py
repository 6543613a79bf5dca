"""The part network: each pixel of the object to pick labelled with its functional part.

A RefineNet-style network (segmentation_network.RefineNetLite, its classes the PartRole values) reads the square
window about the object's mask (part_crop) at the camera's resolution or finer, so that handles a few pixels thick
at the segmenter's input size are 10-20 pixels thick here. Its scores, with the mirror image's (test-time flip),
are resized back to the window in the camera image; the object's pixels take the best part role (PartRole.NONE is
never given to an object pixel: the mask says what is the object, the part network only which part of it).

On a CPU that computes bfloat16 natively (AVX512-BF16 or AMX) the network runs in bfloat16, the same part on
99.9 % of a rendered can's pixels; elsewhere bfloat16 is emulated and slow, and it runs in float32. Traced and frozen
(segmentation_network.frozen), the image and its mirror image on the two cores at once: 12.5 ms a frame as
evaluate.py runs a pick (torch on one thread; benchmark_perception.py --parts, 2026-12-06; float32 15.0 ms).
"""

from pathlib import Path

import numpy as np
import torch

from systems.parallel import parallel_map
from systems.paths import MODELS_DIR
from systems.perception import part_crop, segmentation_network
from systems.perception.parts import PartRole

DEFAULT_PART_WEIGHTS = MODELS_DIR / "part_segmenter.pt"


def native_bfloat16() -> bool:
    """Whether this CPU computes bfloat16 convolutions natively (oneDNN's own test; False where torch lacks it)."""
    try:
        return bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())
    except (AttributeError, RuntimeError):
        return False


class PartSegmenter:
    """Labels an object's pixels with their functional parts (PartRole)."""

    def __init__(self, weights: Path = DEFAULT_PART_WEIGHTS, flip: bool = True, bfloat16: bool | None = None):
        """Args:
        weights: the part network's (scripts/train_part_network.py).
        flip: also read the mirror image and sum the two score maps.
        bfloat16: run the network in bfloat16; None: where the CPU computes it natively (native_bfloat16).

        Raises:
            FileNotFoundError: no such weights.
            ValueError: the weights are no part network's (their classes are not the PartRole names).
        """
        self.dtype = torch.bfloat16 if (native_bfloat16() if bfloat16 is None else bfloat16) else torch.float32
        input_hw = (part_crop.PART_INPUT, part_crop.PART_INPUT)
        self.model, metadata = segmentation_network.load_for_inference(weights, self.dtype, input_hw)
        roles = tuple(metadata.get("classes", ()))
        if roles != tuple(role.name for role in PartRole):
            raise ValueError(f"{weights} is no part network: its classes are {roles}")
        self.flip = flip
        self.metadata = metadata

    def scores(self, window_rgb: np.ndarray) -> np.ndarray:
        """The network's part scores (len(PartRole) x S x S) for one window (S x S x 3 uint8)."""
        x = segmentation_network.to_input(window_rgb).to(self.dtype)
        if not self.flip:
            return self._scores(x)[0].numpy()
        scores, mirrored = parallel_map(self._scores, [x, x.flip(-1)])  # (on the cores at once, as the segmenter)
        return (scores[0] + mirrored[0].flip(-1)).numpy()

    def _scores(self, x: torch.Tensor) -> torch.Tensor:
        """The network's float32 part scores (1 x C x S x S, no gradient) for one window's input (1 x 3 x S x S)."""
        with torch.no_grad():  # (in the calling thread: torch's gradient mode is per thread)
            return self.model(x.contiguous(memory_format=torch.channels_last))

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
        window_scores = self.scores(part_crop.cut(rgb[:, :, :3], window))[1:]  # every role but NONE
        parts[mask] = (part_crop.best_class_at(window_scores, window, mask) + 1).astype(np.uint8)
        return parts
