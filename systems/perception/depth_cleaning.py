"""Cleaning a real depth sensor's artefacts out of the points the pipeline fits, before anything thins them.

A time-of-flight pixel that sees two surfaces at a depth edge reports a depth between them (a flying
pixel): a point floating in free space, off every surface. About 1 % of a drill's points are such points
more than 1 cm off its surface, but farthest point sampling (which the shape registration thins with)
prefers exactly those isolated points: after thinning they were 20-33 % of what the fit saw, and put drill
grasps 6 cm off. Two filters, as real pipelines have them:

  * in the image (flying_pixels): a pixel whose depth agrees with fewer than MIN_AGREEING of its 8 neighbours
    (within the sensor's noise at that depth) lies between surfaces. On a surface, even a steep one, the two
    neighbours along its line of equal depth agree; a flying pixel's neighbours lie on either surface or fly
    at other depths. (On single noisy views of training cans and drills: 2 % of the object's points lay over
    1 cm off its surface, 0.02 % after this filter; on the renderer's perfect depth it drops 0.17 %, with
    three agreeing neighbours 1.2 %.)
  * in space (dense_inliers): a point whose STRAY_NEIGHBOUR-th nearest neighbour is more than STRAY_RATIO times
    as far as the cloud's median is a stray in free space, off the sampled surfaces. The median, not the mean
    and standard deviation of open3d's statistical outlier removal: with a fifth of the points flying, those
    kept 71 % of the strays (this: 12 %). On single noisy views of training cans and drills, without the image
    filter, it removed every point over 1 cm off the surface and 1-2 % of those on it (after it: 0.1-0.8 %).
"""

import numpy as np
from scipy.spatial import cKDTree

from systems.parallel import THREADS

MIN_AGREEING = 2
# Two neighbours agree within AGREE_M + AGREE_PER_M2 * z^2 (m): a few standard deviations of a Kinect-v2-like
# sensor's axial noise (0.5 mm + 1.5 mm/m^2 z^2) and the step between neighbours on a surface seen at a slant.
AGREE_M = 0.005
AGREE_PER_M2 = 0.005
STRAY_NEIGHBOUR = 10
STRAY_RATIO = 3.0


def flying_pixels(depth: np.ndarray) -> np.ndarray:
    """H x W bool: the pixels with a depth (finite, > 0; m) that fewer than MIN_AGREEING of their 8 neighbours
    agree with."""
    z = np.where(np.isfinite(depth) & (depth > 0), depth, np.nan).astype(np.float32)
    padded = np.pad(z, 1, constant_values=np.nan)
    height, width = z.shape
    # In float32, as the depth image is (half the time of float64): two neighbours' difference is exact wherever it
    # can come near the tolerance (Sterbenz), and the tolerance, a float64, is rounded down to the float32 below it,
    # so every comparison is the float64 one's.
    exact = AGREE_M + AGREE_PER_M2 * np.square(z, dtype=float)
    tolerance = exact.astype(np.float32)
    bits = tolerance.view(np.int32)  # (positive floats: one less in their bits is the next float32 below)
    np.subtract(bits, tolerance > exact, out=bits, casting="unsafe")
    agreeing = np.zeros(z.shape, np.uint8)
    difference, agrees = np.empty_like(z), np.empty(z.shape, bool)  # (in place: a frame is 0.2 M pixels)
    with np.errstate(invalid="ignore"):  # NaN neighbours (holes, the border) never agree
        for dv in (-1, 0, 1):
            for du in (-1, 0, 1):
                if dv or du:
                    neighbour = padded[1 + dv : 1 + dv + height, 1 + du : 1 + du + width]
                    np.subtract(neighbour, z, out=difference)
                    np.abs(difference, out=difference)
                    np.less_equal(difference, tolerance, out=agrees)
                    agreeing += agrees
    return np.isfinite(z) & (agreeing < MIN_AGREEING)


def dense_inliers(points: np.ndarray) -> np.ndarray:
    """N bool: the points (N x 3, m) whose STRAY_NEIGHBOUR-th nearest neighbour lies within STRAY_RATIO times the
    cloud's median such distance (all, for too few points to judge)."""
    if len(points) <= 2 * STRAY_NEIGHBOUR:
        return np.ones(len(points), bool)
    # (A sliding-midpoint tree: the same neighbours, built and queried in about 0.7 of the balanced one's time here.)
    # (The query on the cores: each point's neighbours are found alone, the same answers on any number of threads.)
    tree = cKDTree(points, balanced_tree=False)
    distance = tree.query(points, STRAY_NEIGHBOUR + 1, workers=THREADS)[0][:, STRAY_NEIGHBOUR]
    return distance <= STRAY_RATIO * np.median(distance)
