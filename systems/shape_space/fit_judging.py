"""A fit judged against what the camera saw: the Registration and why it may not be trusted (poor_fit).

A fit that leaves many seen points off the fitted shape, puts a handle where none was seen, or puts surface where the
camera saw through says so (Registration.poor_fit) rather than hand on grasps centimetres off; so does a fit beyond
the latent space with a grasp the camera cannot confirm. The thresholds' measurements are in
docs/history/registration_parameters.md.
"""

from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RigidTransform
from scipy.spatial import cKDTree

from systems.perception.depth_view import DepthView
from systems.shape_space.shape_fit import ShapeFit
from systems.shape_space.space import GRASP_NAMES
from systems.shape_space.tool_frame import ToolFrame
from systems.shape_space.visibility import visible_from

# A fit is poor when fewer than MIN_INLIER_SHARE of the points it saw lie within FIT_INLIER_M of the fitted shape
# (good fits keep over 0.9, fits flying pixels pulled centimetres off under 0.25).
FIT_INLIER_M = 0.01
MIN_INLIER_SHARE = 0.8
# Each grasp must be where its handle was seen: of the fitted surface visible from the camera within SUPPORT_M of
# a grasp frame, at least MIN_GRASP_SUPPORT must lie within FIT_INLIER_M of a seen point. A grasp with too little
# visible surface about it is not judged: a drill's grip hidden under its housing is no evidence against it.
SUPPORT_M = 0.03
MIN_GRASP_SUPPORT = 0.6
MIN_SUPPORT_POINTS = 10  # visible surface points about a grasp that a support share needs
# The whole fitted surface the camera sees must lie on what it saw (surface_support): a fit that explains the seen
# points but not the view (a can fitted to a bowl's rim: the rest of it stands where the camera saw the table) is poor.
MIN_SURFACE_SUPPORT = 0.7
# m: a fitted point with a measured surface this much nearer in its pixel is hidden (an arm, another object): no
# evidence either way (without it, the arms in front of a rear handle refused sound fits).
HIDDEN_MARGIN = 0.02


@dataclass
class SeenPoints:
    """What the camera saw of the object, as the registration fits and judges it."""

    observed_W: np.ndarray  # the seen points, strays removed (N x 3, W): the grasps are judged on them
    thinned_W: np.ndarray  # an even thinning of them (K x 3, W): what the fits fit, and the inlier share's points
    viewpoint_W: np.ndarray | None  # where they were seen from (3, W, m); None: from everywhere, grasps not judged
    view: DepthView | None = None  # the depth image they came from: what hid the object is not held against it


@dataclass
class Registration:
    """The registration of a seen object: its pose and whole shape in W, its control poses, and the evidence the
    camera gives for them (poor_fit says whether they may be handed on)."""

    X_WO: RigidTransform
    latent: np.ndarray
    reconstructed_W: np.ndarray  # the whole deformed canonical shape, M x 3 in W
    grasp_poses_W: dict[str, RigidTransform]  # POSE_NAMES -> X_WG
    fit_error_m: float  # mean distance of the observed points to the fitted model
    iterations: int
    inlier_share: float  # of the (thinned) observed points, within FIT_INLIER_M of the reconstruction
    # Per grasp frame (GRASP_NAMES), the share of the visible fitted surface about it that was seen (grasp_support),
    # None where too little of it is visible to judge; empty without a viewpoint.
    grasp_support: dict[str, float | None] = field(default_factory=dict)
    scale: np.ndarray = field(default_factory=lambda: np.ones(3))  # of the latent shape along O's axes
    # The share of the whole fitted surface the camera sees that lies on what it saw (surface_support); None without
    # a viewpoint or where too little of it is visible to judge.
    surface_support: float | None = None
    wider: bool = False  # fitted in the category's wider shape space (Registrar's `wider`)
    scaled: bool = False  # fitted beyond the latent space with the shape's scale (and perhaps each handle's offset)
    # Each grasp's handle moved on its own (GRASP_NAMES x 3, m in O; Registrar's part pass), None where it was not.
    part_offsets_O: np.ndarray | None = None
    tool_W: ToolFrame | None = None  # the tool frame decoded with the fit, in W; None where the space has none

    @property
    def unconfirmed(self) -> bool:
        """A grasp the camera cannot confirm (its surface out of view or hidden) rests on the shape prior alone."""
        return any(share is None for share in self.grasp_support.values())

    @property
    def poor_fit(self) -> str:
        """Why the fit cannot be trusted ("" when it can).

        A latent fit may hand on a grasp the camera cannot confirm (a rear handle at the image's edge); a fit beyond
        the latent space may not: it was tried because the latent fit was poor, so the prior that placed that grasp
        does not hold for this shape."""
        if self.inlier_share < MIN_INLIER_SHARE:
            return (
                f"a poor fit: {100 * self.inlier_share:.0f}% of the seen points lie within "
                f"{1000 * FIT_INLIER_M:.0f} mm of the fitted shape (at least {100 * MIN_INLIER_SHARE:.0f}% expected)"
            )
        if self.surface_support is not None and self.surface_support < MIN_SURFACE_SUPPORT:
            return (
                f"a poor fit: {100 * self.surface_support:.0f}% of the fitted surface the camera sees lies on what it "
                f"saw (at least {100 * MIN_SURFACE_SUPPORT:.0f}% expected): the shape does not explain the view"
            )
        for name, share in self.grasp_support.items():
            hand = name.replace("_grasp", "")
            if share is None and self.wider:
                return (
                    f"a poor fit: the camera cannot confirm the {hand} grasp (out of view or hidden), and the shape "
                    "lies outside the paper-like family, where only the wider space's prior placed the grasp"
                )
            if share is None and self.scaled:
                return (
                    f"a poor fit: the camera cannot confirm the {hand} grasp (out of view or hidden), and the shape "
                    f"lies beyond its latent space (scaled {self.scale[0]:.2f} x {self.scale[1]:.2f} x "
                    f"{self.scale[2]:.2f}), where the latent prior that placed the grasp does not hold"
                )
            if share is not None and share < MIN_GRASP_SUPPORT:
                return (
                    f"a poor fit: the {hand} grasp is not where its handle was seen ({100 * share:.0f}% of the fitted "
                    f"surface the camera sees within {100 * SUPPORT_M:.0f} cm of it lies on seen points, at least "
                    f"{100 * MIN_GRASP_SUPPORT:.0f}% expected)"
                )
        return ""


