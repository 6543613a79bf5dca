"""A fitted grasp frame moved onto the handle the camera saw about it (with a viewpoint only).

Each decoded grasp frame, with its pre-grasp, is moved onto the points seen about it (grasp_shift), then across its
handle where the fitted handle lies beside the one seen (handle_centring), and the reconstruction there with it.
"""

import numpy as np
import open3d as o3d
from pydrake.math import RigidTransform
from scipy.spatial import cKDTree

from systems.shape_space.handle_centring import handle_centring

GRASP_REGION = 0.04  # m: radius about a grasp frame
GRASP_MATCH = 0.015  # m: a model point farther than this from every seen point has no match
GRASP_NORMAL_NEIGHBOURS = 20  # seen points per normal estimate
GRASP_DAMPING = 0.5  # of the mean eigenvalue of sum n n^T: a direction the normals barely see hardly moves
GRASP_SHIFT_LIMIT = 0.03  # m: a longer shift is not trusted (the handle is not where the latent put it)


def grasp_shift(origin_W: np.ndarray, model_W: np.ndarray, observed_W: np.ndarray) -> np.ndarray:
    """How far (3, W, m) to move a grasp frame at origin_W (3, W, m) so that the model's surface about it lies
    on the points seen there: translation-only point-to-plane ICP of the model points (its visible side, N x 3,
    W) within GRASP_REGION of the frame onto the observed points (K x 3, W) there. Along a straight handle the seen
    normals say nothing and the damped steps leave the frame be; where the handle bends (an arc's apex) they
    place it along the handle too. Zero where too little is seen or the shift would exceed GRASP_SHIFT_LIMIT.
    """
    model = model_W[np.linalg.norm(model_W - origin_W, axis=1) < GRASP_REGION]
    seen = observed_W[np.linalg.norm(observed_W - origin_W, axis=1) < GRASP_REGION]
    shift = np.zeros(3)
    if len(model) < 10 or len(seen) < 20:
        return shift
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(seen))
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(GRASP_NORMAL_NEIGHBOURS))
    normals = np.asarray(cloud.normals)
    tree = cKDTree(seen)
    for _ in range(10):
        distance, index = tree.query(model + shift)
        matched = distance < GRASP_MATCH
        if matched.sum() < 10:
            return np.zeros(3)
        n = normals[index[matched]]
        along_normal = np.einsum("ij,ij->i", n, seen[index[matched]] - model[matched] - shift)
        A = n.T @ n
        shift += np.linalg.solve(A + GRASP_DAMPING * np.trace(A) / 3 * np.eye(3), n.T @ along_normal)
    return shift if np.linalg.norm(shift) < GRASP_SHIFT_LIMIT else np.zeros(3)


def placed_on_seen_handles(
    shape_W: np.ndarray, poses_W: dict[str, RigidTransform], observed_W: np.ndarray, seen_model: np.ndarray
) -> tuple[np.ndarray, dict[str, RigidTransform]]:
    """The fitted surface (K x 3, W) and control poses (POSE_NAMES -> X_WG) with each grasp and its pre-grasp moved
    onto the points seen about it (N x 3, W; grasp_shift, then handle_centring across its handle), and the surface
    about each grasp moved with it, fading out over GRASP_REGION / 2. seen_model: the surface's points visible from
    the camera (visible_from)."""
    poses = dict(poses_W)
    moves = np.zeros_like(shape_W)
    for side in ("left", "right"):
        # The pre-grasp moves with its grasp: the approach between them stays along z_G.
        origin = poses[f"{side}_grasp"].translation()
        shift = grasp_shift(origin, seen_model, observed_W)
        # Then across the handle onto the one seen, where the fitted handle lies beside it.
        shift = shift + handle_centring(RigidTransform(shift) @ poses[f"{side}_grasp"], seen_model + shift, observed_W)
        for kind in ("grasp", "pregrasp"):
            poses[f"{side}_{kind}"] = RigidTransform(shift) @ poses[f"{side}_{kind}"]
        # The handle is where it was seen: the reconstruction about the grasp moves with it, fading out.
        fade = np.exp(-np.sum((shape_W - origin) ** 2, axis=1) / (2 * (GRASP_REGION / 2) ** 2))
        moves += fade[:, None] * shift
    return shape_W + moves, poses
