"""A dense surface from a sparse scan: the canonical model's points are the surface a registration
warps into the reconstruction (the planner's obstacle), and a scan of ~500 points leaves holes in it."""

import numpy as np
import open3d as o3d
import trimesh
from scipy.spatial import cKDTree

from systems.shape_space.cpd import thinned

POISSON_DEPTH = 7  # octree depth of the screened Poisson reconstruction: ~1 cm cells on a 0.5 m object
KEEP_WITHIN_SPACINGS = 2.0  # reconstructed points farther from every scan point than this are Poisson's guesses


def point_spacing(points: np.ndarray) -> float:
    """The median distance (m) from a point to its nearest neighbour."""
    return float(np.median(cKDTree(points).query(points, k=2)[0][:, 1]))


def surface_mesh(points: np.ndarray) -> trimesh.Trimesh:
    """A closed surface through a cloud (N x 3, m): screened Poisson over normals estimated from the points,
    cropped to the points' bounding box. Where the scan saw nothing, the surface is Poisson's guess."""
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=15))
    cloud.orient_normals_consistent_tangent_plane(10)
    # One thread: the same surface every run.
    mesh, _ = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(cloud, depth=POISSON_DEPTH, n_threads=1)
    mesh = mesh.crop(cloud.get_axis_aligned_bounding_box())
    return trimesh.Trimesh(np.asarray(mesh.vertices), np.asarray(mesh.triangles), process=False)


def densified(points: np.ndarray, count: int) -> np.ndarray:
    """`count` points (about; K x 3) on a surface reconstructed from a sparse cloud (N x 3, metres).

    The surface is surface_mesh's, and only what lies near the scan is kept: where the scan saw nothing,
    nothing is invented.
    """
    spacing = point_spacing(points)
    dense, _ = trimesh.sample.sample_surface(surface_mesh(points), 4 * count, seed=0)
    near = cKDTree(points).query(dense)[0] <= KEEP_WITHIN_SPACINGS * spacing
    return thinned(np.vstack([points, dense[near]]), count)