def judged(
    fit: ShapeFit,
    reconstructed_W: np.ndarray,
    grasp_poses_W: dict[str, RigidTransform],
    seen: SeenPoints,
    tool_W: ToolFrame | None = None,
) -> Registration:
    """The fit, its whole surface (K x 3, W), its control poses (POSE_NAMES -> X_WG) and tool frame (W) as a
    Registration, with the evidence for and against them: the inlier share, and with a viewpoint each grasp's and
    the whole surface's support."""
    inlier_share = float(np.mean(cKDTree(reconstructed_W).query(seen.thinned_W)[0] < FIT_INLIER_M))
    support, seen_share = {}, None
    if seen.viewpoint_W is not None:
        seen_model = reconstructed_W[visible_from(reconstructed_W, seen.viewpoint_W)]
        observed = cKDTree(seen.observed_W, balanced_tree=False)  # (as dense_inliers': faster to build, the same)
        support = {
            name: grasp_support(grasp_poses_W[name].translation(), seen_model, observed, seen.view)
            for name in GRASP_NAMES
        }
        seen_share = surface_support(seen_model, observed, seen.view, MIN_SUPPORT_POINTS)
    return Registration(
        fit.X_WO,
        fit.latent,
        reconstructed_W,
        grasp_poses_W,
        fit.fit_error_m,
        fit.iterations,
        inlier_share,
        support,
        fit.scale,
        seen_share,
        scaled=fit.scaled,
        part_offsets_O=fit.part_offsets_O,
        tool_W=tool_W,
    )


def grasp_support(
    origin_W: np.ndarray,
    visible_model_W: np.ndarray,
    observed_W: np.ndarray | cKDTree,
    view: DepthView | None = None,
) -> float | None:
    """How much of the fitted surface about a grasp frame the camera confirms: surface_support of the fitted surface
    points visible from the camera (N x 3, W) within SUPPORT_M of the grasp's origin (3, W). Low where the fit put a
    handle the camera would have seen but did not. None (no evidence either way) with fewer than MIN_SUPPORT_POINTS
    such points: the object's own parts hide a drill's pistol grip under its housing from the chest camera on most
    held-out drills."""
    near = visible_model_W[np.linalg.norm(visible_model_W - origin_W, axis=1) < SUPPORT_M]
    return surface_support(near, observed_W, view, MIN_SUPPORT_POINTS)


def surface_support(
    visible_model_W: np.ndarray, observed_W: np.ndarray | cKDTree, view: DepthView | None = None, min_points: int = 1
) -> float | None:
    """The share of fitted surface points visible from the camera (N x 3, W) that the camera confirms: with a seen
    point (K x 3, W, or their k-d tree: built once for several calls) within FIT_INLIER_M. Given the depth image (view),
    a point also counts where the camera measured a surface within FIT_INLIER_M of its depth (a part the segmenter
    missed), and the points something other than the object hid are left out (a nearer surface off the object's
    pixels by more than HIDDEN_MARGIN: an arm, the gripper, another object). None with fewer than min_points such
    points."""
    points = visible_model_W
    if view is not None and len(points):
        looked_up = view.look_up(points)
        depth, measured = looked_up.depth, looked_up.measured
        hidden = np.isnan(measured) | ((measured < depth - HIDDEN_MARGIN) & ~looked_up.on_object)
        points, depth, measured = points[~hidden], depth[~hidden], measured[~hidden]
    if len(points) < min_points:
        return None
    seen = observed_W if isinstance(observed_W, cKDTree) else cKDTree(observed_W)
    supported = seen.query(points)[0] < FIT_INLIER_M
    if view is not None:
        supported |= np.abs(measured - depth) < FIT_INLIER_M
    return float(np.mean(supported))
