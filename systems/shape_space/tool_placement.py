"""A fitted tool frame moved onto the tool the camera saw (with a viewpoint only).

A latent shape gets a tool's direction right (its surface there turns as the tool does) but often not where the tool
ends: a spout's or chuck's length is what the few latent components fit least (a test can's spout tip 29 mm off
along its axis from a whole, true cloud). Where the camera sees the tool's end, the frame is moved there: along its
axis by as much as the seen points about the end reach beyond (or stop short of) the fitted surface's visible points
there, and across it by as much as their centroids differ across the axis (both sides seen from the same viewpoint,
so the visible half of a tube biases both alike).

Chosen on the tuning range extra_201-208 (48 rendered views, kinect_v2, 2026-12-03), tip error medians cans / drills:
as fitted 19.3 / 6.5 mm, moved along only 19.0 / 5.2 mm, along and across 11.0 / 8.8 mm (the drills' chuck is seen
with flying pixels about it; a dead band or a fit check of the across move helped neither). The centroids' premise
did not hold (a tube's seen near half and the fitted surface's differ): the tip is then moved across the axis onto
the centre of the seen tool's cross-sections (tool_centred_on_seen): tuning range 10.5 / 5.1 -> 3.8 / 4.3 mm
(2026-12-05, the drills' axis kept as the category's). That fit comes before the mask's end is read, which takes the
end as wide as the fitted tube there (not the fitted surface), and again after: 3.8 / 4.3 -> 2.8 / 2.6 mm, the drills
along their axis +3.4 -> +0.8 mm (median).
"""

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from systems.perception.depth_view import DepthView
from systems.shape_space.tool_frame import ToolFrame

# The window about the fitted tool's far end (m): from TOOL_WINDOW_BACK behind it to TOOL_WINDOW_AHEAD beyond it along
# the axis, within TOOL_WINDOW_RADIUS of the axis.
TOOL_WINDOW_BACK = 0.06
TOOL_WINDOW_AHEAD = 0.05
TOOL_WINDOW_RADIUS = 0.04
MIN_TOOL_POINTS = 15  # seen and visible model points each, in the window, for the frame to move
# Of the points' reach along the axis, this percentile (flying pixels off the end are not the end).
TOOL_END_PERCENTILE = 98
TOOL_SHIFT_LIMIT = 0.05  # m: a longer move is not trusted: the frame stays as fitted
TOOL_ITERATIONS = 5  # moves, the seen window following each
TOOL_END_LENGTH = 0.03  # m: the tool's last stretch, whose centroids say how far across the axis to move
# The tool's last TOOL_END_LENGTH spans at least this many pixels along the image for its end to be read there.
MIN_END_PIXELS = 5
# A depth sensor returns little of a surface seen more obliquely than this from its ray (a time-of-flight camera's
# light, a stereo pair's texture): the sides of a tool's outline. The fitted surface's points compared with the seen
# ones are those seen less obliquely (returned_points), deg.
GRAZING_LIMIT_DEG = 75.0
NORMAL_NEIGHBOURS = 12  # surface points per normal estimate
MASK_EDGE_PERCENTILE = 5  # of the mask's pixels across the tool's last stretch: its edges (a stray pixel is not one)
# The tool's cross-section fitted across its axis (tool_centred_on_seen): the seen points over its last
# SECTION_LENGTH (m) up to SECTION_AHEAD beyond the frame's end, within TOOL_WINDOW_RADIUS of the axis, at least
# MIN_SECTION_POINTS of them; residuals beyond SECTION_LOSS_SCALE (m) count less and less (soft-L1: flying pixels);
# a fitted radius outside SECTION_RADII (m) is no tool's.
SECTION_LENGTH = 0.04
SECTION_AHEAD = 0.005
MIN_SECTION_POINTS = 30
SECTION_LOSS_SCALE = 0.002
SECTION_RADII = (0.004, 0.035)


