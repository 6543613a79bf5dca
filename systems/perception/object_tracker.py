"""The object tracker: where a known object is now, from one depth image and where it was expected.

A second look at an object the hands already hold. The segmenter cannot serve here: it never saw the
robot while it learned, and with the hands around the object it takes a hand for the object. What is
known instead: the object's reconstructed shape (the shape registrar's cloud from the first look, and
the pose it was at), where it is believed to be now, and where the robot's own body is.

  * points: every depth pixel but flying ones (depth_cleaning), back-projected to W, inside the
    reconstruction's box at the expected pose (grown by CROP_MARGIN) and above the table (SUPPORT_CLEARANCE
    over the expected origin), less the robot's body (its sphere model where the arms stood when the frame
    was taken, TRACK_SELF_MARGIN_M wider).
  * pose: the pose estimator's planar ICP (yaw about z, x-y; at the expected height) of those points
    onto the reconstruction, from the expected pose, over the points within TRACK_INLIER_M of it (fingers and
    stray pixels the spheres missed are not the object), at the expected tilt.
  * tilt and height: an object held at two handles hangs a few degrees off and a few millimetres lower than
    planned (cans 3-7 deg, drills 1-2 deg on the training instances' looks). The planar pose is refined in
    6-DoF (refine_pose): robust point-to-plane Gauss-Newton on the points farther than FAR_FROM_ROBOT_M from
    the robot (fingers pull a fit towards where the hands are, that is, towards the belief), with priors
    about the planar pose, so that a direction the points barely constrain (a drill's roll about its barrel)
    stays where it was. The refined pose is taken when it tilts the object by at least min_tilt_change_rad from
    the planar pose; a smaller tilt is within what one look tells, and the planar pose stands (with too few points
    away from the hands, too). The default, MIN_TILT_CHANGE_RAD, suits a place or a pour; an aim takes every
    refined tilt (AIM_MIN_TILT_CHANGE_RAD), because there the bit's direction matters to a fraction of a degree
    (docs/history/perception_parameters.md).
  * refused (found False, the reason said) when fewer than MIN_TRACK_POINTS points remain, the fit is poorer
    than MAX_FIT_ERROR_M, or it moves the object more than MAX_CORRECTION_M / MAX_CORRECTION_RAD: a
    look that disagrees that much is not trusted over the first one.
"""

import time

import numpy as np
import open3d as o3d
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import CameraInfo, ImageDepth32F
from scipy.spatial import cKDTree

from systems.messages import ObjectEstimate
from systems.perception.depth_cleaning import flying_pixels
from systems.perception.pose_estimator import depth_to_points, fit_yaw_translation, voxel_thin
from systems.planning.sphere_model import off_the_robot

CROP_MARGIN = 0.03  # m
SUPPORT_CLEARANCE = 0.01  # m: points lower than this over the object's origin are the table
TRACK_SELF_MARGIN_M = 0.01  # m: the robot's sphere model grown by this
MIN_TRACK_POINTS = 50
TRACK_INLIER_M = 0.015
PLANAR_FIT_ITERATIONS = 15
# The fit's mean inlier distance to the reconstruction (m) and share of inliers: above what good looks at held cans
# show, below a fit stuck far off (docs/history/perception_parameters.md).
MAX_FIT_ERROR_M = 0.006
MIN_INLIER_FRACTION = 0.8
MAX_CORRECTION_M = 0.05
MAX_CORRECTION_RAD = np.radians(30.0)
FAR_FROM_ROBOT_M = 0.03
MIN_FAR_POINTS = 100
# refine_pose: Tukey weights of this width on the point-to-plane residuals (m), over pairs within TRACK_INLIER_M; the
# residuals' noise (m); neighbouring points share the reconstruction's shape error, so the points count as at most
# EFFECTIVE_POINTS independent measurements; and the priors' standard deviations about the planar pose.
TUKEY_M = TRACK_INLIER_M / 3
RESIDUAL_SIGMA_M = 0.002
EFFECTIVE_POINTS = 50
TILT_PRIOR_RAD = np.radians(3.0)
YAW_PRIOR_RAD = np.radians(5.0)
XY_PRIOR_M = 0.01
HEIGHT_PRIOR_M = 0.01
REFINE_ITERATIONS = 20
# Chosen on looks at training cans and drills carried over the box, and on the tuning drills' aims and cans' pours
# (docs/history/perception_parameters.md).
MIN_TILT_CHANGE_RAD = np.radians(2.0)
AIM_MIN_TILT_CHANGE_RAD = 0.0


