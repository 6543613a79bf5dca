"""The pose estimator system: object mask + depth image -> world point cloud and initial pose X_WO.

Frames: C is the depth camera (x right, y down, z along the optical axis), W the
world (z up), O the object (origin on its support surface, z up, x towards the
spout / chuck; see diagrams/generation/objects/).

  * points: the mask's pixels with a valid depth (NaN, inf and 0 are holes) that are no flying pixels
    (depth_cleaning: a real sensor's mixtures of two surfaces at depth edges), back-projected
    and moved to W. The pose fit below takes only the mask's interior (eroded by a few
    pixels: edges mix object and background).
  * z_O is the world's up axis (the category prior: objects stand upright), and the
    origin's height is the support surface's, measured in a ring of pixels around the mask.
  * a patch of that surface in the mask is left out (table_patch): the mask's points lying on the table, away
    from under the object. On the clear's tables the network gave the table between an object and the drop zone's
    marked line beside it the object's label (with the line: 7-16 % of its points on tune tables 0 and 10 and 8 of
    the first 20 validation tables, kinect_v2), and the shape fit to it was named poor.
  * yaw and origin (x, y): the points' principal horizontal axis and extent give a
    first guess, turned through YAW_CANDIDATES headings; each is refined by planar ICP
    against the category's template (a training instance's surface), scored by the mean
    point distance plus a free-space term (template points the camera would see but
    sees through), and the best few are refined further. The template's spout / chuck
    settles which end is which.
"""

import functools
import hashlib
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import trimesh
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.perception import BaseField, Fields, PointCloud
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import CameraInfo, ImageDepth32F
from scipy.spatial import cKDTree

from systems.messages import ObjectEstimate, PartRole, SeenPart, Segmentation
from systems.paths import cache_dir, save_npz_atomically
from systems.perception.depth_cleaning import flying_pixels
from systems.perception.depth_view import DepthView

MIN_POSE_POINTS = 50
MAX_OBJECT_RADIUS = 0.35  # m from the points' median: farther points are strays
# The table under an object (table_patch): a mask's point at most TABLE_BAND_M above the support surface, farther
# than FOOT_GROW_M (horizontally) from every point over FOOT_HEIGHT_M above it, lies on the table beside the object.
TABLE_BAND_M = 0.008
FOOT_HEIGHT_M = 0.02
FOOT_GROW_M = 0.015
# Fewer such points than this share of the mask's are the silhouette's edge at the object's foot (mixed pixels; at
# most 1.1 % on the 129 single objects' first pick frames of the tuning range), and are kept as they were.
TABLE_PATCH_SHARE = 0.03
BORDER_PIXELS = 3  # a part with pixels this near the image's border was cut by it
FIT_VOXEL_M = 0.006  # m: the points are thinned to one per voxel before fitting
GRID_CELL = 0.004  # m: resolution of the template's nearest-point field
MAX_FIT_POINTS = 400
COARSE_ITERATIONS = 4
COARSE_POINTS = 120
YAW_CANDIDATES = 12
FINE_CANDIDATES = 3
FINE_ITERATIONS = 12
FREE_SPACE_WEIGHT = 0.03  # m of point distance per unit fraction of the template the camera sees through
FREE_SPACE_MARGIN = 0.02  # m


@dataclass(frozen=True)
class CategoryPrior:
    """What the pose estimator knows of a category (diagrams/perception.py makes it from the catalog)."""

    template_mesh: Path  # the visual mesh of one training instance, in its object frame O
    # Where the object frame's origin sits relative to the object's extent: the mean centre (x, y) of the
    # training instances' bounding boxes in O, m.
    box_centre: tuple[float, float]
    # For a category that looks the same turned half a turn about z_O (a pot): the world yaw (rad) of its
    # presentation pose. Of the two equally good yaws the one nearer it is kept, so that the left grasp stays
    # on the robot's left. None: no such symmetry.
    symmetric_about_yaw: float | None = None


