"""Carries the canonical model's control poses onto the other models of a category, offline.

Annotating one model is the paper's promise; the space still needs every training model's grasp
frames (they are learnt beside its field). Offline, each whole model is at hand, so each grasp
frame is carried part by part: the canonical surface about the grasp (the handle and what it joins)
is moved by the model's CPD field, and its rigid best fit starts an ICP of that patch onto
the model's surface: the frame turns with the patch. Its origin then follows a second, local CPD of
the placed patch onto the model's surface about it, with a narrow kernel: a handle's size differs
from model to model, which a rigid patch cannot follow. The frame turns only as far as the handle's
axis does (swing). Pre-grasps keep their canonical pose relative to their grasps.

A field alone carries a frame poorly: the frames lie inside handles, where CPD's correspondences
slide along the tube and the field bends the frame. On the generated training models (train_3
canonical, the 7 others, both grasps), this puts grasp origins 3.0 mm (cans) and 2.2 mm (drills) from
the true ones, median (at most 13.5 and 10.3 mm), turned 2.2 and 1.4 degrees (benchmark_registration.py
--annotation canonical); a throwaway script found the fields alone 8.4 and 11.8 mm off.
"""

import numpy as np
import open3d as o3d
from pydrake.math import RigidTransform, RotationMatrix
from scipy.spatial.transform import Rotation

from systems.shape_space.cpd import DeformableResult, deformable_cpd, thinned

# m: radius of the canonical patch about each grasp point (a handle and where it joins the body).
PATCH_RADIUS = 0.08
ICP_MATCH = 0.01  # m: farther model points are no match in the ICP
ICP_ITERATIONS = 60
LOCAL_BETA = 0.02  # m: kernel width of the local CPD
LOCAL_REACH = 0.10  # m: the model's points this near the placed grasp point are the local CPD's target
LOCAL_SIGMA = 0.01  # m: the local CPD's starting width (the patch is already placed)
PATCH_POINTS = 1500  # at most, in the local CPD (fewer place the grasps less well)


def propagated_poses(
    canonical_surface: np.ndarray,
    canonical_poses: dict[str, RigidTransform],
    field: DeformableResult,
    model_points: np.ndarray,
    grasp_names=("left_grasp", "right_grasp"),
) -> dict[str, RigidTransform]:
    """The canonical control poses carried onto a model.

    Args:
        canonical_surface: the canonical model's surface points (N x 3, in its frame O, metres).
        canonical_poses: its control poses {name: X_OG}; each grasp's pre-grasp is named like it with "pregrasp".
        field: the CPD result that moves the canonical points onto the model (in the model's frame).
        model_points: the model's surface points (K x 3, in the frame the field maps into).
    """
    poses = {}
    for name in grasp_names:
        X_OG = canonical_poses[name]
        patch = canonical_surface[np.linalg.norm(canonical_surface - X_OG.translation(), axis=1) < PATCH_RADIUS]
        if len(patch) < 3:
            raise ValueError(f"the canonical surface has {len(patch)} points within {PATCH_RADIUS} m of its {name}")
        X_moved = refined_fit(patch, model_points, best_fit(patch, field.warp(patch)))
        placed = X_moved @ X_OG
        near = model_points[np.linalg.norm(model_points - placed.translation(), axis=1) < LOCAL_REACH]
        local = deformable_cpd(
            thinned(X_moved.multiply(patch.T).T, PATCH_POINTS),
            thinned(near, 2 * PATCH_POINTS),
            beta=LOCAL_BETA,
            lam=1.0,
            w=0.05,
            max_iterations=100,
            initial_sigma2=LOCAL_SIGMA**2,
        )
        origin = local.warp(placed.translation()[None])[0]
        poses[name] = RigidTransform(swing(X_OG.rotation(), X_moved.rotation()), origin)
        pregrasp = name.replace("grasp", "pregrasp")
        poses[pregrasp] = poses[name] @ X_OG.InvertAndCompose(canonical_poses[pregrasp])
    return {name: poses[name] for name in canonical_poses if name in poses}


def swing(R_OG: RotationMatrix, turn: RotationMatrix) -> RotationMatrix:
    """R_OG turned only as far as its x axis (the handle's axis) turns under `turn`, by the shortest rotation.

    A handle is a tube: a patch fit fixes its axis, but its roll about the axis only loosely, and that roll
    would swing the hand's approach (z) about the handle. The approach keeps the canonical's direction but
    for what the axis's turn forces.
    """
    axis = R_OG.col(0)
    moved = turn.multiply(axis)
    return RotationMatrix(Rotation.align_vectors(moved[None], axis[None])[0].as_matrix()) @ R_OG


def best_fit(source: np.ndarray, target: np.ndarray) -> RigidTransform:
    """The rigid transform X minimising sum |X source_i - target_i|^2, rows corresponding (open3d's estimate)."""
    rows = np.arange(len(source))
    X = o3d.pipelines.registration.TransformationEstimationPointToPoint().compute_transformation(
        _cloud(source), _cloud(target), o3d.utility.Vector2iVector(np.column_stack([rows, rows]))
    )
    return RigidTransform(X)


def refined_fit(source: np.ndarray, target: np.ndarray, initial: RigidTransform) -> RigidTransform:
    """Point-to-point ICP of `source` onto `target`, from `initial`."""
    result = o3d.pipelines.registration.registration_icp(
        _cloud(source),
        _cloud(target),
        ICP_MATCH,
        initial.GetAsMatrix4(),
        o3d.pipelines.registration.TransformationEstimationPointToPoint(),
        o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=ICP_ITERATIONS),
    )
    return RigidTransform(result.transformation)


def _cloud(points: np.ndarray) -> o3d.geometry.PointCloud:
    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
