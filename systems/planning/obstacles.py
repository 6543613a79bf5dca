"""The scene for the sphere model: oriented boxes, point sets as distance fields (an object's surface, a perceived
cloud, the scene as the camera saw it), and what the robot carries through it. Obstacles are data
for one plan or check, built by their caller (systems/planning/world.py: PlanningWorld.planning_obstacles) and
passed in: nothing keeps them between plans.
"""

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import distance_transform_edt, map_coordinates
from scipy.spatial import cKDTree


class DistanceField:
    """Distance to a point set, precomputed on a grid (cell CELL) around it and interpolated trilinearly.

    Points farther than REACH from the set's box get the cap.
    """

    CELL = 0.01  # m
    REACH = 0.15  # m

    def __init__(self, points: np.ndarray, inflation: float = 0.0):
        self.inflation = inflation
        shape = self._grid(points, self.CELL)
        nodes = self.lower + self.cell * np.stack(np.indices(shape), axis=-1).reshape(-1, 3)
        self.values = cKDTree(points).query(nodes)[0].reshape(shape)

    def _grid(self, points: np.ndarray, cell: float) -> np.ndarray:
        """Sets the grid (cell, lower corner) around the points, REACH beyond them; returns its shape."""
        self.cell, self.lower = cell, points.min(axis=0) - self.REACH
        return np.ceil((points.max(axis=0) + self.REACH - self.lower) / cell).astype(int) + 1

    def __call__(self, query: np.ndarray, cap: float) -> np.ndarray:
        grid = ((query - self.lower) / self.cell).T
        distance = map_coordinates(self.values, grid, order=1, mode="constant", cval=np.inf)
        return np.minimum(distance - self.inflation, cap)


class SceneField(DistanceField):
    """Distance to a scene given as many points (e.g. the camera's: measured surface points and the centres of the
    cubes hidden behind them). Within NEAR of them, where clearances are judged, it is the exact distance to the
    points (k-d tree) at the grid's nodes; farther, the Euclidean distance transform of the grid's cells that hold
    a point (within a cell's diagonal): fast for many points, and the grid only shapes the cost there."""

    NEAR = 0.04  # m: beyond the largest sphere's radius plus STOMP's required clearance

    def __init__(self, points: np.ndarray, cell: float, inflation: float = 0.0):  # (not DistanceField's)
        self.inflation = inflation
        shape = self._grid(points, cell)
        occupied = np.zeros(shape, bool)
        index = np.clip(np.rint((points - self.lower) / cell).astype(int), 0, shape - 1)
        occupied[index[:, 0], index[:, 1], index[:, 2]] = True
        self.values = distance_transform_edt(~occupied, sampling=cell)
        near = self.values < self.NEAR + cell
        self.values[near] = cKDTree(points).query(self.lower + cell * np.argwhere(near))[0]


@dataclass
class CarriedPoints:
    """An object the hands carry, as spheres fixed to one of the robot's bodies: kept clear of the scene."""

    slot: int  # the body's index in the batched kinematics' poses
    points_B: np.ndarray  # M x 3 sphere centres in that body's frame, m
    radius: float  # m


class Obstacles:
    """The scene for the sphere model: oriented boxes and point sets (e.g. an object's surface), and what
    the robot carries through it (`carried`, optional)."""

    def __init__(self):
        self.boxes: list[tuple[np.ndarray, np.ndarray]] = []  # (X_BW 4x4, half sizes)
        self.fields: list[DistanceField] = []
        self.carried: CarriedPoints | None = None

    def carrying(self, carried: CarriedPoints) -> "Obstacles":
        """The same scene with the robot carrying `carried`."""
        scene = Obstacles()
        scene.boxes, scene.fields, scene.carried = self.boxes, self.fields, carried
        return scene

    def add_box(self, X_WB: np.ndarray, size) -> "Obstacles":
        self.boxes.append((np.linalg.inv(X_WB), 0.5 * np.asarray(size, float)))
        return self

    def add_points(self, points_W: np.ndarray, inflation: float = 0.0) -> "Obstacles":
        """A surface given by points; distances to it are reduced by `inflation` (m), e.g. half their spacing."""
        self.fields.append(DistanceField(np.asarray(points_W, float), inflation))
        return self

    def add_scene(self, points_W: np.ndarray, cell: float, inflation: float = 0.0) -> "Obstacles":
        """A scene of many points (N x 3 in W, e.g. as the camera saw it), on a grid of cell `cell` (m); distances to
        them are reduced by `inflation` (m)."""
        if len(points_W):
            self.fields.append(SceneField(np.asarray(points_W, float), cell, inflation))
        return self

    def distance(self, centres: np.ndarray, cap: float = 0.3) -> np.ndarray:
        """Distance (m, negative inside a box) from each point (... x 3) to the nearest obstacle, capped at `cap`.

        Nothing beyond the cap matters to the costs (it must exceed the margin plus the largest sphere).
        """
        flat = centres.reshape(-1, 3)
        nearest = np.full(len(flat), float(cap))
        for X_BW, half in self.boxes:  # in place: a large share of a STOMP iteration's time
            excess = flat @ X_BW[:3, :3].T
            excess += X_BW[:3, 3]
            np.abs(excess, out=excess)
            excess -= half
            largest = np.maximum(np.maximum(excess[:, 0], excess[:, 1]), excess[:, 2])  # (.max(axis=1) is slow)
            inside = np.minimum(largest, 0.0)
            np.maximum(excess, 0.0, out=excess)
            np.minimum(nearest, np.sqrt(np.einsum("ij,ij->i", excess, excess)) + inside, out=nearest)
        for field_ in self.fields:
            nearest = np.minimum(nearest, field_(flat, cap))
        return nearest.reshape(centres.shape[:-1])
