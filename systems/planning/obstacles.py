"""The scene for the sphere model: oriented boxes, point sets as distance fields (an object's surface, a perceived
cloud, the scene as the camera saw it), and what the robot carries through it. Obstacles are data
for one plan or check, built by their caller (systems/planning/world.py: PlanningWorld.planning_obstacles) and
passed in: nothing keeps them between plans.
"""

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import distance_transform_edt, map_coordinates
from scipy.spatial import cKDTree

from systems.parallel import THREADS
from systems.planning.kinematics import rotated

# m: a scene's distance field (many points) is exact this near them: the hands' spheres (0.031 m) plus STOMP's
# required clearance; the arms' larger spheres are judged on the transform's values (within 8.7 mm at 1 cm cells)
SCENE_NEAR = 0.04


class DistanceField:
    """Distance (m) to a point set, precomputed on a grid of cell `cell` around it, REACH beyond, and interpolated
    trilinearly; points beyond the grid get the cap.

    Within `near` of the points, where clearances are judged, the grid's nodes hold the exact distance to the points
    (k-d tree); farther, the Euclidean distance transform of the grid's cells that hold a point, within half a
    cell's diagonal of the exact one: there the grid only shapes the cost (a k-d tree query at every node costs
    several times as much).
    """

    CELL = 0.01  # m
    REACH = 0.15  # m
    # The largest arm sphere (0.061 m) plus STOMP's margin (0.02 m), and a little: beyond it only the torso's and
    # the pelvis' spheres (0.10-0.14 m) are judged, on the transform's values (within 8.7 mm at 1 cm cells).
    NEAR = 0.085  # m

    def __init__(self, points: np.ndarray, inflation: float = 0.0, cell: float = CELL, near: float = NEAR):
        self.inflation, self.cell = inflation, cell
        self.lower = points.min(axis=0) - self.REACH
        shape = np.ceil((points.max(axis=0) + self.REACH - self.lower) / cell).astype(int) + 1
        occupied = np.zeros(shape, bool)
        index = np.clip(np.rint((points - self.lower) / cell).astype(int), 0, shape - 1)
        occupied[index[:, 0], index[:, 1], index[:, 2]] = True
        self.values = distance_transform_edt(~occupied, sampling=cell)
        exact = self.values < near + cell  # (the transform is within a cell of the exact distance)
        # (The nodes' query on the cores: each node's nearest point found alone, the same on any number of threads.)
        self.values[exact] = cKDTree(points).query(self.lower + cell * np.argwhere(exact), workers=THREADS)[0]

    def __call__(self, query: np.ndarray, cap: float) -> np.ndarray:
        grid = ((query - self.lower) / self.cell).T
        distance = map_coordinates(self.values, grid, order=1, mode="constant", cval=np.inf)
        return np.minimum(distance - self.inflation, cap)


# m: the carried spheres are grouped into clusters of about this radius, each bounded by one sphere: a cluster whose
# bounding sphere keeps clear of the scene by the cost's margin is not placed sphere by sphere (most of a held move's
# carried spheres, most of the time).
CLUSTER_RADIUS = 0.05


@dataclass
class CarriedPoints:
    """An object the hands carry, as spheres fixed to one of the robot's bodies: kept clear of the scene."""

    slot: int  # the body's index in the batched kinematics' poses
    points_B: np.ndarray  # M x 3 sphere centres in that body's frame, m
    radius: float  # m

    def __post_init__(self):
        chosen, self.cluster_of = clusters(self.points_B, CLUSTER_RADIUS)  # cluster_of: M, each sphere's cluster
        self.cluster_centres_B = self.points_B[chosen]  # K x 3, m
        self.clusters = Groups(self.cluster_of, len(chosen))
        offsets = np.linalg.norm(self.points_B - self.cluster_centres_B[self.cluster_of], axis=1)
        reach = np.maximum.reduceat(offsets[self.clusters.members], self.clusters.first)
        self.cluster_radii = reach + self.radius  # K, m: each cluster's spheres lie within


