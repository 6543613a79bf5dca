"""The registration's EM core: one fit of pose and shape to the seen points, from one start.

The model is the canonical shape deformed by the latent vector z and moved by X_WO: s_m = R (y_m + v_m(z)) + t;
beyond the latent space its scale along O's axes (and each grasp's handle part's offset) is fitted too. Like CPD,
the observed points are samples of a Gaussian mixture centred on the s_m with an outlier component, so points on the
unseen side of the model simply get no weight. EM alternates the posteriors (E-step) with one Gauss-Newton step
(analytic Jacobians in rotation, translation and z) on

    sum_mn p_mn |x_n - s_m|^2 / (2 sigma^2) + (1/2) sum_k z_k^2 / var_k,

the latent prior keeping the shape plausible. Given the viewpoint the cloud was seen from, only the model points
visible from it (hidden point removal) are mixture centroids: else the seen front pulls the model's unseen back
towards the camera too (a 1-2 cm bias along the view ray on cans and drills).
"""

from dataclasses import dataclass

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RotationMatrix
from scipy.spatial.distance import cdist

from systems.shape_space.cpd import gmm_posteriors, squared_distances
from systems.shape_space.space import GRASP_NAMES, ShapeSpace, scaled_poses
from systems.shape_space.tool_frame import ToolFrame
from systems.shape_space.visibility import visible_from

MODEL_POINTS = 800  # mixture centroids, an even choice of the canonical points (fewer cost the test cans accuracy)
OUTLIER_WEIGHT = 0.1
EM_ITERATIONS = 40
INITIAL_SIGMA = 0.02  # m
MAX_LOG_SCALE = 0.5  # the largest |log| of the shape's scale along an axis
# A handle part: the model points about a grasp frame of the mean shape, weighted exp(-d^2 / 2 PART_RADIUS^2) by
# their distance d to it; chosen with registration.PART_PRIOR on the tuning cans' first frames.
PART_RADIUS = 0.04  # m
TRANSLATION_PRIOR = 0.02  # m: standard deviation of the origin about the initial estimate
CONVERGED = 3e-3  # stop when sigma^2 changes by less than this, relative (tighter: slower, grasps within 0.1 mm)
VISIBILITY_EVERY = 5  # iterations between visibility updates


@dataclass
class ShapeFit:
    """One hypothesis's fit: the pose and shape EM settled on, and how near the seen points it lies."""

    X_WO: RigidTransform
    latent: np.ndarray  # z (q,)
    scale: np.ndarray  # of the latent shape along O's axes (3,); ones where it was not fitted
    fit_error_m: float  # mean distance of the (thinned) observed points to the nearest model point
    iterations: int  # EM iterations run
    scaled: bool  # fitted beyond the latent space (with a scale prior)
    # Each grasp's handle part's offset (GRASP_NAMES x 3, m in O), None where the parts were not fitted.
    part_offsets_O: np.ndarray | None = None


