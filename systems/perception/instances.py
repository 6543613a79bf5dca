"""Object instances in a labelled image, and the one to pick among them.

The network labels pixels by class; on a cluttered table one class's pixels can belong to several objects, and two
objects can touch in the image. Instances are the connected regions of object pixels (any class), cut apart along
the depth image's edges (a jump of more than DEPTH_JUMP_M between neighbouring pixels, or a hole: a real sensor loses
the pixels along an occluding edge) into pieces that are each a large share of the region (an object's handle in
front of its body, or a spout rising towards the camera, is a small piece: it stays with the body; an object
standing in front of another is not). Classes never cut an instance: the network may label one object in parts.
Each instance has the class that labelled most of it.
"""

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from systems.messages import Segmentation

DEPTH_JUMP_M = 0.015  # m between neighbouring pixels: an edge between two surfaces
# A piece cut off by depth edges is an object of its own only if it holds at least this share of the
# largest piece of its region (and min_pixels): smaller ones are parts (a handle, a spout, mislabelled pixels).
PIECE_SHARE = 0.25
# Among the instances of a named category, only those with at least this share of the largest one are candidates:
# a small mislabelled patch nearer the camera is not an object to pick.
CANDIDATE_SHARE = 0.4


@dataclass
class Instance:
    """One object in the image."""

    mask: np.ndarray  # H x W bool
    votes: np.ndarray  # pixels per object class (classes[1:])
    depth_m: float  # median depth of its pixels (NaN without a valid one), m

    @property
    def pixel_count(self) -> int:
        return int(self.votes.sum())

    def category(self, classes) -> str:
        return classes[1 + int(np.argmax(self.votes))]


def depth_edges(depth: np.ndarray, jump: float = DEPTH_JUMP_M) -> np.ndarray:
    """H x W bool: pixels with a valid depth whose right or lower neighbour's depth differs by more than `jump` m
    (both sides of the edge are marked)."""
    valid = np.isfinite(depth) & (depth > 0)
    edges = np.zeros(depth.shape, bool)
    for axis in (0, 1):
        a = [slice(None)] * 2
        b = [slice(None)] * 2
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        a, b = tuple(a), tuple(b)
        both = valid[a] & valid[b]
        jump_here = both & (np.abs(np.where(both, depth[a] - depth[b], 0.0)) > jump)
        edges[a] |= jump_here
        edges[b] |= jump_here
    return edges


def _split(region: np.ndarray, cut: np.ndarray, min_pixels: int) -> list[np.ndarray]:
    """The region (H x W bool) as one mask, or, where removing `cut` leaves two or more large pieces (PIECE_SHARE),
    one mask per large piece, every other pixel of the region given to the nearest one."""
    count, pieces = cv2.connectedComponents((region & ~cut).astype(np.uint8), connectivity=8)
    sizes = np.bincount(pieces[region], minlength=count)
    sizes[0] = 0
    large = [i for i in range(1, count) if sizes[i] >= max(min_pixels, PIECE_SHARE * sizes.max())]
    if len(large) < 2:
        return [region]
    seeds = np.isin(pieces, large) & region
    _, (rows, cols) = ndimage.distance_transform_edt(~seeds, return_indices=True)
    owner = pieces[rows, cols]
    return [region & (owner == i) for i in large]


def object_instances(labels: np.ndarray, depth: np.ndarray | None, classes, min_pixels: int) -> list[Instance]:
    """The objects in a labelled image (H x W class ids, 0 background), cut apart by depth edges (depth: H x W m,
    or None) and by class; instances smaller than min_pixels are dropped. Largest first."""
    pixels = cv2.morphologyEx((labels > 0).astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    count, regions = cv2.connectedComponents(pixels, connectivity=8)
    # Cut along depth edges and holes (a real sensor loses the pixels along an occluding edge).
    edges = depth_edges(depth) | ~(np.isfinite(depth) & (depth > 0)) if depth is not None else None
    if edges is None:
        edges = np.zeros(labels.shape, bool)
    instances = []
    for index in range(1, count):
        region = regions == index
        if np.count_nonzero(region) < min_pixels:
            continue
        for mask in _split(region, edges, min_pixels):
            votes = np.array([np.count_nonzero(mask & (labels == c)) for c in range(1, len(classes))])
            valid = mask & np.isfinite(depth) & (depth > 0) if depth is not None else None
            depth_m = float(np.median(depth[valid])) if valid is not None and valid.any() else float("nan")
            instances.append(Instance(mask, votes, depth_m))
    return sorted(instances, key=lambda instance: -instance.pixel_count)


def named_object(instances: list[Instance], classes, category: str, shape) -> Segmentation:
    """The instance to pick when the user named its category: the nearest to the camera (median depth) of those the
    network labelled mostly `category` (and at least CANDIDATE_SHARE of the largest of them). With none, the
    largest instance, taken as `category` as named (one object on the table that the network misclassifies);
    its network_category says what the network made of it."""
    mine = [i for i in instances if i.category(classes) == category]
    if mine:
        largest = max(i.pixel_count for i in mine)
        candidates = [i for i in mine if i.pixel_count >= CANDIDATE_SHARE * largest]
        chosen = min(candidates, key=lambda i: (np.nan_to_num(i.depth_m, nan=np.inf), -i.pixel_count))
        message = f"{category}: {chosen.pixel_count} px"
        if len(candidates) > 1:
            others = ", ".join(f"{i.depth_m:.2f}" for i in candidates if i is not chosen)
            message += f", the nearest of {len(candidates)} (at {chosen.depth_m:.2f} m; the others at {others} m)"
    elif instances:
        chosen = instances[0]
        share = chosen.votes.max() / max(chosen.pixel_count, 1)
        message = (
            f"{category}: {chosen.pixel_count} px as named (the network labelled {share:.0%} of it "
            f"{chosen.category(classes)})"
        )
    else:
        return Segmentation(False, mask=np.zeros(shape, bool), message=f"no {category} in view")
    network = chosen.category(classes)
    return Segmentation(True, category, chosen.mask, chosen.pixel_count, message, network_category=network)
