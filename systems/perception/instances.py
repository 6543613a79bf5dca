"""Object instances in a labelled image, and the one to pick among them.

The network labels pixels by class; on a cluttered table one class's pixels can belong to several objects, and two
objects can touch in the image. Instances are found in 3D: the object pixels' points (from the depth image) fall
into INSTANCE_CUBE_M cubes, and cubes that touch (26 neighbours) are one cluster: two objects that stand apart by more
than a cube come apart, whatever the image shows, and an object's parts (a handle in front of its body, a spout rising
towards the camera) stay together where they join. A cluster with less than PIECE_SHARE of the largest in its image
region is a part: it joins the nearest large cluster where it lies within ATTACHED_M of it (a part cut off by a line
of lost pixels), and is left out otherwise (a fragment of another object the network labelled too). Pixels without
depth go with the nearest pixel of their region that has it. Classes never cut an instance: the network may label
one object in parts. Each instance has the class that labelled most of it.

Where the table is known (TableView), a large cluster that floats (its lowest points more than INSTANCE_FLOAT_M above
the table top) cannot stand on its own: every object rests on the table. Nearer the camera than a cluster of its image
region that does stand, within INSTANCE_JOIN_M of it, it is that object's upper part, cut off by self-occlusion (a
drill's barrel and grip in front of and above its battery pack, seen from above: the grip's thin side leaves a depth
step), and joins it. A floating cluster farther from the camera than the standing ones is left alone: it may be another
object whose base the nearer one hides.
"""

from dataclasses import dataclass

import cv2
import numpy as np
from pydrake.math import RigidTransform
from pydrake.systems.sensors import CameraInfo
from scipy import ndimage
from scipy.spatial import cKDTree

from systems.messages import LeftOut, Segmentation
from systems.perception.pose_estimator import depth_to_points
from systems.planning.outlines import distance_to

INSTANCE_CUBE_M = 0.008  # m: points in touching cubes of this side are one object
# A cluster is an object of its own only with at least this share of the largest one in its image region (and
# min_pixels): smaller ones are parts, or fragments.
PIECE_SHARE = 0.25
ATTACHED_M = 0.015  # m: a part this near a large cluster joins it
CONNECTIVITY = 3  # cubes that share a face (1), an edge (2) or a corner (3) touch
# Among the instances of a named category, only those with at least this share of the largest one are candidates:
# a small mislabelled patch nearer the camera is not an object to pick.
CANDIDATE_SHARE = 0.4
# (Both chosen on the tuning drills' first pick frames and the tuning range's cluttered tables:
# docs/history/perception_parameters.md.)
INSTANCE_FLOAT_M = 0.05  # m: a cluster whose lowest points are higher above the table top floats
INSTANCE_JOIN_M = 0.08  # m: a floating cluster joins a standing one at most this far from it
LOWEST_PERCENTILE = 2  # a cluster's lowest points: this percentile of its heights (a few stray pixels are noise)


@dataclass
class TableView:
    """The table top as the depth camera sees it."""

    X_WC: RigidTransform  # the depth camera's pose in W
    top_z: float  # the table top's height in W, m

    def heights(self, points_C: np.ndarray) -> np.ndarray:
        """N x 3 points in the camera frame C -> their heights above the table top, m."""
        return points_C @ self.X_WC.rotation().matrix()[2] + self.X_WC.translation()[2] - self.top_z


@dataclass
class Instance:
    """One object in the image."""

    mask: np.ndarray  # H x W bool
    votes: np.ndarray  # pixels per object class (classes[1:])
    depth_m: float  # median depth of its pixels (NaN without a valid one), m

    @property
    def pixel_count(self) -> int:
        return int(self.votes.sum())

    def category(self, classes) -> str:
        return classes[1 + int(np.argmax(self.votes))]