class ShapeFitter:
    """The model points of one ShapeSpace, fitted to seen points by EM (fit) and decoded whole (surface_and_poses_W).

    Args:
        space: the category's shape space.
        upright: the object stands upright (rotation about the world z only), else full 3D rotation.
        prior_weight: scales the latent prior against the data term.
        handle_parts: precompute each grasp's handle part (PART_RADIUS) so that fits may offset it (part_prior).
    """

    def __init__(self, space: ShapeSpace, upright: bool = True, prior_weight: float = 1.0, handle_parts: bool = False):
        self.space = space
        self.upright = upright
        self.prior_weight = prior_weight
        M = len(space.canonical_points)
        self.model_index = np.linspace(0, M - 1, min(MODEL_POINTS, M)).astype(int)
        mean_field, components = space.field_basis()
        # The model points at z = 0: the canonical points moved by the mean field, m x 3 in O.
        self.mean_shape = (space.canonical_points + mean_field)[self.model_index]
        self.B = np.transpose(components[:, self.model_index, :], (1, 2, 0))  # m x 3 x q
        self.inverse_variances = 1.0 / np.maximum(space.pca.variances, 1e-12)
        surface_O = space.reconstruct(np.zeros(space.latent_size))  # its one-off precomputation now, not per fit
        if handle_parts:
            # Each point's weight in each grasp's handle part (PART_RADIUS about the grasp frames of the mean shape):
            # the model points (m x 2) and the dense surface the registration returns (K x 2).
            zero = space.control_poses_at(np.zeros(space.latent_size))
            grasps_O = np.array([zero[name].translation() for name in GRASP_NAMES])

            def part_weights(points_O):
                return np.exp(-np.sum((points_O[:, None, :] - grasps_O) ** 2, axis=2) / (2 * PART_RADIUS**2))

            self.part_weights = part_weights(self.mean_shape)
            self.surface_part_weights = part_weights(surface_O)

    def surface_and_poses_W(self, fit: ShapeFit) -> tuple[np.ndarray, dict[str, RigidTransform]]:
        """The whole fitted surface (K x 3, W: the dense canonical surface carried by the field, scaled and its
        handle parts offset as fitted) and the control poses decoded with it (POSE_NAMES -> X_WG)."""
        shape_O = self.space.reconstruct(fit.latent)
        shape_O = shape_O * fit.scale if fit.scaled else shape_O
        poses_O = self.space.control_poses_at(fit.latent)
        if fit.scaled:  # (else exactly the latent fit's)
            poses_O = scaled_poses(poses_O, fit.scale)
        parts = fit.part_offsets_O
        if parts is not None:  # each handle part moved, its grasp and pre-grasp with it
            shape_O = shape_O + self.surface_part_weights @ parts
            for k, name in enumerate(GRASP_NAMES):
                for pose in (name, name.replace("grasp", "pregrasp")):
                    poses_O[pose] = RigidTransform(parts[k]) @ poses_O[pose]
        shape_W = fit.X_WO.multiply(shape_O.T).T
        return shape_W, {name: fit.X_WO @ X_OG for name, X_OG in poses_O.items()}

    def tool_W(self, fit: ShapeFit) -> ToolFrame | None:
        """The tool frame decoded with the fit (scaled as the shape is), in W; None where the space has none. (A
        handle part's offset leaves it: the tool is no handle.)"""
        tool_O = self.space.tool_at(fit.latent)
        if tool_O is None:
            return None
        return (tool_O.scaled(fit.scale) if fit.scaled else tool_O).moved(fit.X_WO)

    def fit(
        self,
        X: np.ndarray,
        X_WO_start: RigidTransform,
        viewpoint_W: np.ndarray | None,
        scale_prior: float | None = None,
        part_prior: float | None = None,
    ) -> ShapeFit:
        """EM from X_WO_start (and the mean shape) onto the seen points X (N x 3, W).

        viewpoint_W: where they were seen from (3, W, m); None: every model point is a centroid.
        scale_prior: the standard deviation of the log of the shape's scale along each of O's axes; None: not fitted.
        part_prior: that of each handle part's offset per axis (m; needs handle_parts); None: not fitted.
        """
        R, t = X_WO_start.rotation().matrix(), X_WO_start.translation().copy()
        q = len(self.inverse_variances)
        z = np.zeros(q)
        log_scale = np.zeros(3)
        sigma2 = INITIAL_SIGMA**2
        # Upright: turn about z only, and the origin stays on the support surface (the initial height).
        rotation_dofs = [2] if self.upright else [0, 1, 2]
        translation_dofs = [0, 1] if self.upright else [0, 1, 2]
        moved = slice(len(rotation_dofs), len(rotation_dofs) + len(translation_dofs))
        latent = slice(moved.stop, moved.stop + q)
        scaled = slice(latent.stop, latent.stop + (3 if scale_prior else 0))
        moved_parts = slice(scaled.stop, scaled.stop + (3 * len(GRASP_NAMES) if part_prior else 0))
        parts = np.zeros((len(GRASP_NAMES), 3))  # each handle part's offset in O, m
        t0 = t.copy()
        scaled_O = self.mean_shape  # the model in O at (z, scale), m x 3
        shape_O = scaled_O  # (and the handle parts' offsets)
        RS = shape_O @ R.T  # the model in O turned into W's axes, m x 3 (z = 0)
        model = RS + t
        # The mixture's centroids: the model points visible from the viewpoint (all without one). Only
        # their rows of the posteriors are ever non-zero, so only they are computed.
        rows = np.arange(len(model))
        squared = None
        # The squared distances in float32 about the seen points' centroid (coordinates within the object's
        # size: the rounding of |s|^2 + |x|^2 - 2 s.x stays within about 1e-8 m^2); X1's column of ones gives P's
        # row sums (P1) in the same product as P X.
        centre = X.mean(0)
        X32 = (X - centre).astype(np.float32)
        X1 = np.hstack([X32, np.ones((len(X), 1), np.float32)])
        latent_prior = self.prior_weight * np.diag(self.inverse_variances)
        translation_prior = np.eye(len(translation_dofs)) / TRANSLATION_PRIOR**2
        damping = 1e-9 * np.eye(moved_parts.stop)
        for iteration in range(1, EM_ITERATIONS + 1):  # noqa: B007 (the count is returned)
            if viewpoint_W is not None and iteration % VISIBILITY_EVERY == 1:
                rows = np.flatnonzero(visible_from(model, viewpoint_W))
                squared = None
            if squared is None:
                squared = squared_distances(model[rows] - centre, X32)
                # The Jacobian's blocks that change only with the rows: d s_m / d t, and the latent basis's rows.
                d_translation = np.broadcast_to(np.eye(3)[:, translation_dofs], (len(rows), 3, len(translation_dofs)))
                B_rows = self.B[rows]
            # E-step: posterior of each centroid for each observed point, with a uniform outlier term (in
            # float32, twice the speed; P X and P 1 summed by float32's matrix product, the rest in float64).
            P = gmm_posteriors(squared, sigma2, OUTLIER_WEIGHT, 3)
            PX1 = (P @ X1).astype(float)
            P1 = PX1[:, 3]
            Np = P1.sum()
            if Np < 1e-9:
                break
            # Gauss-Newton on sum_m P1_m |s_m - target_m / P1_m|^2 / (2 sigma2) + prior.
            residual = PX1[:, :3] - P1[:, None] * (model[rows] - centre)  # = P1_m (target_m - s_m)
            scale = np.exp(log_scale)
            blocks = [
                _skew_columns(RS[rows])[:, :, rotation_dofs],
                d_translation,
                R @ (scale[:, None] * B_rows),
            ]
            if scale_prior:  # d(R S y)/d(log s_k) = R[:, k] s_k y_k
                blocks.append(R[None, :, :] * scaled_O[rows][:, None, :])
            if part_prior:  # d s_m / d(offset of part k) = w_mk R
                blocks += [R[None, :, :] * self.part_weights[rows, k][:, None, None] for k in range(len(GRASP_NAMES))]
            J = np.concatenate(blocks, axis=2).reshape(3 * len(rows), -1)  # (3 rows) x (parameters)
            H = (J * np.repeat(P1, 3)[:, None]).T @ J / sigma2
            g = J.T @ residual.ravel() / sigma2
            # Priors: a plausible shape, and an origin near the initial estimate.
            H[latent, latent] += latent_prior
            g[latent] -= self.prior_weight * self.inverse_variances * z
            H[moved, moved] += translation_prior
            g[moved] -= (t - t0)[translation_dofs] / TRANSLATION_PRIOR**2
            if scale_prior:
                H[scaled, scaled] += np.eye(3) / scale_prior**2
                g[scaled] -= log_scale / scale_prior**2
            if part_prior:
                H[moved_parts, moved_parts] += np.eye(parts.size) / part_prior**2
                g[moved_parts] -= parts.ravel() / part_prior**2
            step = np.linalg.solve(H + damping, g)
            omega = np.zeros(3)
            omega[rotation_dofs] = step[: len(rotation_dofs)]
            R = _rotation(omega) @ R
            t[translation_dofs] += step[moved]
            z = z + step[latent]
            if scale_prior:
                log_scale = np.clip(log_scale + step[scaled], -MAX_LOG_SCALE, MAX_LOG_SCALE)
            if part_prior:
                parts = parts + step[moved_parts].reshape(parts.shape)
            scaled_O = (self.mean_shape + self.B @ z) * np.exp(log_scale)
            shape_O = scaled_O + self.part_weights @ parts if part_prior else scaled_O
            RS = shape_O @ R.T
            model = RS + t
            squared = squared_distances(model[rows] - centre, X32)
            previous, sigma2 = sigma2, max(float(np.vdot(P, squared)) / (3 * Np), 1e-8)
            if abs(previous - sigma2) < CONVERGED * previous:
                break
        error = float(np.sqrt(cdist(model, X, "sqeuclidean").min(0)).mean())
        return ShapeFit(
            X_WO=RigidTransform(RotationMatrix(R), t),
            latent=z,
            scale=np.exp(log_scale),
            fit_error_m=error,
            iterations=iteration,
            scaled=scale_prior is not None,
            part_offsets_O=parts if part_prior else None,
        )


def _skew_columns(v: np.ndarray) -> np.ndarray:
    """For rows v_m, the 3 x 3 matrices -[v_m]x: d(R v)/d(omega) for a small world-frame rotation omega."""
    out = np.zeros((len(v), 3, 3))
    out[:, 0, 1], out[:, 0, 2] = v[:, 2], -v[:, 1]
    out[:, 1, 0], out[:, 1, 2] = -v[:, 2], v[:, 0]
    out[:, 2, 0], out[:, 2, 1] = v[:, 1], -v[:, 0]
    return out


def _rotation(omega: np.ndarray) -> np.ndarray:
    """The rotation matrix of the rotation vector omega (3,), rad."""
    angle = float(np.linalg.norm(omega))
    return np.eye(3) if angle < 1e-12 else RotationMatrix(AngleAxis(angle, omega / angle)).matrix()
