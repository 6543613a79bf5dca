"""A depth image as the shape registration reads it: which points (in W) fall in the object's pixels, and how deep
the image measured them. Frames: W the world, C the depth camera (z along the optical axis); metres."""

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform


@dataclass
class DepthView:
    """The depth image a cloud was taken from, its camera and the object's pixels."""

    depth: np.ndarray  # H x W, metres along the optical axis (NaN, inf or 0 where nothing was measured)
    X_WC: RigidTransform  # the depth camera's pose
    focal: tuple[float, float]  # fx, fy in pixels
    centre: tuple[float, float]  # cx, cy in pixels
    mask: np.ndarray | None = None  # H x W bool, the object's pixels (None: every pixel may be something else)

    def look_up(self, points_W: np.ndarray) -> "DepthLookup":
        """For points (N x 3, W): their depths, the depths measured in their pixels and whether those are the
        object's."""
        p = self.X_WC.inverse().multiply(np.asarray(points_W, dtype=float).T)
        height, width = self.depth.shape
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.round(self.focal[0] * p[0] / p[2] + self.centre[0])
            v = np.round(self.focal[1] * p[1] / p[2] + self.centre[1])
        inside = (p[2] > 0) & (u >= 0) & (u < width) & (v >= 0) & (v < height)
        rows, columns = v[inside].astype(int), u[inside].astype(int)
        measured = np.full(len(p[0]), np.nan)
        measured[inside] = self.depth[rows, columns]
        measured[~np.isfinite(measured) | (measured <= 0)] = np.nan  # (a sensor's 0: no return)
        on_object = np.zeros(len(p[0]), dtype=bool)
        if self.mask is not None:
            on_object[inside] = self.mask[rows, columns]
        return DepthLookup(p[2], measured, on_object)


@dataclass
class DepthLookup:
    """Points looked up in a depth image (DepthView.look_up), one entry per point."""

    depth: np.ndarray  # (N,) their depths along the optical axis, m
    measured: np.ndarray  # (N,) the depths measured in their pixels, m (NaN outside the image or nothing measured)
    on_object: np.ndarray  # (N,) bool: their pixels are the object's
