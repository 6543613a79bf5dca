"""Latent + rigid registration of an observed partial cloud to a category's shape space: which fits are tried, in
which order, and which wins.

The seen points lose their strays first (points in free space, far from their neighbours: farthest point sampling
would pick them first), then are thinned evenly (farthest point sampling): surfaces the camera sees at a slant then
weigh as much as those facing it. Several yaw hypotheses around the initial pose (and the pose turned end for end),
against the local minima where one end of an object is registered onto the other, are each fitted by EM
(shape_fit.ShapeFitter), their grasps placed on the handles seen (grasp_placement) and judged (fit_judging). In turn:

1. the latent fit: the hypothesis nearest the seen points;
2. where it is poor, or a grasp rests on the shape prior alone (unconfirmed), the fit with the shape's scale along
   O's axes: taken where the latent fit is poor or it is sound;
3. where that is poor too and a part prior is given (not in the pick), also each grasp's handle part's own offset:
   taken where sound;
4. where still poor, the category's wider space (a registrar of its own, its latent fit): taken where sound.

Beyond the latent space (2 and 3) the nearest hypothesis judged sound wins, if it lies about as near the points as the
nearest (nearest_sound).
"""

from collections.abc import Callable

import numpy as np
import open3d as o3d
from pydrake.math import RigidTransform, RotationMatrix

from systems.parallel import THREADS, parallel_map
from systems.perception.depth_cleaning import dense_inliers
from systems.perception.depth_view import DepthView
from systems.shape_space.fit_judging import Registration, SeenPoints, judged
from systems.shape_space.grasp_placement import placed_on_seen_handles
from systems.shape_space.shape_fit import ShapeFit, ShapeFitter
from systems.shape_space.space import ShapeSpace
from systems.shape_space.tool_placement import tool_centred_on_seen, tool_end_in_image, tool_on_seen_surface
from systems.shape_space.visibility import visible_from

# The seen points kept by the even thinning (more: slower, the grasps within 0.1 mm).
OBSERVED_POINTS = 300
# Yaw offsets (rad) tried about the initial pose; pi: the pose estimator's end-for-end flip.
YAW_HYPOTHESES = (0.0, -0.35, 0.35, np.pi)
# m: the part prior chosen with shape_fit.PART_RADIUS (Registrar's part_prior); not the pick's, which has none.
PART_PRIOR = 0.03
# Beyond the latent space, a yaw hypothesis judged sound replaces the nearest (poor) one only where its mean distance
# to the seen points is within this factor of the nearest's: one much further off is the shape turned end for end.
SOUND_FIT_MARGIN = 1.1
MIN_REGISTRATION_POINTS = 20  # finite observed points a registration needs


