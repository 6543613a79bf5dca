"""The scene as the camera sees it, for the planner: everything in view that is not the object to pick, and the
space hidden behind it.

Frames: C is the depth camera (z along the optical axis), W the world (z up).

From one depth image:
  * every pixel with a valid depth that is no flying pixel (depth_cleaning), outside the object's mask (grown by
    MASK_GROWTH_PX: its edge mixes object and background), back-projected to W;
  * kept where it is farther than OBJECT_SURFACE_M from the object's registered shape (its pixels the mask
    missed are the object's), above the table top (its height is known: the table's own surface is the planner's
    box), within reach (WORKSPACE_RADIUS_M of the robot's torso axis) and off the robot (its sphere model,
    SELF_MARGIN_M);
  * thinned to one measured point per SEEN_SPACING_M cube (the planner measures its distance to these points: a
    face is where the camera saw it, not up to a cube beyond); then, behind each SCENE_VOXEL_M cube of them, the
    space hidden from the camera along its ray, up to HIDDEN_DEPTH_M further (and never below the table top), as the
    centres of SCENE_VOXEL_M cubes: the camera cannot tell how deep an object is, so the space behind what it sees
    counts as occupied that far;
  * hidden space within TARGET_MARGIN_M of the object's reconstruction is the object's (where the far hand goes),
    and within SELF_MARGIN_M of the robot the robot's: not an obstacle. Only space hidden by other things is.
"""

import cv2
import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import CameraInfo, ImageDepth32F
from scipy.spatial import cKDTree

from systems.messages import Segmentation
from systems.parallel import THREADS
from systems.perception.depth_cleaning import flying_pixels
from systems.perception.pose_estimator import depth_to_points, voxel_thin
from systems.planning.sphere_model import off_the_robot

SEEN_SPACING_M = 0.005
SCENE_VOXEL_M = 0.01
HIDDEN_DEPTH_M = 0.10
MASK_GROWTH_PX = 4
TABLE_MARGIN_M = 0.012  # m above the known table top: below, a point is the table itself (or its noise)
WORKSPACE_RADIUS_M = 1.3  # m from the torso's axis
WORKSPACE_HEIGHT_M = 0.8  # m above the table top
SELF_MARGIN_M = 0.05  # m: the sphere model leaves parts of the fingers out by up to about 4 cm
TARGET_MARGIN_M = 0.03
OBJECT_SURFACE_M = 0.015  # m: a seen point this near the object's registered shape is the object's


def scene_points(
    depth: np.ndarray,
    object_mask: np.ndarray,
    intrinsics: CameraInfo,
    X_WC: RigidTransform,
    table_top_z: float,
    torso_axis_W: np.ndarray,
    robot_spheres_W: np.ndarray,
    object_cloud_W: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(seen, hidden): the scene's occupied points in W, as the module docstring says: N x 3 measured points (one per
    SEEN_SPACING_M cube) and M x 3 centres of SCENE_VOXEL_M cubes. object_mask: H x W bool (may be empty: nothing to
    leave out); object_cloud_W: the object's reconstruction (N x 3 in W), or None."""
    depth = np.where(np.isfinite(depth), depth, 0.0).astype(np.float32)
    mask = np.zeros(depth.shape, bool)
    if object_mask.shape == depth.shape and object_mask.any():
        size = 2 * MASK_GROWTH_PX + 1
        mask = cv2.dilate(object_mask.astype(np.uint8), np.ones((size, size), np.uint8)).astype(bool)
    keep = ~mask & ~flying_pixels(depth)
    points_W = X_WC.multiply(depth_to_points(depth, keep, intrinsics).T).T
    height = points_W[:, 2] - table_top_z
    reach = np.linalg.norm(points_W[:, :2] - torso_axis_W, axis=1)
    points_W = points_W[(height > TABLE_MARGIN_M) & (height < WORKSPACE_HEIGHT_M) & (reach < WORKSPACE_RADIUS_M)]
    points_W = off_the_robot(points_W, robot_spheres_W, SELF_MARGIN_M)
    if object_cloud_W is not None and len(object_cloud_W) and len(points_W):  # its pixels the mask missed
        points_W = points_W[cKDTree(object_cloud_W).query(points_W, workers=THREADS)[0] > OBJECT_SURFACE_M]
    if not len(points_W):
        return np.zeros((0, 3)), np.zeros((0, 3))
    seen = voxel_thin(points_W, SEEN_SPACING_M)
    cubes = voxel_centres(points_W)
    rays = cubes - X_WC.translation()
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    steps = np.arange(1, int(round(HIDDEN_DEPTH_M / SCENE_VOXEL_M)) + 1) * SCENE_VOXEL_M
    behind = (cubes[:, None, :] + steps[None, :, None] * rays[:, None, :]).reshape(-1, 3)
    behind = behind[behind[:, 2] > table_top_z + TABLE_MARGIN_M]
    hidden = voxel_centres(behind) if len(behind) else np.zeros((0, 3))
    if len(hidden):
        hidden = hidden[cKDTree(seen).query(hidden, workers=THREADS)[0] > 0.5 * SCENE_VOXEL_M]  # (not seen already)
    if object_cloud_W is not None and len(object_cloud_W) and len(hidden):
        hidden = hidden[cKDTree(object_cloud_W).query(hidden, workers=THREADS)[0] > TARGET_MARGIN_M]
    # The robot's own shadow (behind parts of it the sphere model leaves out, e.g. the fingers) is not an obstacle.
    return seen, off_the_robot(hidden, robot_spheres_W, SELF_MARGIN_M)


