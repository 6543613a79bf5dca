"""The object tracker: where a known object is now, from one depth image and where it was expected.

A second look at an object the hands already hold. The segmenter cannot serve here: it never saw the
robot while it learned, and with the hands around the object it takes a hand for the object. What is
known instead: the object's reconstructed shape (the shape registrar's cloud from the first look, and
the pose it was at), where it is believed to be now, and where the robot's own body is.

  * points: every depth pixel, back-projected to W, inside the reconstruction's box at the expected
    pose (grown by CROP_MARGIN) and above the table (SUPPORT_CLEARANCE over the expected origin), less
    the robot's body (its sphere model where the arms stood when the frame was taken, SELF_MARGIN wider).
  * pose: the pose estimator's planar ICP (yaw about z, x-y; at the expected height) of those points
    onto the reconstruction, from the expected pose, over the points within INLIER_M of it (fingers and
    stray pixels the spheres missed are not the object); the expected tilt is kept.
  * refused (found False, the reason said) when fewer than MIN_POINTS points remain, the fit is poorer
    than MAX_FIT_ERROR_M, or it moves the object more than MAX_CORRECTION_M / MAX_CORRECTION_RAD: a
    look that disagrees that much is not trusted over the first one.
"""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import CameraInfo, ImageDepth32F
from scipy.spatial import cKDTree

from systems.pose_estimator import ObjectEstimate, depth_to_points, fit_yaw_translation, voxel_thin

CROP_MARGIN = 0.03  # m
SUPPORT_CLEARANCE = 0.01  # m: points lower than this over the object's origin are the table
SELF_MARGIN = 0.01  # m
MIN_POINTS = 50
INLIER_M = 0.015
ITERATIONS = 15
MAX_FIT_ERROR_M = 0.006  # mean distance of the inliers to the reconstruction (the looks at held cans: 3.8-4.1 mm)
MIN_INLIER_FRACTION = 0.8  # (those looks: 94-95 %; a fit stuck 35 deg or 8 cm off a test shape: 59-60 %)
MAX_CORRECTION_M = 0.05
MAX_CORRECTION_RAD = np.radians(30.0)


def off_the_robot(points_W: np.ndarray, robot_spheres_W: np.ndarray, margin: float = SELF_MARGIN) -> np.ndarray:
    """The points (N x 3 in W) farther than `margin` from every sphere (S x 4: centre in W, radius; m)."""
    if not len(robot_spheres_W) or not len(points_W):
        return points_W
    on_robot = np.zeros(len(points_W), bool)
    for index in cKDTree(points_W).query_ball_point(robot_spheres_W[:, :3], robot_spheres_W[:, 3] + margin):
        on_robot[index] = True
    return points_W[~on_robot]


