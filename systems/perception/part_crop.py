"""The square window about an object that the part network sees, and the way back to the camera image.

The functional parts of an object (systems/perception/parts.py) are thin: a handle is 4-6 pixels across at the
segmenter's input size. The part network therefore looks at the object alone, at the camera's own resolution or
finer: a square window about the object's mask (its larger side plus a margin), resized to PART_INPUT pixels.
Training (diagrams/generation/segmentation_data.py) and the pick (systems/perception/segmenter.py) cut their
windows with the same functions.
"""

from dataclasses import dataclass

import cv2
import numpy as np

PART_INPUT = 192  # px: the part network's input is PART_INPUT x PART_INPUT
MARGIN = 0.1  # of the mask's larger side, added on every side of the window
MIN_SIDE = 24  # px: a smaller window is no object the part network can read


@dataclass(frozen=True)
class Window:
    """A square window in an image: its top-left pixel (row, column) and side (px); it may reach past the image."""

    row: int
    column: int
    side: int


def window_about(mask: np.ndarray, margin: float = MARGIN) -> Window | None:
    """The square window about the mask's pixels (H x W bool) with `margin` of its larger side around them; None for
    an empty mask."""
    rows, columns = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not len(rows):
        return None
    height, width = rows[-1] - rows[0] + 1, columns[-1] - columns[0] + 1
    side = max(int(round(max(height, width) * (1 + 2 * margin))), MIN_SIDE)
    centre_row, centre_column = (rows[0] + rows[-1] + 1) / 2, (columns[0] + columns[-1] + 1) / 2
    return Window(int(round(centre_row - side / 2)), int(round(centre_column - side / 2)), side)


def jittered(window: Window, rng: np.random.Generator, shift: float = 0.08, scale: float = 0.1) -> Window:
    """The window moved by up to `shift` of its side and resized by up to `scale` (training: the pick's windows
    come from masks a little larger or smaller than the truth)."""
    side = max(int(round(window.side * rng.uniform(1 - scale, 1 + scale))), MIN_SIDE)
    row = window.row + (window.side - side) // 2 + int(round(rng.uniform(-shift, shift) * window.side))
    column = window.column + (window.side - side) // 2 + int(round(rng.uniform(-shift, shift) * window.side))
    return Window(row, column, side)


def cut(image: np.ndarray, window: Window, size: int = PART_INPUT, labels: bool = False) -> np.ndarray:
    """The window of `image` (H x W or H x W x C) resized to size x size; outside the image, zeros. Labels (class
    or part ids) are resized by nearest neighbour, colour by area."""
    pad = max(0, -window.row, -window.column, window.row + window.side - image.shape[0])
    pad = max(pad, window.column + window.side - image.shape[1])
    if pad:
        widths = ((pad, pad), (pad, pad)) + ((0, 0),) * (image.ndim - 2)
        image = np.pad(image, widths)
    row, column = window.row + pad, window.column + pad
    piece = image[row : row + window.side, column : column + window.side]
    interpolation = cv2.INTER_NEAREST if labels else (cv2.INTER_AREA if window.side > size else cv2.INTER_LINEAR)
    return cv2.resize(np.ascontiguousarray(piece), (size, size), interpolation=interpolation)


def best_class_at(scores: np.ndarray, window: Window, mask: np.ndarray) -> np.ndarray:
    """The best class at each of the mask's pixels, from a window's per-class scores (C x size x size) resized to
    the window (bilinear): an int array in the order of `image[mask]`.

    Args:
        mask: H x W bool, every pixel inside the window (a window about the mask is).

    Raises:
        ValueError: a mask pixel outside the window.
    """
    top, left = max(window.row, 0), max(window.column, 0)
    bottom, right = min(window.row + window.side, mask.shape[0]), min(window.column + window.side, mask.shape[1])
    inside = mask[top:bottom, left:right]
    if np.count_nonzero(inside) != np.count_nonzero(mask):
        raise ValueError(f"the mask reaches outside the window {window}")
    resized = np.stack([cv2.resize(s, (window.side, window.side), interpolation=cv2.INTER_LINEAR) for s in scores])
    seen = resized[:, top - window.row : bottom - window.row, left - window.column : right - window.column]
    return np.argmax(seen[:, inside], axis=0)