class Registrar:
    """Registers observed clouds to one category's ShapeSpace."""

    def __init__(
        self,
        space: ShapeSpace,
        upright: bool = True,
        prior_weight: float = 1.0,
        half_turn_symmetric: bool = False,
        scale_prior: float | None = None,
        wider: "Registrar | None" = None,
        part_prior: float | None = None,
    ):
        """Args:
        upright: the object stands upright (rotation about the world z only), else full 3D rotation.
        prior_weight: scales the latent prior against the data term.
        half_turn_symmetric: the category looks the same turned by pi about z_O (a pot): the end-for-end
            hypothesis is not tried, so the pose stays on the initial pose's side (and each grasp on its hand's).
        scale_prior: the standard deviation of the log of the shape's scale along each of O's axes, fitted
            beside the latent vector where the latent fit alone is poor; None: the latent space alone.
        wider: a registrar of the category's wider shape space (more of what its products vary in), tried last
            where this space's fits are poor; a grasp the camera cannot confirm in its fit makes the fit poor.
        part_prior: with scale_prior, where the scaled fit is poor too, each grasp's handle part is also offset on
            its own with this standard deviation per axis (m; PART_PRIOR, shape_fit.PART_RADIUS); None: not.
        """
        self.space = space
        self.wider = wider
        self.scale_prior, self.part_prior = scale_prior, part_prior
        self.yaw_hypotheses = tuple(h for h in YAW_HYPOTHESES if not (half_turn_symmetric and h == np.pi))
        self.fitter = ShapeFitter(space, upright, prior_weight, handle_parts=part_prior is not None)

    def register(
        self,
        observed_W: np.ndarray,
        X_WO_initial: RigidTransform,
        viewpoint_W: np.ndarray | None = None,
        view: DepthView | None = None,
    ) -> Registration:
        """Fits pose and shape to observed points (N x 3, W) from an initial pose; the best hypothesis wins.

        viewpoint_W: where the points were seen from (the camera's position in W, m); None: the
            model's points all take part, as if the object were seen from everywhere, and the grasps' support
            (grasp_support) is not judged.
        view: the depth image the points came from: what hid parts of the object is then not held against a grasp.

        Raises:
            ValueError: fewer than 20 finite points, not an N x 3 array, or a viewpoint that is not 3 finite numbers.
        """
        observed = _check_cloud(observed_W)
        # Strays out before the even thinning, which would pick them first.
        inliers = dense_inliers(observed)
        if np.count_nonzero(inliers) >= MIN_REGISTRATION_POINTS:
            observed = observed[inliers]
        if viewpoint_W is not None:
            viewpoint_W = np.asarray(viewpoint_W, dtype=float)
            if viewpoint_W.shape != (3,) or not np.all(np.isfinite(viewpoint_W)):
                raise ValueError(f"the viewpoint must be 3 finite numbers (m, in W), got {viewpoint_W!r}")
        seen = SeenPoints(observed, evenly_thinned(observed, OBSERVED_POINTS), viewpoint_W, view)
        registration = self._latent_fit(seen, X_WO_initial)
        if self.scale_prior is not None and (registration.poor_fit or registration.unconfirmed):
            # A shape the latent space fits with both grasps seen keeps its latent fit exactly. (A scaled fit that
            # is not poor has both grasps confirmed: see Registration.poor_fit.)
            scaled = self._fit_beyond_latent(seen, X_WO_initial)
            if registration.poor_fit or not scaled.poor_fit:
                registration = scaled
        if registration.poor_fit and self.scale_prior is not None and self.part_prior is not None:
            # A handle moved where none was seen is not a handle: taken only where sound.
            parts = self._fit_beyond_latent(seen, X_WO_initial, self.part_prior)
            if not parts.poor_fit:
                registration = parts
        if registration.poor_fit and self.wider is not None:
            wider = self.wider._latent_fit(seen, X_WO_initial)
            wider.wider = True
            if not wider.poor_fit:
                registration = wider
        return registration

    def _latent_fit(self, seen: SeenPoints, X_WO_initial: RigidTransform) -> Registration:
        """The hypothesis nearest the seen points, in the latent space alone."""
        fits = self._fits(seen, X_WO_initial, None, None)
        return self._judged(min(fits, key=lambda fit: fit.fit_error_m), seen)

    def _fit_beyond_latent(
        self, seen: SeenPoints, X_WO_initial: RigidTransform, part_prior: float | None = None
    ) -> Registration:
        """The hypotheses fitted with the shape's scale (and with part_prior each handle part's offset), the winner
        chosen by nearest_sound."""
        fits = self._fits(seen, X_WO_initial, self.scale_prior, part_prior)
        return nearest_sound(fits, lambda fit: self._judged(fit, seen))

    def _fits(
        self, seen: SeenPoints, X_WO_initial: RigidTransform, scale_prior: float | None, part_prior: float | None
    ) -> list[ShapeFit]:
        """Each yaw hypothesis's fit, in the order of yaw_hypotheses: the initial pose turned about its origin."""
        starts = []
        for offset in self.yaw_hypotheses:
            X0 = RigidTransform(RotationMatrix.MakeZRotation(offset)) @ X_WO_initial
            starts.append(RigidTransform(X0.rotation(), X_WO_initial.translation()))
        # The hypotheses are independent: fitted at once on the cores (the same fits as one after the other).
        return parallel_map(
            lambda X0: self.fitter.fit(seen.thinned_W, X0, seen.viewpoint_W, scale_prior, part_prior), starts
        )

    def _judged(self, fit: ShapeFit, seen: SeenPoints) -> Registration:
        """One hypothesis's fit made a Registration: its grasps placed on what was seen, and judged."""
        shape_W, poses_W = self.fitter.surface_and_poses_W(fit)
        tool_W = self.fitter.tool_W(fit)
        if seen.viewpoint_W is not None:
            seen_model = shape_W[visible_from(shape_W, seen.viewpoint_W)]  # (the grasps' and the tool's placing)
            shape_W, poses_W = placed_on_seen_handles(shape_W, poses_W, seen.observed_W, seen_model)
            if tool_W is not None:
                beyond = self.space.tool_beyond
                placed = tool_on_seen_surface(tool_W, beyond, seen_model, seen.observed_W, shape_W, seen.viewpoint_W)
                tube = tool_centred_on_seen(placed, beyond, seen.observed_W)  # across: onto the seen tube's axis
                if seen.view is not None:  # along the axis: where the colour mask ends; then across again there
                    surface_W = shape_W + tube.tool_W.tip - tool_W.tip
                    placed = tool_end_in_image(tube.tool_W, beyond, surface_W, seen.view, tube.end_radius)
                    tube = tool_centred_on_seen(placed, beyond, seen.observed_W)
                tool_W = tube.tool_W
        return judged(fit, shape_W, poses_W, seen, tool_W)


def nearest_sound(fits: list[ShapeFit], judge: Callable[[ShapeFit], Registration]) -> Registration:
    """Of the hypotheses' fits beyond the latent space, the nearest the seen points that `judge` finds sound (not
    poor_fit) among those within SOUND_FIT_MARGIN of the nearest's distance; where none is, the nearest, judged.

    Beyond the latent space a stretched shape can lie nearer the points end for end (tall cans: the flipped fit hides
    a grasp behind the body). The fits are judged nearest first, THREADS at a time on the cores (the same
    registration as one after the other), and no further than the first batch with a sound one.
    """
    fits = sorted(fits, key=lambda fit: fit.fit_error_m)
    near = [fit for fit in fits if fit.fit_error_m <= SOUND_FIT_MARGIN * fits[0].fit_error_m]
    nearest = None
    for start in range(0, len(near), THREADS):
        batch = parallel_map(judge, near[start : start + THREADS])
        sound = [registration for registration in batch if not registration.poor_fit]
        if sound:
            return sound[0]
        if nearest is None:
            nearest = batch[0]
    return nearest


def evenly_thinned(points: np.ndarray, count: int) -> np.ndarray:
    """At most `count` of the points (N x 3), spread evenly over them (farthest point sampling).

    A camera samples the surfaces facing it densely and those it sees at a slant sparsely. Thinned at
    random, the fit would weigh the facing side most (a can seen from behind and above settled towards the camera)."""
    if len(points) <= count:
        return points
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    return np.asarray(cloud.farthest_point_down_sample(count).points)


def _check_cloud(points: np.ndarray) -> np.ndarray:
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"the observed cloud must be N x 3, got shape {points.shape}")
    points = points[np.all(np.isfinite(points), axis=1)]
    if len(points) < MIN_REGISTRATION_POINTS:
        raise ValueError(
            f"the observed cloud has {len(points)} finite points; registration needs at least {MIN_REGISTRATION_POINTS}"
        )
    return points