class _ModelField:
    """The model's nearest point to any point (the interface of pose_estimator.NearestPointField, by k-d tree:
    one look queries it a few thousand times, too few to pay for a grid)."""

    def __init__(self, points: np.ndarray):
        self.points, self._tree = points, cKDTree(points)

    def query(self, query_points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._tree.query(query_points)


def track(points_W: np.ndarray, model_O: np.ndarray, X_WO_expected: RigidTransform) -> ObjectEstimate:
    """Planar ICP of observed points (N x 3 in W, already cropped) onto the model (M x 3 in O) from the
    expected pose; the refined X_WO (turned about z and moved in x-y from the expected one), or why not."""
    if len(points_W) < MIN_POINTS:
        return ObjectEstimate(False, message=f"only {len(points_W)} points where the object was expected")
    points_W = voxel_thin(points_W)
    field = _ModelField(model_O)
    p = X_WO_expected.translation()
    expected_yaw = RollPitchYaw(X_WO_expected.rotation()).yaw_angle()
    yaw, xy, _ = fit_yaw_translation(points_W, expected_yaw, p[:2], p[2], field, ITERATIONS, INLIER_M)
    # The fit turns the expected pose about W's z (its tilt in the hands, which one view cannot tell, is kept).
    turn = RotationMatrix.MakeZRotation(yaw - expected_yaw)
    X = RigidTransform(turn @ X_WO_expected.rotation(), [*xy, p[2]])
    distance, _ = field.query(X.inverse().multiply(points_W.T).T)
    inlier = distance < INLIER_M
    if np.count_nonzero(inlier) < MIN_POINTS:
        return ObjectEstimate(False, message=f"only {np.count_nonzero(inlier)} points lie on the expected shape")
    error, fraction = float(distance[inlier].mean()), float(inlier.mean())
    moved = float(np.linalg.norm(X.translation() - X_WO_expected.translation()))
    turned = abs(RollPitchYaw(X_WO_expected.rotation().inverse() @ X.rotation()).yaw_angle())
    summary = f"{len(points_W)} points, {100 * fraction:.0f}% within {1000 * INLIER_M:.0f} mm at {1000 * error:.1f} mm"
    change = f"moved {100 * moved:.1f} cm and {np.degrees(turned):.1f} deg from where it was expected"
    if error > MAX_FIT_ERROR_M or fraction < MIN_INLIER_FRACTION:
        return ObjectEstimate(False, X_WO=X, points_W=points_W, message=f"a poor fit: {summary}")
    if moved > MAX_CORRECTION_M or turned > MAX_CORRECTION_RAD:
        return ObjectEstimate(False, X_WO=X, points_W=points_W, message=f"not trusted: {change}")
    return ObjectEstimate(True, X_WO=X, points_W=points_W, message=f"{change} ({summary})")


class ObjectTracker(LeafSystem):
    """The object held by the hands, found again in a depth image near where it is expected.

    .. pydrake_system::

        name: ObjectTracker
        input_ports:
        - depth_image
        - camera_pose
        - robot_spheres_W
        - expected_X_WO
        - model_cloud_W
        - model_X_WO
        output_ports:
        - estimate

    ``depth_image`` (ImageDepth32F, m); ``camera_pose`` (RigidTransform X_WB of the camera body);
    ``robot_spheres_W`` (S x 4: the robot's sphere model, centre in W and radius, m); ``expected_X_WO``
    (RigidTransform: where the object is believed to be); ``model_cloud_W`` (M x 3: the reconstructed shape
    in W, m) at ``model_X_WO`` (RigidTransform: the pose it was reconstructed at). ``estimate``
    (ObjectEstimate: X_WO and the points it was fitted to, or why not).

    Args:
        intrinsics: the depth camera's. X_BC: the depth sensor in the camera body.
    """

    def __init__(self, intrinsics: CameraInfo, X_BC: RigidTransform | None = None):
        super().__init__()
        self.intrinsics, self.X_BC = intrinsics, X_BC or RigidTransform()
        self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F()))
        for name, model in (
            ("camera_pose", RigidTransform()),
            ("robot_spheres_W", np.zeros((0, 4))),
            ("expected_X_WO", RigidTransform()),
            ("model_cloud_W", np.zeros((0, 3))),
            ("model_X_WO", RigidTransform()),
        ):
            self.DeclareAbstractInputPort(name, AbstractValue.Make(model))
        # Computed from the inputs alone (not from time): a latched frame is tracked once.
        self.DeclareAbstractOutputPort(
            "estimate", lambda: AbstractValue.Make(ObjectEstimate(False)), self._calc, {self.all_input_ports_ticket()}
        )

    def estimate(self, depth, X_WB, robot_spheres_W, X_WO_expected, model_cloud_W, model_X_WO) -> ObjectEstimate:
        if len(model_cloud_W) < MIN_POINTS:
            return ObjectEstimate(False, message="no reconstructed shape to track")
        model_O = model_X_WO.inverse().multiply(np.asarray(model_cloud_W).T).T
        X_WC = X_WB @ self.X_BC
        everything = np.ones(depth.shape, bool)
        points_W = X_WC.multiply(depth_to_points(depth, everything, self.intrinsics).T).T
        in_O = X_WO_expected.inverse().multiply(points_W.T).T
        lower, upper = model_O.min(axis=0) - CROP_MARGIN, model_O.max(axis=0) + CROP_MARGIN
        lower[2] = max(lower[2], SUPPORT_CLEARANCE)
        inside = np.all((in_O >= lower) & (in_O <= upper), axis=1)
        points_W = off_the_robot(points_W[inside], robot_spheres_W)
        return track(points_W, model_O, X_WO_expected)

    def _calc(self, context, output):
        depth = np.asarray(self.GetInputPort("depth_image").Eval(context).data)[:, :, 0]
        values = [
            self.GetInputPort(name).Eval(context)
            for name in ("camera_pose", "robot_spheres_W", "expected_X_WO", "model_cloud_W", "model_X_WO")
        ]
        output.set_value(self.estimate(depth, *values))