class Groups:
    """Items (spheres) by the group (cluster, body) each belongs to, to pick out every member of a few groups."""

    def __init__(self, group_of: np.ndarray, groups: int):
        self.members = np.argsort(group_of, kind="stable")  # group by group: members[first[g]:first[g] + count[g]]
        self.count = np.bincount(group_of, minlength=groups)
        self.first = np.cumsum(self.count) - self.count

    def expand(self, rows: np.ndarray, groups: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(row, member) of every member of group groups[i] in row rows[i], for all i (each row's in order when
        the pairs are, as np.nonzero gives them)."""
        count = self.count[groups]
        start = np.repeat(self.first[groups] - (np.cumsum(count) - count), count)  # each one's offset in members
        return np.repeat(rows, count), self.members[start + np.arange(len(start))]


def placed(points_B: np.ndarray, X_WB: np.ndarray) -> np.ndarray:
    """Points fixed to a body (M x 3, m, in its frame B) where the body is at each pose X_WB (B x 4 x 4): B x M x 3."""
    return points_B @ np.swapaxes(X_WB[:, :3, :3], 1, 2) + X_WB[:, None, :3, 3]


def placed_each(points_B: np.ndarray, X_WB: np.ndarray) -> np.ndarray:
    """Each point (... x 3, m, in its body's frame) where its own pose X_WB (... x 3 x 4, or ... x 4 x 4) puts it:
    ... x 3 (kinematics.rotated: numpy's stacks of 3 x 3 products are slow)."""
    return rotated(X_WB[..., :3, :3], points_B) + X_WB[..., :3, 3]


def covering_centres(points: np.ndarray, radius: float, most: int) -> np.ndarray:
    """Sphere centres among the points (N x 3, m) such that every point lies within `radius` (m) of one: farthest
    point sampling from the first point, stopped once the farthest is that near (or at `most` centres)."""
    points = np.asarray(points, float)
    return points[covering(points, radius, most)]


def clusters(points: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """The points (N x 3, m) grouped about covering_centres(points, radius): the centres' indices among the points
    (K), and each point's nearest centre (N, 0..K-1)."""
    chosen = covering(points, radius, len(points))
    return chosen, np.linalg.norm(points[:, None] - points[chosen][None], axis=2).argmin(axis=1)


def covering(points: np.ndarray, radius: float, most: int) -> np.ndarray:
    """The indices of covering_centres' centres among the points."""
    if not len(points):
        raise ValueError("no points to cover")
    chosen = [0]
    nearest = np.linalg.norm(points - points[0], axis=1)
    while len(chosen) < most and nearest.max() > radius:
        chosen.append(int(nearest.argmax()))
        np.minimum(nearest, np.linalg.norm(points - points[chosen[-1]], axis=1), out=nearest)
    return np.array(chosen)


class Obstacles:
    """The scene for the sphere model: oriented boxes and point sets (e.g. an object's surface), and what
    the robot carries through it (`carried`, optional)."""

    def __init__(self):
        self.boxes: list[tuple[np.ndarray, np.ndarray]] = []  # (X_BW 4x4, half sizes)
        self._box_arrays = (None, 0, None, None)  # (the list, its length, X_BW and half sizes as float32 arrays)
        self.fields: list[DistanceField] = []
        self.carried: CarriedPoints | None = None
        # How far (m, float32) each pair of the robot's own spheres (the planner's pairs, in its order) may overlap
        # without counting as a collision; None: not at all.
        self.self_overlap: np.ndarray | None = None

    def _copy(self) -> "Obstacles":
        scene = Obstacles()
        scene.boxes, scene.fields, scene.carried, scene.self_overlap = (
            self.boxes,
            self.fields,
            self.carried,
            self.self_overlap,
        )
        return scene

    def carrying(self, carried: CarriedPoints) -> "Obstacles":
        """The same scene with the robot carrying `carried`."""
        scene = self._copy()
        scene.carried = carried
        return scene

    def allowing_self_overlap(self, overlap: np.ndarray) -> "Obstacles":
        """The same scene with the robot's own sphere pairs allowed to overlap by `overlap` (m, one per pair)."""
        scene = self._copy()
        scene.self_overlap = np.asarray(overlap, np.float32)
        return scene

    def add_box(self, X_WB: np.ndarray, size) -> "Obstacles":
        self.boxes.append((np.linalg.inv(X_WB), 0.5 * np.asarray(size, float)))
        return self

    def add_points(self, points_W: np.ndarray, inflation: float = 0.0) -> "Obstacles":
        """A surface given by points; distances to it are reduced by `inflation` (m), e.g. half their spacing."""
        self.fields.append(DistanceField(np.asarray(points_W, float), inflation))
        return self

    def add_scene(self, points_W: np.ndarray, cell: float, inflation: float = 0.0) -> "Obstacles":
        """A scene of many points (N x 3 in W, e.g. as the camera saw it: measured surface points and the centres of
        the cubes hidden behind them), on a grid of cell `cell` (m), exact within SCENE_NEAR of them; distances to
        them are reduced by `inflation` (m)."""
        if len(points_W):
            self.fields.append(DistanceField(np.asarray(points_W, float), inflation, cell, near=SCENE_NEAR))
        return self

    def carried_clearances(self, X_WB: np.ndarray, margin: float) -> np.ndarray:
        """Clearance (m) of each carried sphere from the scene (B x M) with the carrying body at X_WB (B x 4 x 4):
        exact where the sphere's cluster comes within `margin` (m) of the scene; elsewhere the cluster's lower
        bound, at least `margin`. Nothing below the margin differs from placing every sphere."""
        carried = self.carried
        bound = self.distance(placed(carried.cluster_centres_B, X_WB)) - carried.cluster_radii  # B x K
        clearances = bound[:, carried.cluster_of]
        b, m = carried.clusters.expand(*np.nonzero(bound < margin))
        if len(b):  # each near cluster's spheres alone at their own pose
            points = placed_each(carried.points_B[m], np.ascontiguousarray(X_WB[:, :3])[b])
            clearances[b, m] = self.distance(points) - carried.radius
        return clearances

    def _float32_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """The boxes' X_BW (boxes x 4 x 4) and half sizes (boxes x 3 x 1) in float32, made again only when the box
        list changed (boxes are appended, or the list replaced)."""
        listed, length, X_BW, half = self._box_arrays
        if listed is not self.boxes or length != len(self.boxes):
            X_BW = np.array([X for X, _ in self.boxes], np.float32)
            half = np.array([half for _, half in self.boxes], np.float32)[:, :, None]
            self._box_arrays = (self.boxes, len(self.boxes), X_BW, half)
        return X_BW, half

    def distance(self, centres: np.ndarray, cap: float = 0.3) -> np.ndarray:
        """Distance (m, negative inside a box) from each point (... x 3) to the nearest obstacle, capped at `cap`.

        Nothing beyond the cap matters to the costs (it must exceed the margin plus the largest sphere). The boxes'
        distances in float32 (within a micrometre), on the points' coordinates as three rows: a large share of a
        STOMP iteration's time, 4-6 times less than in float64 on N x 3 rows.
        """
        flat = centres.reshape(-1, 3)
        points = flat.T.astype(np.float32)  # 3 x N
        nearest = np.full(len(flat), cap, np.float32)
        if self.boxes:  # every box at once: excess (boxes x 3 x N) of each point beyond each box's faces
            X_BW, half = self._float32_boxes()
            excess = X_BW[:, :3, :3] @ points
            excess += X_BW[:, :3, 3, None]
            np.abs(excess, out=excess)
            excess -= half
            largest = np.maximum(np.maximum(excess[:, 0], excess[:, 1]), excess[:, 2])
            np.maximum(excess, 0.0, out=excess)
            excess *= excess
            outside = np.sqrt(excess[:, 0] + excess[:, 1] + excess[:, 2])
            outside += np.minimum(largest, 0.0)
            np.minimum(nearest, outside.min(axis=0), out=nearest)
        nearest = nearest.astype(np.float64)
        for field_ in self.fields:
            nearest = np.minimum(nearest, field_(flat, cap))
        return nearest.reshape(centres.shape[:-1])
