"""An object's parts the network left unlabelled, found in 3D.

The network labels the parts of a familiar object that look like its training shapes. A part that looks like
none of them (the battery block under a grip that stands under the middle of its housing, and that housing) it
may call background, and the instance found from the labelled pixels is then an object in pieces: the pose
estimator and the registrar see half a drill, and the fit is named poor. But an object is one body standing on the
table, and the objects on it stand apart. So the instance is completed in 3D: the points at least ABOVE_TABLE_M
above the table top near it (not flying pixels) fall into BODY_CUBE_M cubes, and cubes that touch are one body.
  * A body holding SEED_SHARE of the instance's points, and made mostly (MOSTLY_OWN) of them, is the object's.
  * A body that floats (its lowest points BODY_FLOAT_M above the table top: it cannot stand by itself) nearer the
    camera than the object's body nearest to it, within BODY_JOIN_M of it, is the object's too: its upper part, cut
    off by a depth step where it hides its own junction (a drill's housing over its grip, seen from above).
  * The object's bodies' points the network labelled (as any class) join the instance, and so do their
    unlabelled points within GROW_M of a labelled one: where that adds at least MIN_ADDED_SHARE of it (less is the
    silhouette's edge, and an object the network labelled whole keeps the mask it had).

What it may not do, and why (the middle three each seen on the tuning range's cluttered tables, with looser rules):
  * join another object the instances found (its pixels are never looked at: a neighbour drill's housing, floating
    nearer the camera within BODY_JOIN_M, joined a drill on report table 15 of the clear task, and the two were taken
    for one object);
  * join another object: surfaces more than 1.8 cm apart (the diagonal of two cubes) never touch as cubes, and
    nearer ones only where they face each other along a diagonal (the cluttered tables keep 1.5 cm between
    outlines); a flying pixel between them is left out;
  * join a floating body farther from the camera, though the network labelled it: another object's housing,
    behind the instance and partly hidden by it, looks just so (a drill's side handle does too, and is left out);
  * complete a body the network labelled only in part (a cylinder it took partly for a can): MOSTLY_OWN;
  * join a body that floats only a little: the lower part of a box in front of the object may be hidden;
  * take the table: its points lie below ABOVE_TABLE_M (the object's lowest 1.5 cm stay as the network saw them).
"""

import numpy as np
from scipy.spatial import cKDTree

from systems.perception.depth_cleaning import flying_pixels
from systems.perception.instances import LOWEST_PERCENTILE, TableView, grouped, touching_cubes
from systems.perception.pose_estimator import depth_to_points

BODY_CUBE_M = 0.005  # m: points in touching cubes of this side are one body
ABOVE_TABLE_M = 0.015  # m: points at least this high above the table top may be the object's
SEED_SHARE = 0.1  # a body holding this share of the instance's points is the object's,
MOSTLY_OWN = 0.6  # where they are at least this share of the body's points
GROW_M = 0.1  # m: an unlabelled point joins at most this far from a labelled one of the object's bodies
# A completion that adds less than this share of the instance's pixels adds its edge, not a missing part, and is
# not made (docs/history/perception_parameters.md).
MIN_ADDED_SHARE = 0.05
NEAR_M = 0.12  # m: only points this near the instance's (its box, grown) are looked at (beyond GROW_M)
MIN_BODY_POINTS = 20  # smaller bodies are noise
BODY_FLOAT_M = 0.1  # m: a body whose lowest points are higher above the table top floats
BODY_JOIN_M = 0.08  # m: a floating body joins the object's body nearest to it at most this far from it
JOIN_STRIDE = 4  # (the object's bodies' every JOIN_STRIDE-th point is measured against a floating one)