def voxel_centres(points: np.ndarray) -> np.ndarray:
    """The centres of the SCENE_VOXEL_M cubes (on the world's grid) that hold points (N x 3, m; none for none)."""
    if not len(points):
        return np.zeros((0, 3))
    cells = np.unique(np.floor(voxel_thin(points, SCENE_VOXEL_M) / SCENE_VOXEL_M).astype(np.int64), axis=0)
    return (cells + 0.5) * SCENE_VOXEL_M


class SceneCloud(LeafSystem):
    """The scene the camera sees, but for the object to pick, as occupied points for the planner (scene_points).

    .. pydrake_system::

        name: SceneCloud
        input_ports:
        - depth_image
        - camera_pose
        - segmentation
        - robot_spheres_W
        - object_cloud_W
        output_ports:
        - scene_cloud_W

    ``depth_image`` (ImageDepth32F, m) and ``camera_pose`` (X_WB of the camera body) of one frame; ``segmentation``
    (the object's mask in it); ``robot_spheres_W`` (S x 4, the robot's sphere model when the frame was taken: centre
    in W, radius; m); ``object_cloud_W`` (the object's reconstruction, N x 3 in W: the space hidden near it is the
    object's). ``scene_cloud_W``: the occupied points (N x 3 in W), seen then hidden (scene_points).

    Args:
        intrinsics, X_BC: the depth camera's intrinsics and its pose in the camera body.
        table_top_z: the table top's height in W, m (known).
        torso_axis_W: where the robot's torso axis meets the floor plane (x, y in W), m.
    """

    def __init__(self, intrinsics: CameraInfo, X_BC: RigidTransform, table_top_z: float, torso_axis_W):
        super().__init__()
        self.intrinsics, self.X_BC = intrinsics, X_BC
        self.table_top_z, self.torso_axis_W = table_top_z, np.asarray(torso_axis_W, float)
        self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F()))
        self.DeclareAbstractInputPort("camera_pose", AbstractValue.Make(RigidTransform()))
        self.DeclareAbstractInputPort("segmentation", AbstractValue.Make(Segmentation(False)))
        self.DeclareAbstractInputPort("robot_spheres_W", AbstractValue.Make(np.zeros((0, 4))))
        self.DeclareAbstractInputPort("object_cloud_W", AbstractValue.Make(np.zeros((0, 3))))
        self.DeclareAbstractOutputPort(
            "scene_cloud_W",
            lambda: AbstractValue.Make(np.zeros((0, 3))),
            self._calc,
            {self.all_input_ports_ticket()},
        )

    def _calc(self, context, output):
        image = self.GetInputPort("depth_image").Eval(context)
        if image.width() == 0:  # no frame yet
            output.set_value(np.zeros((0, 3)))
            return
        depth = np.asarray(image.data)[:, :, 0]
        X_WC = self.GetInputPort("camera_pose").Eval(context) @ self.X_BC
        segmentation = self.GetInputPort("segmentation").Eval(context)
        mask = segmentation.mask if segmentation.found else np.zeros(depth.shape, bool)
        seen, hidden = scene_points(
            depth,
            mask,
            self.intrinsics,
            X_WC,
            self.table_top_z,
            self.torso_axis_W,
            self.GetInputPort("robot_spheres_W").Eval(context),
            self.GetInputPort("object_cloud_W").Eval(context),
        )
        output.set_value(np.vstack([seen, hidden]))