def depth_to_points(depth: np.ndarray, mask: np.ndarray, intrinsics: CameraInfo) -> np.ndarray:
    """Back-projects the masked pixels with a finite, positive depth to N x 3 points in C."""
    if depth.shape != mask.shape:
        raise ValueError(f"depth image {depth.shape} and mask {mask.shape} differ in size")
    rows, columns = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not len(rows):
        return np.zeros((0, 3))
    box = slice(rows[0], rows[-1] + 1), slice(columns[0], columns[-1] + 1)  # (the same pixels, in the same order)
    v, u = np.nonzero(mask[box] & np.isfinite(depth[box]) & (depth[box] > 0))
    v, u = v + rows[0], u + columns[0]
    z = depth[v, u].astype(float)
    x = (u - intrinsics.center_x()) * z / intrinsics.focal_x()
    y = (v - intrinsics.center_y()) * z / intrinsics.focal_y()
    return np.column_stack([x, y, z])


def voxel_thin(points: np.ndarray, size: float = FIT_VOXEL_M) -> np.ndarray:
    """One point (the first) per occupied voxel: near surfaces no longer outweigh far ones."""
    cells = np.floor(points / size).astype(np.int64)
    cells -= cells.min(axis=0)
    span = cells.max(axis=0) + 1
    # One integer key per cell: np.unique over int64 keys is 4x faster than over rows (axis=0).
    keys = (cells[:, 0] * span[1] + cells[:, 1]) * span[2] + cells[:, 2]
    _, first = np.unique(keys, return_index=True)
    return points[np.sort(first)]