def completed_mask(
    mask: np.ndarray,
    labels: np.ndarray,
    depth: np.ndarray,
    intrinsics,
    table: TableView,
    others: np.ndarray | None = None,
) -> np.ndarray:
    """The instance's mask (H x W bool) with the pixels of its bodies in 3D, as the module docstring says.

    Args:
        mask: the instance's pixels.
        labels: the network's class ids (H x W, 0 background).
        depth: the depth image (H x W, m; NaN or 0 where none).
        intrinsics: the depth camera's (CameraInfo).
        table: the table top as the depth camera sees it.
        others: the pixels of the other objects found in the image (H x W bool; instances.object_instances), never
            added: each is an object of its own, its floating parts joined to it already.
    """
    rows, columns = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not len(rows):
        return mask
    # Only the pixels that can see within NEAR_M of the instance: its box in the image, grown by NEAR_M at its depth.
    nearest_m = np.nanmin(np.where(mask & (depth > 0), depth, np.nan), initial=np.inf)
    pad = int(np.ceil(intrinsics.focal_x() * NEAR_M / nearest_m)) if np.isfinite(nearest_m) else 0
    box = np.zeros(mask.shape, bool)
    box[max(rows[0] - pad, 0) : rows[-1] + pad + 1, max(columns[0] - pad, 0) : columns[-1] + pad + 1] = True
    crop = np.ix_(box.any(axis=1), box.any(axis=0))
    valid = box & np.isfinite(depth) & (depth > 0)
    if others is not None:
        valid &= ~others
    valid[crop] &= ~flying_pixels(depth[crop])
    points = depth_to_points(depth, valid, intrinsics)  # (in the order of np.nonzero(valid))
    v, u = np.nonzero(valid)
    own = mask[v, u]
    if not own.any():
        return mask
    low, high = points[own].min(axis=0) - NEAR_M, points[own].max(axis=0) + NEAR_M
    heights = table.heights(points)
    keep = np.all((points >= low) & (points <= high), axis=1) & (heights >= ABOVE_TABLE_M)
    points, v, u, own = points[keep], v[keep], u[keep], own[keep]
    if not own.any() or np.count_nonzero(~own) < MIN_ADDED_SHARE * np.count_nonzero(mask):
        return mask  # (too few other points about it to add MIN_ADDED_SHARE: an object seen whole, on its own)
    # (The cubes from the points' lowest corner, as measured.)
    body = touching_cubes(points - points.min(axis=0), BODY_CUBE_M)
    in_bodies = np.isin(body, _object_bodies(body, own, points, heights[keep]))
    labelled = in_bodies & ((labels[v, u] > 0) | own)
    unlabelled = in_bodies & ~labelled
    if unlabelled.any():
        gap, _ = cKDTree(points[labelled]).query(points[unlabelled], distance_upper_bound=GROW_M)
        unlabelled[unlabelled] = np.isfinite(gap)
    completed = mask.copy()
    joined = labelled | unlabelled
    completed[v[joined], u[joined]] = True
    if np.count_nonzero(completed & ~mask) < MIN_ADDED_SHARE * np.count_nonzero(mask):
        return mask  # (the silhouette's edge, not a missing part)
    return completed


def _object_bodies(body: np.ndarray, own: np.ndarray, points: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """The ids of the object's bodies, as the module docstring says.

    Args:
        body: each point's body id (from 1).
        own: which points are the instance's.
        points: N x 3 in the camera frame, m.
        heights: the points' heights above the table top, m.
    """
    sizes = np.bincount(body)
    members = {b: indices for b, indices in enumerate(grouped(body)) if b and sizes[b] >= MIN_BODY_POINTS}
    counts = np.bincount(body[own], minlength=len(sizes))
    group = {b for b in members if counts[b] >= SEED_SHARE * own.sum() and counts[b] >= MOSTLY_OWN * len(members[b])}
    floating = {b for b in members if np.percentile(heights[members[b]], LOWEST_PERCENTILE) >= BODY_FLOAT_M}
    depth = {b: np.median(points[members[b], 2]) for b in members}
    trees, gaps = {}, {}  # (a floating body, one of the object's) -> their gap, m: each measured once

    def gap(b, g):
        if (b, g) not in gaps:
            tree = trees.setdefault(b, cKDTree(points[members[b]]))
            gaps[b, g] = tree.query(points[members[g][::JOIN_STRIDE]])[0].min()
        return gaps[b, g]

    changed = bool(group)
    while changed:
        changed = False
        for b in sorted(floating - group):
            nearest = min(group, key=lambda g: gap(b, g))
            if gap(b, nearest) < BODY_JOIN_M and depth[b] < depth[nearest]:
                group.add(b)
                changed = True
    return np.array(sorted(group), int)