def tool_on_seen_surface(
    tool_W: ToolFrame,
    beyond: float,
    seen_model: np.ndarray,
    observed_W: np.ndarray,
    surface_W: np.ndarray,
    viewpoint_W: np.ndarray,
) -> ToolFrame:
    """The fitted tool frame (W) moved onto the seen points about its end (N x 3, W), against the fitted surface's
    points visible from the camera (K x 3, W: visible_from) that a depth sensor there returns (returned_points, of
    the whole fitted surface M x 3 and the viewpoint, 3, W); as fitted where too little is seen there. beyond: how
    far (m) the tip lies beyond the tool's surface along its axis (a drill's bit; ShapeSpace.tool_beyond)."""
    axis = tool_W.axis
    end = tool_W.tip - beyond * axis
    model_near_end = returned_points(_window(seen_model, end, axis), surface_W, viewpoint_W)
    shift = np.zeros(3)
    for _ in range(TOOL_ITERATIONS):  # the window follows the shift: a tool seen far from the fitted one is reached
        seen = _window(observed_W, end + shift, axis)
        model = model_near_end + shift
        if len(seen) < MIN_TOOL_POINTS or len(model) < MIN_TOOL_POINTS:
            return tool_W
        seen_end, model_end = (np.percentile(p @ axis, TOOL_END_PERCENTILE) for p in (seen, model))
        # Across: the centroids of the last TOOL_END_LENGTH of each (the camera may see no more of the tool than that).
        seen_tip = seen[seen @ axis > seen_end - TOOL_END_LENGTH]
        model_tip = model[model @ axis > model_end - TOOL_END_LENGTH]
        across = seen_tip.mean(axis=0) - model_tip.mean(axis=0)
        across = across - (across @ axis) * axis
        shift = shift + across + (seen_end - model_end) * axis
    if np.linalg.norm(shift) > TOOL_SHIFT_LIMIT:
        return tool_W
    return ToolFrame(tool_W.tip + shift, axis)


def tool_end_in_image(
    tool_W: ToolFrame, beyond: float, surface_W: np.ndarray, view: DepthView, end_radius: float | None = None
) -> ToolFrame:
    """The tool frame moved along its axis so that the tool's end face, as the frame puts it, ends in the image where
    the object's mask does.

    The end face is a circle about the axis at the frame's end (the tip less `beyond`), `end_radius` wide (m: the
    seen tube's, SeenTube.end_radius), or where none is given as wide as the fitted surface (M x 3, W, as the frame
    was placed) is over the tool's last TOOL_END_LENGTH; its outline reaches as far along the projected axis as its
    farthest projected point. The fitted surface's width there is a latent shape's, and a tapering tool's median
    width over its last stretch is not its end's: a millimetre of radius off puts the tip up to a millimetre off
    along (tuning range's drills, the fitted width: +3.4 mm along, median; the seen tube's: +0.8 mm). The mask's
    pixels are taken in a band about the projected axis; the difference of the two reaches (pixels) is turned into
    metres along the axis. The colour image's mask ends where the tool does (within a pixel on rendered frames); the
    depth loses the last millimetres of a tool pointing away from the camera (mixed and grazing pixels), so the seen
    points end short of it."""
    if view.mask is None or not view.mask.any():
        return tool_W
    X_CW = view.X_WC.inverse()
    focal, centre = np.asarray(view.focal, dtype=float), np.asarray(view.centre, dtype=float)

    def pixels(points_W):
        p = X_CW.multiply(np.atleast_2d(points_W).T).T
        return focal * p[:, :2] / p[:, 2:3] + centre, p[:, 2]

    axis = tool_W.axis
    end = tool_W.tip - beyond * axis
    offset = np.asarray(surface_W) - end
    along = offset @ axis
    across = np.linalg.norm(offset - along[:, None] * axis, axis=1)
    last = (along > -TOOL_END_LENGTH) & (along < 0.01) & (across < TOOL_WINDOW_RADIUS)
    (e0, e1), (depth, _) = pixels(np.array([end, end + 0.01 * axis]))
    px_per_m = np.linalg.norm(e1 - e0) / 0.01
    if last.sum() < MIN_TOOL_POINTS or depth <= 0 or px_per_m * TOOL_END_LENGTH < MIN_END_PIXELS:
        return tool_W  # too little of the tool fitted there, or its axis nearly along the ray: no end to read
    radius = float(np.median(across[last])) if end_radius is None else end_radius
    u, v = _across(axis)
    angles = np.linspace(0.0, 2 * np.pi, 72, endpoint=False)
    rim = end + radius * (np.outer(np.cos(angles), u) + np.outer(np.sin(angles), v))
    along_dir = (e1 - e0) / np.linalg.norm(e1 - e0)
    across_dir = np.array([-along_dir[1], along_dir[0]])
    rows, columns = np.nonzero(view.mask)
    mask = np.column_stack([columns, rows]) - e0
    across_px = mask @ across_dir
    along_px = mask @ along_dir
    inside = (np.abs(across_px) < TOOL_WINDOW_RADIUS * focal.mean() / depth) & (along_px > -TOOL_WINDOW_BACK * px_per_m)
    inside &= along_px < TOOL_WINDOW_AHEAD * px_per_m
    if inside.sum() < MIN_TOOL_POINTS:
        return tool_W
    seen_end = along_px[inside].max()
    shift = (seen_end - float(((pixels(rim)[0] - e0) @ along_dir).max())) / px_per_m
    # Across, in the image: the tool's outline is about as wide either side of its projected axis; the mask's last
    # TOOL_END_LENGTH says where its middle is. That offset is a move perpendicular to the axis and the ray.
    last_px = inside & (along_px > seen_end - TOOL_END_LENGTH * px_per_m)
    low, high = np.percentile(across_px[last_px], [MASK_EDGE_PERCENTILE, 100 - MASK_EDGE_PERCENTILE])
    sideways = np.cross(end - view.X_WC.translation(), axis)
    sideways /= np.linalg.norm(sideways)
    if (pixels(end + 0.01 * sideways)[0][0] - e0) @ across_dir < 0:
        sideways = -sideways
    move = shift * axis + 0.5 * (low + high) * depth / focal.mean() * sideways
    if np.linalg.norm(move) > TOOL_SHIFT_LIMIT:
        return tool_W
    return ToolFrame(tool_W.tip + move, axis)