class _ModelField:
    """The model's nearest point to any point (the interface of pose_estimator.NearestPointField, by k-d tree:
    one look queries it a few thousand times, too few to pay for a grid)."""

    def __init__(self, points: np.ndarray):
        self.points, self._tree = points, cKDTree(points)

    def query(self, query_points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._tree.query(query_points)


def _tilt(R: RotationMatrix) -> RotationMatrix:
    """The rotation less its turn about W's z: R = Rz(yaw) @ _tilt(R)."""
    rpy = RollPitchYaw(R)
    return RotationMatrix(RollPitchYaw(rpy.roll_angle(), rpy.pitch_angle(), 0.0))


def _planar_fit(points_W, model_O, X_from: RigidTransform) -> RigidTransform:
    """Planar ICP from X_from: its yaw and x-y refined, its tilt and height kept."""
    tilt = _tilt(X_from.rotation())
    field = _ModelField(tilt.multiply(model_O.T).T)
    p = X_from.translation()
    yaw_from = RollPitchYaw(X_from.rotation()).yaw_angle()
    planar = fit_yaw_translation(points_W, yaw_from, p[:2], p[2], field, PLANAR_FIT_ITERATIONS, TRACK_INLIER_M)
    return RigidTransform(RotationMatrix.MakeZRotation(planar.yaw) @ tilt, [*planar.xy, p[2]])


def _skew(a: np.ndarray) -> np.ndarray:
    """[a]x: [a]x b = a x b."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _rotation(omega: np.ndarray) -> RotationMatrix:
    angle = float(np.linalg.norm(omega))
    return RotationMatrix(AngleAxis(angle, omega / angle)) if angle > 0 else RotationMatrix()


def refine_pose(points_W: np.ndarray, model_O: np.ndarray, X_WO: RigidTransform) -> RigidTransform:
    """X_WO refined in 6-DoF so that the model (M x 3 in O) lies on the points (N x 3 in W): the most probable
    small motion x = (omega, v) of the object about the points' centroid c (p -> R(omega)(p - c) + c + v),
    by Gauss-Newton on robust point-to-plane residuals (Tukey, TUKEY_M) and Gaussian priors on the tilt and
    yaw (omega) and on the origin's move in x-y and height, about X_WO.

    Deterministic (numpy; open3d only estimates the model's normals): a pick's outcome must not depend on the
    thread count or the machine's load, as open3d's threaded registration sums could make it.
    """
    model_W = X_WO.multiply(model_O.T).T
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(model_W))
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(20))
    normals_W = np.asarray(cloud.normals)
    c = points_W.mean(axis=0)
    # The prior's rows: tilt (omega_x, omega_y), yaw (omega_z), and the origin's move omega x (o - c) + v.
    moves_origin = np.hstack([-_skew(X_WO.translation() - c), np.eye(3)])
    prior_rows = np.vstack([np.eye(6)[:3], moves_origin])
    prior_sigma = np.array([TILT_PRIOR_RAD, TILT_PRIOR_RAD, YAW_PRIOR_RAD, XY_PRIOR_M, XY_PRIOR_M, HEIGHT_PRIOR_M])
    prior_information = prior_rows.T @ (prior_rows / prior_sigma[:, None] ** 2)
    x = np.zeros(6)
    for _ in range(REFINE_ITERATIONS):
        R = _rotation(x[:3]).matrix()
        moved = (model_W - c) @ R.T + c + x[3:]
        distance, index = cKDTree(moved).query(points_W, distance_upper_bound=TRACK_INLIER_M)
        paired = np.isfinite(distance)
        if np.count_nonzero(paired) < MIN_FAR_POINTS:
            break
        p, m, n = points_W[paired], moved[index[paired]], normals_W[index[paired]] @ R.T
        residual = np.sum((p - m) * n, axis=1)
        weight = np.where(np.abs(residual) < TUKEY_M, (1.0 - (residual / TUKEY_M) ** 2) ** 2, 0.0)
        jacobian = -np.hstack([np.cross(m - c, n), n])  # d residual / d (a further small omega, v)
        scale = min(1.0, EFFECTIVE_POINTS / max(weight.sum(), 1.0)) / RESIDUAL_SIGMA_M**2
        H = scale * jacobian.T @ (weight[:, None] * jacobian) + prior_information
        g = scale * jacobian.T @ (weight * residual) + prior_information @ x
        step = -np.linalg.solve(H, g)
        x += step
        if np.linalg.norm(step) < 1e-7:
            break
    R = _rotation(x[:3])
    return RigidTransform(R, c + x[3:] - R.multiply(c)) @ X_WO


def track(
    points_W: np.ndarray,
    model_O: np.ndarray,
    X_WO_expected: RigidTransform,
    robot_spheres_W=None,
    min_tilt_change_rad: float = MIN_TILT_CHANGE_RAD,
) -> ObjectEstimate:
    """Planar ICP of observed points (N x 3 in W, already cropped) onto the model (M x 3 in O) from the
    expected pose, then the 6-DoF refinement of the points away from the robot (spheres S x 4, centre in W and
    radius, m) where it tilts the object by min_tilt_change_rad (rad) or more; the X_WO found, or why not."""
    if len(points_W) < MIN_TRACK_POINTS:
        return ObjectEstimate(False, message=f"only {len(points_W)} points where the object was expected")
    points_W = voxel_thin(points_W)
    X = _planar_fit(points_W, model_O, X_WO_expected)
    far = off_the_robot(points_W, np.zeros((0, 4)) if robot_spheres_W is None else robot_spheres_W, FAR_FROM_ROBOT_M)
    tilt_said = f"tilt kept ({len(far)} points away from the hands)"
    if len(far) >= MIN_FAR_POINTS:
        X_refined = refine_pose(far, model_O, X)
        tilt = (_tilt(X.rotation()).inverse() @ _tilt(X_refined.rotation())).ToAngleAxis().angle()
        height = X_refined.translation()[2] - X.translation()[2]
        said = f"hangs {np.degrees(tilt):.1f} deg and {1000 * height:+.0f} mm off the belief"
        if tilt >= min_tilt_change_rad:
            X, tilt_said = X_refined, said
        else:
            tilt_said = f"tilt kept ({said}: within what one look tells)"
    field = _ModelField(model_O)
    distance, _ = field.query(X.inverse().multiply(points_W.T).T)
    inlier = distance < TRACK_INLIER_M
    if np.count_nonzero(inlier) < MIN_TRACK_POINTS:
        return ObjectEstimate(False, message=f"only {np.count_nonzero(inlier)} points lie on the expected shape")
    error, fraction = float(distance[inlier].mean()), float(inlier.mean())
    moved = float(np.linalg.norm(X.translation()[:2] - X_WO_expected.translation()[:2]))
    turned = abs(RollPitchYaw(X_WO_expected.rotation().inverse() @ X.rotation()).yaw_angle())
    summary = (
        f"{len(points_W)} points, {100 * fraction:.0f}% within {1000 * TRACK_INLIER_M:.0f} mm at {1000 * error:.1f} mm"
    )
    change = f"moved {100 * moved:.1f} cm and {np.degrees(turned):.1f} deg from where it was expected; {tilt_said}"
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
        intrinsics: the depth camera's. X_BC: the depth sensor in the camera body. min_tilt_change_rad: the
        smallest tilt off the planar pose that a look takes (track()).
    """

    def __init__(
        self,
        intrinsics: CameraInfo,
        X_BC: RigidTransform | None = None,
        min_tilt_change_rad: float = MIN_TILT_CHANGE_RAD,
    ):
        super().__init__()
        self.intrinsics, self.X_BC = intrinsics, X_BC or RigidTransform()
        self.min_tilt_change_rad = min_tilt_change_rad
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
        if len(model_cloud_W) < MIN_TRACK_POINTS:
            return ObjectEstimate(False, message="no reconstructed shape to track")
        model_O = model_X_WO.inverse().multiply(np.asarray(model_cloud_W).T).T
        X_WC = X_WB @ self.X_BC
        surfaces = ~flying_pixels(depth)
        points_W = X_WC.multiply(depth_to_points(depth, surfaces, self.intrinsics).T).T
        in_O = X_WO_expected.inverse().multiply(points_W.T).T
        lower, upper = model_O.min(axis=0) - CROP_MARGIN, model_O.max(axis=0) + CROP_MARGIN
        lower[2] = max(lower[2], SUPPORT_CLEARANCE)
        inside = np.all((in_O >= lower) & (in_O <= upper), axis=1)
        points_W = off_the_robot(points_W[inside], robot_spheres_W, TRACK_SELF_MARGIN_M)
        return track(points_W, model_O, X_WO_expected, robot_spheres_W, self.min_tilt_change_rad)

    def _calc(self, context, output):
        depth = np.asarray(self.GetInputPort("depth_image").Eval(context).data)[:, :, 0]
        values = [
            self.GetInputPort(name).Eval(context)
            for name in ("camera_pose", "robot_spheres_W", "expected_X_WO", "model_cloud_W", "model_X_WO")
        ]
        started = time.perf_counter()
        estimate = self.estimate(depth, *values)
        estimate.compute_s = time.perf_counter() - started
        output.set_value(estimate)
