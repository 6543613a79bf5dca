"""The container finder: the pour task's container (its opening) in one depth frame, among whatever else stands on
the table.

Frames: W the world (z up), B the camera body (camera_pose is X_WB), C the depth sensor (X_BC, its mounting).

Every valid pixel (no flying pixel) outside the object's mask (grown by scene_cloud's MASK_GROWTH_PX) is
back-projected to W; the points above the known table top are thinned to one per SPACING_M cube and grouped into
clusters (DBSCAN, points within CLUSTER_EPS_M of one another). Each cluster is asked for an opening
(container_opening.opening_of: walls round a vertical axis, its highest band a circle about it of a container's
size; part of the round will do); of those that are one, the widest-seen rim (the most rim points) is the container
(a container the can cuts in two is two clusters: the larger part wins). An opening with something seen over it
(points_over) is none: a piece of a round body is round too. The robot's arms, the can's handle and a box are no
circle, and are passed over.
"""

import cv2
import numpy as np
import open3d as o3d
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import CameraInfo, ImageDepth32F

from systems.messages import ContainerSeen, Segmentation
from systems.perception.container_opening import Opening, opening_of
from systems.perception.depth_cleaning import flying_pixels
from systems.perception.pose_estimator import depth_to_points, voxel_thin
from systems.perception.scene_cloud import MASK_GROWTH_PX, TABLE_MARGIN_M

SPACING_M = 0.004  # m: the points are thinned to one per cube of this size
CLUSTER_EPS_M = 0.015  # m: DBSCAN's neighbourhood
MIN_CLUSTER_POINTS = 60  # a cluster of fewer thinned points is no container
# An opening has nothing over it: no more than MAX_POINTS_OVER thinned points within its radius less COVER_INSET_M of
# its axis, COVER_BAND_M above its rim (a lid, or the rest of a taller round thing: a piece of a can's body cut off
# by its spout had the can's top 11-20 cm over it; the hands at the robot's start hang higher).
COVER_INSET_M = 0.01
COVER_BAND_M = (0.02, 0.15)
MAX_POINTS_OVER = 20


def find_container(
    depth: np.ndarray, object_mask: np.ndarray, intrinsics: CameraInfo, X_WC: RigidTransform, table_top_z: float
) -> ContainerSeen:
    """The container's opening in one frame (H x W depth in m; object_mask H x W bool, the object to leave out, may
    be empty; X_WC the depth sensor's pose; table_top_z the table top's height in W, m)."""
    clusters = above_table_clusters(depth, object_mask, intrinsics, X_WC, table_top_z)
    seen = np.vstack(clusters) if clusters else np.zeros((0, 3))
    openings, refusals = [], []
    for points in clusters:
        what = f"a cluster of {len(points)} points"
        try:
            opening = opening_of(points, what)
        except ValueError as error:
            refusals.append(str(error))
            continue
        if (over := points_over(opening, seen)) > MAX_POINTS_OVER:
            refusals.append(f"{what}: no opening: {over} points seen over it (at most {MAX_POINTS_OVER})")
        else:
            openings.append(opening)
    if not openings:
        why = f"; the largest: {refusals[0]}" if refusals else ""
        return ContainerSeen(False, message=f"no container seen: {len(clusters)} clusters above the table{why}")
    best = max(openings, key=lambda opening: opening.rim_points)
    return ContainerSeen(
        True, best.centre_W, best.radius,
        f"a container's opening {200 * best.radius:.1f} cm across at {np.round(best.centre_W, 3)} (of "
        f"{len(openings)} openings in {len(clusters)} clusters)",
    )  # fmt: skip


def points_over(opening: Opening, points_W: np.ndarray) -> int:
    """How many of the points (N x 3 in W, m) lie over the opening: within its radius less COVER_INSET_M of its axis,
    COVER_BAND_M above its rim."""
    across = np.linalg.norm(points_W[:, :2] - opening.centre_W[:2], axis=1)
    above = points_W[:, 2] - opening.centre_W[2]
    low, high = COVER_BAND_M
    return int(np.sum((across < opening.radius - COVER_INSET_M) & (above > low) & (above < high)))


def above_table_clusters(
    depth: np.ndarray, object_mask: np.ndarray, intrinsics: CameraInfo, X_WC: RigidTransform, table_top_z: float
) -> list[np.ndarray]:
    """The seen points above the table top outside the object's mask (module docstring), as clusters (each N x 3 in
    W, m), the largest first."""
    depth = np.where(np.isfinite(depth), depth, 0.0).astype(np.float32)
    mask = np.zeros(depth.shape, bool)
    if object_mask.shape == depth.shape and object_mask.any():
        size = 2 * MASK_GROWTH_PX + 1
        mask = cv2.dilate(object_mask.astype(np.uint8), np.ones((size, size), np.uint8)).astype(bool)
    points_W = X_WC.multiply(depth_to_points(depth, ~mask & ~flying_pixels(depth), intrinsics).T).T
    points_W = points_W[points_W[:, 2] > table_top_z + TABLE_MARGIN_M]
    if len(points_W) < MIN_CLUSTER_POINTS:
        return []
    points_W = voxel_thin(points_W, SPACING_M)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points_W))
    labels = np.asarray(cloud.cluster_dbscan(CLUSTER_EPS_M, MIN_CLUSTER_POINTS))
    clusters = [points_W[labels == label] for label in range(labels.max() + 1)]
    return sorted(clusters, key=len, reverse=True)


class ContainerFinder(LeafSystem):
    """Finds the pour task's container's opening in a latched depth frame (module docstring).

    .. pydrake_system::

        name: ContainerFinder
        input_ports:
        - depth_image
        - camera_pose
        - segmentation
        output_ports:
        - container

    ``depth_image`` (ImageDepth32F, m); ``camera_pose`` (RigidTransform X_WB); ``segmentation`` (Segmentation: the
    object's mask, left out). ``container`` (ContainerSeen): the opening's centre and radius in W, or why none was
    found (an empty frame: "no frame yet").
    """

    def __init__(self, intrinsics: CameraInfo, X_BC: RigidTransform, table_top_z: float):
        super().__init__()
        self.intrinsics, self.X_BC, self.table_top_z = intrinsics, X_BC, table_top_z
        self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F()))
        self.DeclareAbstractInputPort("camera_pose", AbstractValue.Make(RigidTransform()))
        self.DeclareAbstractInputPort("segmentation", AbstractValue.Make(Segmentation(False)))
        self.DeclareAbstractOutputPort("container", lambda: AbstractValue.Make(ContainerSeen()), self._calc)

    def _calc(self, context, output):
        depth = self.get_input_port(0).Eval(context).data[..., 0]
        if depth.size == 0:
            output.set_value(ContainerSeen(False, message="the container: no frame yet"))
            return
        X_WC = self.get_input_port(1).Eval(context) @ self.X_BC
        mask = self.get_input_port(2).Eval(context).mask
        output.set_value(find_container(depth, mask, self.intrinsics, X_WC, self.table_top_z))