def returned_points(model_W: np.ndarray, surface_W: np.ndarray, viewpoint_W: np.ndarray) -> np.ndarray:
    """Of the fitted surface's visible points (N x 3, W), those a depth sensor at viewpoint_W (3,) returns: the
    surface there (its normal from the NORMAL_NEIGHBOURS nearest of surface_W, M x 3) within GRAZING_LIMIT_DEG of
    facing the ray."""
    if len(model_W) == 0 or len(surface_W) < NORMAL_NEIGHBOURS:
        return model_W
    _, neighbours = cKDTree(surface_W).query(model_W, NORMAL_NEIGHBOURS)
    patches = surface_W[neighbours] - surface_W[neighbours].mean(axis=1, keepdims=True)
    normals = np.linalg.eigh(np.einsum("nki,nkj->nij", patches, patches))[1][:, :, 0]  # the least spread
    rays = model_W - np.asarray(viewpoint_W, dtype=float)
    facing = np.abs(np.einsum("ni,ni->n", normals, rays)) / np.linalg.norm(rays, axis=1)
    return model_W[facing >= np.cos(np.radians(GRAZING_LIMIT_DEG))]


def _across(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit directions across the unit `axis`, at right angles to it and to each other."""
    u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    return u, np.cross(axis, u)


def _window(points: np.ndarray, end: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The points (N x 3) in the window about the tool's end."""
    offset = points - end
    along = offset @ axis
    across = np.linalg.norm(offset - along[:, None] * axis, axis=1)
    inside = (along > -TOOL_WINDOW_BACK) & (along < TOOL_WINDOW_AHEAD) & (across < TOOL_WINDOW_RADIUS)
    return points[inside]


@dataclass(frozen=True)
class SeenTube:
    """The tool frame moved onto the tool the camera saw (tool_centred_on_seen), and that tube's radius at the frame's
    end (m; None where too little was seen or the fit was no tool's: the frame then as it was)."""

    tool_W: ToolFrame
    end_radius: float | None


def tool_centred_on_seen(tool_W: ToolFrame, beyond: float, observed_W: np.ndarray) -> SeenTube:
    """The tool frame (W) moved across its axis onto the axis of the tool the camera saw: the seen points (N x 3, W)
    over the tool's last SECTION_LENGTH are a tube about it that narrows or widens towards its end (a chuck, a
    spout and its rose), whose cross-sections' centre is fitted (robust least squares: each point's distance from
    the axis minus a radius that changes linearly along it). A depth camera sees the tube's near half, whose
    centroid lies nearer the camera than the axis: the circle says where the axis is, the centroids do not. The axis
    keeps its direction (a drill's is the category's; a can's as the fitted spout turned it, within a few degrees).
    As it was where too little is seen or the fit is no tool's. beyond: how far (m) the tip lies beyond the tool's
    surface along its axis."""
    axis = tool_W.axis
    end = tool_W.tip - beyond * axis
    offset = np.asarray(observed_W, dtype=float) - end
    along = offset @ axis
    across = offset - along[:, None] * axis
    inside = (along > -SECTION_LENGTH) & (along < SECTION_AHEAD)
    inside &= np.linalg.norm(across, axis=1) < TOOL_WINDOW_RADIUS
    if inside.sum() < MIN_SECTION_POINTS:
        return SeenTube(tool_W, None)
    u, v = _across(axis)
    section = np.column_stack([across[inside] @ u, across[inside] @ v])
    a = along[inside]

    def residuals(x):  # x: the centre (2), the radius at the end, its change per metre along
        return np.linalg.norm(section - x[:2], axis=1) - (x[2] + x[3] * a)

    radius = float(np.median(np.linalg.norm(section, axis=1)))
    fit = least_squares(residuals, [0.0, 0.0, radius, 0.0], loss="soft_l1", f_scale=SECTION_LOSS_SCALE, max_nfev=100)
    centre, end_radius = fit.x[:2], float(fit.x[2])
    if not SECTION_RADII[0] <= end_radius <= SECTION_RADII[1] or np.linalg.norm(centre) > TOOL_WINDOW_RADIUS:
        return SeenTube(tool_W, None)
    return SeenTube(ToolFrame(tool_W.tip + centre[0] * u + centre[1] * v, axis), end_radius)