class NearestPointField:
    """Nearest template point to any point, by lookup in a precomputed voxel grid (cell GRID_CELL).

    Far cheaper than a k-d tree query per ICP iteration; exact up to half a cell.
    Points outside the grid take the nearest cell's answer; their distance is still exact.
    """

    def __init__(self, points: np.ndarray, margin: float = 0.15, index: np.ndarray | None = None):
        """`index`: the grid, when it was computed before for these points (see category_template)."""
        self.points = points
        self.lower = points.min(axis=0) - margin
        self.shape = np.ceil((points.max(axis=0) + margin - self.lower) / GRID_CELL).astype(int) + 1
        if index is not None and index.shape == tuple(self.shape):
            self.index = index
            return
        centres = self.lower + GRID_CELL * np.stack(np.indices(self.shape), axis=-1).reshape(-1, 3)
        self.index = cKDTree(points).query(centres)[1].astype(np.int32).reshape(self.shape)

    def query(self, query_points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(distance, template index) of each query point (N x 3)."""
        cell = np.rint((query_points - self.lower) / GRID_CELL).astype(int)
        np.maximum(cell, 0, out=cell)
        np.minimum(cell, self.shape - 1, out=cell)
        index = self.index.ravel()[(cell[:, 0] * self.shape[1] + cell[:, 1]) * self.shape[2] + cell[:, 2]]
        offset = query_points - self.points[index]
        offset *= offset
        return np.sqrt(offset.sum(axis=1)), index  # (the Euclidean norm as numpy's, in fewer calls)


@functools.cache
def category_template(mesh_file: Path, count: int = 3000) -> tuple[np.ndarray, NearestPointField]:
    """Surface points (in O) of a category's template mesh, and their nearest-point field.

    The field takes seconds to compute; it is kept in the user's cache, keyed by the mesh and the grid.
    """
    mesh = trimesh.load(mesh_file, force="mesh")
    points, _ = trimesh.sample.sample_surface_even(mesh, count, seed=0)
    points = np.asarray(points)  # (not trimesh's tracked array: its bookkeeping slowed every ICP step)
    key = hashlib.sha256(mesh_file.read_bytes() + f"{count} {GRID_CELL}".encode()).hexdigest()[:16]
    path = cache_dir() / "pose_templates" / f"{key}.npz"
    if path.is_file():
        with np.load(path) as data:
            return points, NearestPointField(points, index=data["index"])
    field = NearestPointField(points)
    save_npz_atomically(path, index=field.index)
    return points, field


def _rotation_2d(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


@dataclass
class PlanarFit:
    """An upright pose X_WO = (Rz(yaw), [x, y, z]) fitted to observed points, and how well it fits."""

    yaw: float  # rad, about W's z
    xy: np.ndarray  # (2,): the origin's x, y in W, m
    error: float  # the points' mean distance to the template, m (estimate_pose adds its free-space cost)


def fit_yaw_translation(
    points_W, yaw, xy, z, field: NearestPointField, iterations, inlier_m: float = np.inf
) -> PlanarFit:
    """Planar ICP (yaw about z, translation in x-y; the origin at height z) of the observed points onto the
    template (`field`: its .points in O and .query(points in O) -> (distance, index)).

    Every observed point within inlier_m of the template counts (by default all: the spout and handles are few
    points, but they fix the yaw; the object tracker leaves out the fingers and strays around a held object).

    Returns the fit, its error over all the points.
    """

    in_O = np.empty_like(points_W)  # (filled in place: the small arrays' calls are most of the time)
    in_O[:, 2] = points_W[:, 2] - z
    planar_W = points_W[:, :2]

    def nearest(yaw, xy):
        in_O[:, :2] = (planar_W - xy) @ _rotation_2d(yaw)
        return field.query(in_O)

    for _ in range(iterations):
        distance, index = nearest(yaw, xy)
        used = distance < inlier_m
        if not used.any():
            break
        a, b = field.points[index, :2], planar_W
        if not used.all():
            a, b = a[used], b[used]
        # Best rotation + translation taking the matched template points (in O) to the observations (in W).
        a_mean, b_mean = a.sum(axis=0) / len(a), b.sum(axis=0) / len(b)  # (numpy's mean, in fewer calls)
        H = (a - a_mean).T @ (b - b_mean)
        yaw = np.arctan2(H[0, 1] - H[1, 0], H[0, 0] + H[1, 1])
        xy = b_mean - _rotation_2d(yaw) @ a_mean
    distance, _ = nearest(yaw, xy)  # the error of the pose returned
    return PlanarFit(yaw, xy, float(distance.mean()))


def estimate_pose(
    points_W: np.ndarray, prior: CategoryPrior, support_height: float | None = None, see_through=None
) -> RigidTransform:
    """Upright X_WO of an object of the category `prior` describes, from its observed surface points (N x 3 in W).

    Args:
        support_height: the table's height under the object (m); None takes the lowest points'.
        see_through: optional f(points_W) -> fraction of those points the camera would have seen
            but sees through (PoseEstimator's free-space test); it settles which end is which.
    """
    thinned = voxel_thin(points_W)
    if len(thinned) > MAX_FIT_POINTS:
        thinned = thinned[np.linspace(0, len(thinned) - 1, MAX_FIT_POINTS).astype(int)]
    z = np.percentile(thinned[:, 2], 1.0) if support_height is None else support_height
    template, field = category_template(prior.template_mesh)
    # Principal horizontal axis and the centre of the extent along it and across it.
    centred = thinned[:, :2] - thinned[:, :2].mean(axis=0)
    _, vectors = np.linalg.eigh(centred.T @ centred)
    axis_yaw = np.arctan2(vectors[1, -1], vectors[0, -1])
    R_axes = _rotation_2d(axis_yaw)
    in_axes = thinned[:, :2] @ R_axes
    extent_centre = R_axes @ (0.5 * (np.percentile(in_axes, 0.5, axis=0) + np.percentile(in_axes, 99.5, axis=0)))
    box_centre = np.asarray(prior.box_centre)
    coarse = thinned[np.linspace(0, len(thinned) - 1, min(len(thinned), COARSE_POINTS)).astype(int)]

    def fit(points, yaw, xy, iterations) -> PlanarFit:
        planar = fit_yaw_translation(points, yaw, xy, z, field, iterations)
        if see_through is not None:
            X_WO = RigidTransform(RotationMatrix.MakeZRotation(planar.yaw), [planar.xy[0], planar.xy[1], z])
            planar.error += FREE_SPACE_WEIGHT * see_through(X_WO.multiply(template[::4].T).T)
        return planar

    candidates = []
    for k in range(YAW_CANDIDATES):
        yaw = axis_yaw + k * 2 * np.pi / YAW_CANDIDATES
        candidates.append(fit(coarse, yaw, extent_centre - _rotation_2d(yaw) @ box_centre, COARSE_ITERATIONS))
    candidates.sort(key=lambda candidate: candidate.error)
    refined = [fit(thinned, c.yaw, c.xy, FINE_ITERATIONS) for c in candidates[:FINE_CANDIDATES]]
    best = min(refined, key=lambda candidate: candidate.error)
    yaw, xy = best.yaw, best.xy
    if prior.symmetric_about_yaw is not None:
        yaw = folded_yaw(yaw, prior.symmetric_about_yaw)
    return RigidTransform(RotationMatrix.MakeZRotation(yaw), [xy[0], xy[1], z])


def folded_yaw(yaw: float, reference: float) -> float:
    """Of yaw and yaw + pi (rad), the one nearer `reference`: the pose of a half-turn symmetric object that
    keeps O's z axis (the symmetry axis) where it is and turns O towards the reference."""
    if abs(np.angle(np.exp(1j * (yaw - reference)))) > np.pi / 2:
        yaw += np.pi
    return float(np.angle(np.exp(1j * yaw)))


def table_patch(
    mask: np.ndarray, depth: np.ndarray, X_WC: RigidTransform, intrinsics: CameraInfo, support_z: float
) -> np.ndarray | None:
    """The mask's pixels (H x W bool) that see the table beside the object: their points at most TABLE_BAND_M
    above the support surface (support_z, m in W), farther than FOOT_GROW_M horizontally from every point of the
    mask higher than FOOT_HEIGHT_M above it (the object's upper part: the table under its foot is not seen). None
    where they are fewer than TABLE_PATCH_SHARE of the mask's points, or nothing of the mask stands higher."""
    points_W = X_WC.multiply(depth_to_points(depth, mask, intrinsics).T).T
    height = points_W[:, 2] - support_z
    low, upper = height <= TABLE_BAND_M, height > FOOT_HEIGHT_M
    if np.count_nonzero(low) < TABLE_PATCH_SHARE * len(points_W) or not upper.any():
        return None
    apart, _ = cKDTree(points_W[upper, :2]).query(points_W[low, :2], distance_upper_bound=FOOT_GROW_M)
    on_table = np.zeros(len(points_W), bool)
    on_table[np.flatnonzero(low)[~np.isfinite(apart)]] = True
    if np.count_nonzero(on_table) < TABLE_PATCH_SHARE * len(points_W):
        return None
    # (depth_to_points keeps the order of np.nonzero over the mask's valid pixels)
    v, u = np.nonzero(mask & np.isfinite(depth) & (depth > 0))
    patch = np.zeros(mask.shape, bool)
    patch[v[on_table], u[on_table]] = True
    return patch


def to_point_cloud(points: np.ndarray) -> PointCloud:
    cloud = PointCloud(len(points), Fields(BaseField.kXYZs))
    cloud.mutable_xyzs()[:] = points.T
    return cloud


class PoseEstimator(LeafSystem):
    """Initial 6D pose of the segmented object from depth (paper §III).

    .. pydrake_system::

        name: PoseEstimator
        input_ports:
        - segmentation
        - depth_image
        - camera_pose
        output_ports:
        - estimate
        - point_cloud

    Inputs ``segmentation`` (Segmentation from the Segmenter), ``depth_image`` (ImageDepth32F, metres: NaN,
    inf and 0 are holes), ``camera_pose`` (RigidTransform X_WB of the camera body, the station's
    ``camera0.pose``). Outputs ``estimate`` (ObjectEstimate: found False, with the reason, when there is no
    object or too few points) and ``point_cloud`` (the object's points in W as a drake PointCloud).
    """

    def __init__(
        self,
        intrinsics: CameraInfo,
        priors: dict[str, CategoryPrior],
        X_BC: RigidTransform | None = None,
        erode_pixels: int = 2,
    ):
        """Args:
        intrinsics: the depth camera's. priors: per category name. X_BC: the depth sensor in the camera body.
        erode_pixels: the pose fit takes the mask shrunk by this much.
        """
        super().__init__()
        self.intrinsics, self.priors = intrinsics, priors
        self.X_BC = X_BC or RigidTransform()
        self.erode_pixels = erode_pixels
        for prior in priors.values():  # loaded now, not on the first image
            category_template(prior.template_mesh)
        self.segmentation_port = self.DeclareAbstractInputPort("segmentation", AbstractValue.Make(Segmentation(False)))
        self.depth_port = self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F()))
        self.camera_pose_port = self.DeclareAbstractInputPort("camera_pose", AbstractValue.Make(RigidTransform()))
        # Computed from the inputs alone (not from time): a latched frame is localised once.
        inputs = {self.all_input_ports_ticket()}
        self.estimate_port = self.DeclareAbstractOutputPort(
            "estimate", lambda: AbstractValue.Make(ObjectEstimate(False)), self._calc, inputs
        )
        self.DeclareAbstractOutputPort(
            "point_cloud", lambda: AbstractValue.Make(PointCloud()), self._calc_cloud, inputs
        )

    def estimate(self, segmentation: Segmentation, depth: np.ndarray, X_WB: RigidTransform) -> ObjectEstimate:
        if not segmentation.found:
            return ObjectEstimate(False, message=f"no object to localise ({segmentation.message})")
        prior = self.priors.get(segmentation.category)
        if prior is None:
            return ObjectEstimate(False, segmentation.category, message=f"no pose prior for {segmentation.category!r}")
        X_WC = X_WB @ self.X_BC
        depth = np.where(flying_pixels(depth), np.nan, depth)
        points_W = self._object_points_W(segmentation.mask, depth, X_WC)
        if len(points_W) < MIN_POSE_POINTS:
            return ObjectEstimate(
                False,
                segmentation.category,
                message=f"only {len(points_W)} of {segmentation.pixel_count} object pixels have a valid depth",
            )
        # The pose fit takes the mask's interior: edge pixels mix object and background depth. The
        # estimate keeps every point: the silhouette's edge is the shape's extent, and the shape
        # registration weighs strays down itself.
        mask, parts = segmentation.mask, segmentation.parts
        fit_points_W = self._interior_points_W(mask, depth, X_WC, points_W)
        support = self.support_height(mask, depth, X_WC, fit_points_W)
        table = None if support is None else table_patch(mask, depth, X_WC, self.intrinsics, support)
        if table is not None:  # (the mask less the table's patch: its points, the fit's, the parts')
            mask = mask & ~table
            parts = None if parts is None else np.where(table, 0, parts)
            points_W = self._object_points_W(mask, depth, X_WC)
            fit_points_W = self._interior_points_W(mask, depth, X_WC, points_W)
        X_WO = estimate_pose(fit_points_W, prior, support, self._free_space_test(mask, depth, X_WC))
        K = self.intrinsics
        view = DepthView(depth, X_WC, (K.focal_x(), K.focal_y()), (K.center_x(), K.center_y()), mask)
        return ObjectEstimate(
            True,
            segmentation.category,
            X_WO,
            points_W,
            f"{len(points_W)} points",
            X_WC.translation(),
            view=view,
            parts=self.seen_parts(parts, depth, X_WC, points_W),
        )

    def seen_parts(self, parts: np.ndarray | None, depth, X_WC, points_W) -> dict[PartRole, SeenPart]:
        """Each functional part's points in W (those of the object's points' stray-free extent), and whether the
        image's border cut it; nothing without a part image."""
        if parts is None:
            return {}
        seen = {}
        centre = np.median(points_W, axis=0)
        for role in (PartRole.LEFT_HANDLE, PartRole.RIGHT_HANDLE, PartRole.TOOL):
            mask = parts == role
            if not mask.any():
                continue
            part_W = X_WC.multiply(depth_to_points(depth, mask, self.intrinsics).T).T
            part_W = part_W[np.linalg.norm(part_W - centre, axis=1) < MAX_OBJECT_RADIUS]
            edge = BORDER_PIXELS
            cut_off = bool(mask[:edge].any() or mask[-edge:].any() or mask[:, :edge].any() or mask[:, -edge:].any())
            seen[role] = SeenPart(part_W, cut_off)
        return seen

    def _interior_points_W(self, mask, depth, X_WC, points_W: np.ndarray) -> np.ndarray:
        """The points of the mask's interior (eroded by erode_pixels), in W; points_W (the whole mask's) where
        the interior has too few."""
        if not self.erode_pixels:
            return points_W
        kernel = np.ones((2 * self.erode_pixels + 1,) * 2, np.uint8)
        eroded = cv2.erode(mask.astype(np.uint8), kernel).astype(bool)
        interior_W = self._object_points_W(eroded, depth, X_WC)
        return interior_W if len(interior_W) >= MIN_POSE_POINTS else points_W

    def _object_points_W(self, mask, depth, X_WC) -> np.ndarray:
        """The mask's pixels with a valid depth, in W (N x 3), less far strays."""
        points_W = X_WC.multiply(depth_to_points(depth, mask, self.intrinsics).T).T
        if len(points_W) < MIN_POSE_POINTS:
            return points_W
        # Far strays (a wrongly segmented patch of wall or table) are not part of the object.
        near = np.linalg.norm(points_W - np.median(points_W, axis=0), axis=1) < MAX_OBJECT_RADIUS
        return points_W[near] if np.count_nonzero(near) >= MIN_POSE_POINTS else points_W

    def _free_space_test(self, mask, depth, X_WC):
        """f(points_W) -> fraction of the points the camera would have seen but sees through.

        A point contradicts the image where it projects off the object's (grown) mask and the
        camera measured a surface behind it there; points hidden behind a nearer surface or
        outside the image are not evidence either way.
        """
        # Grown generously: a thin spout the segmenter missed must not count against the right pose.
        grown = cv2.dilate(mask.astype(np.uint8), np.ones((15, 15), np.uint8)).astype(bool)
        seen = np.where(np.isfinite(depth) & (depth > 0), depth, np.inf)
        X_CW = X_WC.inverse()
        K = self.intrinsics

        def see_through_fraction(points_W):
            p = X_CW.multiply(points_W.T)
            u = np.round(K.focal_x() * p[0] / p[2] + K.center_x()).astype(int)
            v = np.round(K.focal_y() * p[1] / p[2] + K.center_y()).astype(int)
            inside = (p[2] > 0) & (u >= 0) & (u < mask.shape[1]) & (v >= 0) & (v < mask.shape[0])
            if not inside.any():
                return 1.0
            u, v, z = u[inside], v[inside], p[2][inside]
            contradicted = ~grown[v, u] & (seen[v, u] > z + FREE_SPACE_MARGIN)
            return float(contradicted.mean())

        return see_through_fraction

    def support_height(self, mask, depth, X_WC, points_W) -> float | None:
        """Height (m) of the surface the object stands on, from the pixels in a ring around the mask.

        The ring's points no higher than a little above the object's lowest points are the table;
        None when too few are seen (then the object's lowest points decide).
        """
        near = cv2.dilate(mask.astype(np.uint8), np.ones((9, 9), np.uint8))
        far = cv2.dilate(mask.astype(np.uint8), np.ones((31, 31), np.uint8))
        ring_W = X_WC.multiply(depth_to_points(depth, (far > near), self.intrinsics).T).T
        bottom = np.percentile(points_W[:, 2], 2.0)
        table = ring_W[(ring_W[:, 2] < bottom + 0.02) & (ring_W[:, 2] > bottom - 0.15), 2]
        return float(np.median(table)) if len(table) >= MIN_POSE_POINTS else None

    def _calc(self, context, output):
        segmentation = self.segmentation_port.Eval(context)
        depth = np.asarray(self.depth_port.Eval(context).data)[:, :, 0]
        X_WB = self.camera_pose_port.Eval(context)
        started = time.perf_counter()
        estimate = self.estimate(segmentation, depth, X_WB)
        estimate.compute_s = time.perf_counter() - started
        output.set_value(estimate)

    def _calc_cloud(self, context, output):
        output.set_value(to_point_cloud(self.estimate_port.Eval(context).points_W))