def object_instances(
    labels: np.ndarray,
    depth: np.ndarray | None,
    classes,
    min_pixels: int,
    intrinsics: CameraInfo | None = None,
    table: TableView | None = None,
) -> list[Instance]:
    """The objects in a labelled image (H x W class ids, 0 background), cut apart in 3D where the depth image (H x W,
    m) and the camera's intrinsics are given (else each connected region of object pixels is one), a floating
    cluster joined to the standing one below it where the table is given; instances smaller than min_pixels are
    dropped. Largest first."""
    pixels = cv2.morphologyEx((labels > 0).astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    count, regions = cv2.connectedComponents(pixels, connectivity=8)
    if depth is not None and intrinsics is not None:
        owner = _clusters(regions, depth, intrinsics, min_pixels, table)
    else:
        owner = regions
    instances = []
    for index in np.unique(owner[owner > 0]):
        mask = owner == index
        votes = np.array([np.count_nonzero(mask & (labels == c)) for c in range(1, len(classes))])
        if votes.sum() < min_pixels:
            continue
        valid = mask & np.isfinite(depth) & (depth > 0) if depth is not None else None
        depth_m = float(np.median(depth[valid])) if valid is not None and valid.any() else float("nan")
        instances.append(Instance(mask, votes, depth_m))
    return sorted(instances, key=lambda instance: -instance.pixel_count)


def _clusters(
    regions: np.ndarray, depth: np.ndarray, intrinsics: CameraInfo, min_pixels: int, table: TableView | None
) -> np.ndarray:
    """H x W cluster ids (0: none) of the object pixels (regions > 0), as the module docstring says."""
    valid = (regions > 0) & np.isfinite(depth) & (depth > 0)
    v, u = np.nonzero(valid)
    points = depth_to_points(depth, valid, intrinsics)  # (in the same pixel order)
    if not len(points):
        return np.zeros(regions.shape, np.int32)
    cluster = touching_cubes(points, INSTANCE_CUBE_M, CONNECTIVITY)  # per valid pixel
    sizes = np.bincount(cluster)
    members = grouped(cluster).__getitem__  # members(c): the pixels of cluster c

    # Large clusters: PIECE_SHARE of the largest one in their image region.
    region = regions[v, u]
    home = {c: int(np.bincount(region[members(c)]).argmax()) for c in np.flatnonzero(sizes)}  # its image region
    largest_in_region = np.zeros(regions.max() + 1, int)
    for c, r in home.items():
        largest_in_region[r] = max(largest_in_region[r], sizes[c])
    large = [c for c in home if sizes[c] >= max(min_pixels // 2, PIECE_SHARE * largest_in_region[home[c]])]
    final = np.zeros(len(sizes), np.int64)  # cluster -> the large cluster it joins (0: left out)
    final[large] = large
    if table is not None:
        _join_floating(large, home, members, points, table, final)
    parts = [c for c in home if final[c] == 0]
    if large and parts:
        # Every part's points against every fourth point of the large clusters.
        sample = np.concatenate([members(c)[::4] for c in large])
        gap, nearest = cKDTree(points[sample]).query(points[np.concatenate([members(c) for c in parts])])
        nearest = cluster[sample[nearest]]
        ends = np.cumsum([sizes[c] for c in parts])
        for c, end in zip(parts, ends, strict=True):
            closest = end - sizes[c] + np.argmin(gap[end - sizes[c] : end])
            if gap[closest] < ATTACHED_M:
                final[c] = final[nearest[closest]]
    owner = np.zeros(regions.shape, np.int64)
    owner[v, u] = final[cluster]
    # Pixels without depth (and left-out ones' holes) take the nearest pixel's owner in their region.
    # (Within the box of the object pixels: every valid pixel is one.)
    box = ndimage.find_objects((regions > 0).astype(np.int8))[0]
    owner_in, regions_in = owner[box], regions[box]  # (views: writing owner_in writes owner)
    holes = (regions_in > 0) & ~valid[box]
    _, (rows, cols) = ndimage.distance_transform_edt(~valid[box], return_indices=True)
    rows, cols = rows[holes], cols[holes]
    owner_in[holes] = np.where(regions_in[rows, cols] == regions_in[holes], owner_in[rows, cols], 0)
    return owner


def touching_cubes(points: np.ndarray, size: float, connectivity: int = 3) -> np.ndarray:
    """Each point's cluster id (N, from 1): the points (N x 3, m) fall into cubes of side `size` (m), and cubes that
    touch (share a face: connectivity 1, an edge: 2, a corner: 3) are one cluster."""
    cells = np.floor(points / size).astype(np.int64)
    cells -= cells.min(axis=0)
    grid = np.zeros(cells.max(axis=0) + 1, bool)
    grid[tuple(cells.T)] = True
    cluster_of_cell, _ = ndimage.label(grid, structure=ndimage.generate_binary_structure(3, connectivity))
    return cluster_of_cell[tuple(cells.T)]


def grouped(ids: np.ndarray) -> list[np.ndarray]:
    """The indices of each id's members, in order (ids: N non-negative ints; entry k: the indices where ids == k)."""
    return np.split(np.argsort(ids, kind="stable"), np.cumsum(np.bincount(ids))[:-1])


def _join_floating(large, home, members, points, table: TableView, final) -> None:
    """Joins each floating large cluster to the nearest standing one of its image region that lies farther from the
    camera, within INSTANCE_JOIN_M (final: cluster -> the cluster it belongs to, updated), as the module docstring
    says."""
    lowest = {c: np.percentile(table.heights(points[members(c)]), LOWEST_PERCENTILE) for c in large}
    depth = {c: np.median(points[members(c), 2]) for c in large}
    standing = [c for c in large if lowest[c] <= INSTANCE_FLOAT_M]
    for c in large:
        below = [s for s in standing if home[s] == home[c] and depth[s] > depth[c]]
        if lowest[c] <= INSTANCE_FLOAT_M or not below:
            continue
        tree = cKDTree(points[members(c)])
        gaps = [tree.query(points[members(s)[::4]])[0].min() for s in below]
        if min(gaps) < INSTANCE_JOIN_M:
            final[c] = below[int(np.argmin(gaps))]


def named_object(instances: list[Instance], classes, category: str, shape) -> Segmentation:
    """The instance to pick when the user named its category: the nearest to the camera (median depth) of those the
    network labelled mostly `category` (and at least CANDIDATE_SHARE of the largest of them). With none, the
    largest instance, taken as `category` as named (one object on the table that the network misclassifies);
    its network_category says what the network made of it."""
    mine = [i for i in instances if i.category(classes) == category]
    if mine:
        largest = max(i.pixel_count for i in mine)
        candidates = [i for i in mine if i.pixel_count >= CANDIDATE_SHARE * largest]
        chosen = min(candidates, key=lambda i: (np.nan_to_num(i.depth_m, nan=np.inf), -i.pixel_count))
        message = f"{category}: {chosen.pixel_count} px"
        if len(candidates) > 1:
            others = ", ".join(f"{i.depth_m:.2f}" for i in candidates if i is not chosen)
            message += f", the nearest of {len(candidates)} (at {chosen.depth_m:.2f} m; the others at {others} m)"
    elif instances:
        chosen = instances[0]
        share = chosen.votes.max() / max(chosen.pixel_count, 1)
        message = (
            f"{category}: {chosen.pixel_count} px as named (the network labelled {share:.0%} of it "
            f"{chosen.category(classes)})"
        )
    else:
        return Segmentation(False, mask=np.zeros(shape, bool), message=f"no {category} in view")
    network = chosen.category(classes)
    return Segmentation(True, category, chosen.mask, chosen.pixel_count, message, network_category=network)


# m: an object whose points' centre (x, y) lies this near the outline of one the clear task gave up (the convex outline
# of its points, completed) is that object (the centre of a drill's points may lie between its handles)
GIVEN_UP_MARGIN_M = 0.03
# m: an object whose points' centre lies this near the footprint of one the clear set down in the zone is that one: it
# stands within the place's 2 cm of its spot, and a camera that sees its near side only puts the centre on the robot's
# side of it, outside the zone where the spot is at its edge (report table 0, 2026-12-05: a can set down 4 cm inside
# the zone's edge, seen with its centre on the edge, was taken on again and carried out of the zone)
PLACED_MARGIN_M = 0.03
# m: an object whose lowest seen points are higher above the table top does not stand on it (the arms backed off above
# it do not; an object whose base another hides may show its lowest points several centimetres up), unless the camera
# does not see its foot (foot_hidden: report table 8, 2026-12-07, a can near the robot whose lowest 12.6 cm the image's
# lower border cut was never taken on)
CLEAR_FLOAT_M = 0.10
# Below a mask's lowest pixel in a column (the camera looks down at the table: below in the image is lower or nearer in
# the scene), within FOOT_ROWS pixels: a surface FOOT_NEARER_M nearer the camera than the object hides its foot there.
FOOT_ROWS = 6
FOOT_NEARER_M = 0.03
FOOT_HIDDEN_SHARE = 0.5  # of the mask's columns whose foot is seen hidden so: the object's foot is hidden


def foot_hidden(mask: np.ndarray, depth: np.ndarray) -> bool:
    """Whether the camera does not see the foot of the object in `mask` (H x W bool; depth H x W, m): in at least
    FOOT_HIDDEN_SHARE of the mask's columns, the image's lower border cuts it, or a pixel within FOOT_ROWS below its
    lowest one lies FOOT_NEARER_M nearer the camera (the arms above the table have the table, farther, below them)."""
    columns = np.flatnonzero(mask.any(axis=0))
    if not len(columns):
        return False
    height = mask.shape[0]
    lowest = height - 1 - np.argmax(mask[::-1, columns], axis=0)
    rows = np.clip(lowest[:, None] + np.arange(1, FOOT_ROWS + 1), 0, height - 1)
    below = depth[rows, columns[:, None]]
    below = np.where(np.isfinite(below) & (below > 0), below, np.inf).min(axis=1)  # (no depth: nothing seen there)
    hidden = (below < depth[lowest, columns] - FOOT_NEARER_M) | (lowest == height - 1)  # (NaN depth: not hidden)
    return bool(np.mean(hidden) >= FOOT_HIDDEN_SHARE)


def next_object(
    instances: list[Instance],
    classes,
    points_W: list[np.ndarray],
    left_out: LeftOut,
    first_near_W,
    shape,
    table_top_z: float,
    feet_hidden: list[bool] | None = None,
) -> Segmentation:
    """The clear task's next object: of the objects the network labelled one of its categories (each at least
    CANDIDATE_SHARE of the largest of its category left), not standing in the drop zone (its points' centre in it,
    or within PLACED_MARGIN_M of the footprint of an object set down there) nor where
    an object was given up (left_out: its points' centre within GIVEN_UP_MARGIN_M of one's outline), the one nearest
    first_near_W (its points' centre, x and y, m: the drop zone's centre; the objects nearest it stand in the way of
    the others' carries).
    Only objects standing on the table (their lowest points at most CLEAR_FLOAT_M above table_top_z, m, or their
    foot hidden: feet_hidden, by instance, foot_hidden's) are candidates: the robot's arms, backed off above the
    table, are no object to clear whatever the network makes of them. points_W: each instance's points in W (N x 3,
    m; none where it has no depth)."""
    in_zone, given_up, eligible = 0, 0, []
    feet_hidden = feet_hidden or [False] * len(instances)
    for instance, points, hidden in zip(instances, points_W, feet_hidden, strict=True):
        if not len(points) or (
            np.percentile(points[:, 2], LOWEST_PERCENTILE) - table_top_z > CLEAR_FLOAT_M and not hidden
        ):
            continue  # (not standing on the table)
        centre = points.mean(axis=0)
        placed = any(distance_to(footprint, centre[:2]) <= PLACED_MARGIN_M for footprint in left_out.placed_W)
        if placed or (left_out.zone is not None and left_out.zone.contains(centre[:2])):
            in_zone += 1
        elif any(distance_to(outline, centre[:2]) <= GIVEN_UP_MARGIN_M for outline in left_out.given_up_W):
            given_up += 1
        else:
            eligible.append((float(np.linalg.norm(centre[:2] - np.asarray(first_near_W))), instance))
    # (The share against the largest of its category among those left: one given up may be the largest in view.)
    largest = {}
    for _, instance in eligible:
        category = instance.category(classes)
        largest[category] = max(largest.get(category, 0), instance.pixel_count)
    candidates = [(d, i) for d, i in eligible if i.pixel_count >= CANDIDATE_SHARE * largest[i.category(classes)]]
    aside = f"{in_zone} in the drop zone, {given_up} given up"
    if not candidates:
        message = f"nothing to clear: no familiar object left ({aside})"
        return Segmentation(False, mask=np.zeros(shape, bool), message=message)
    distance, chosen = min(candidates, key=lambda c: (c[0], -c[1].pixel_count))
    category = chosen.category(classes)
    message = (
        f"{category}: {chosen.pixel_count} px, {distance:.2f} m from the drop zone, the nearest of {len(candidates)}"
    )
    message += f" left ({aside})"
    return Segmentation(True, category, chosen.mask, chosen.pixel_count, message, network_category=category)
