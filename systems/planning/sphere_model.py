"""A sphere model of the robot's collision geometry: spheres covering each proximity geometry of the tracked bodies,
placed in batches from BatchedKinematics.body_poses."""

from dataclasses import dataclass
from enum import IntEnum

import numpy as np
from pydrake.geometry import Box, Capsule, Cylinder, Sphere
from pydrake.multibody.plant import MultibodyPlant
from scipy.spatial import cKDTree

from systems.planning.kinematics import BatchedKinematics


class SphereGroup(IntEnum):
    """The rigid group a robot sphere moves with."""

    TORSO = 0  # pelvis, torso, head
    LEFT = 1  # the left arm and hand
    RIGHT = 2  # the right arm and hand


def on_the_robot(points_W: np.ndarray, robot_spheres_W: np.ndarray, margin: float) -> np.ndarray:
    """Which points (N x 3 in W) lie within `margin` (m) of a sphere (S x 4: centre in W, radius; m): N bools."""
    on_robot = np.zeros(len(points_W), bool)
    if not len(robot_spheres_W) or not len(points_W):
        return on_robot
    for index in cKDTree(points_W).query_ball_point(robot_spheres_W[:, :3], robot_spheres_W[:, 3] + margin):
        on_robot[index] = True
    return on_robot


def off_the_robot(points_W: np.ndarray, robot_spheres_W: np.ndarray, margin: float) -> np.ndarray:
    """The points (N x 3 in W) farther than `margin` (m) from every sphere (S x 4: centre in W, radius; m)."""
    return points_W[~on_the_robot(points_W, robot_spheres_W, margin)]


@dataclass
class SphereModel:
    """Spheres bounding the robot's collision geometry, attached to bodies."""

    body: np.ndarray  # S, position of each sphere's body in BatchedKinematics.links
    centre_B: np.ndarray  # S x 3, in the body frame
    radius: np.ndarray  # S
    group: np.ndarray  # S, the SphereGroup (arm side) each sphere moves with, as its int value
    geometry: list  # S, the GeometryId each sphere covers

    def __post_init__(self):
        # Each body's sphere centres as the columns of one matrix (bodies x 4 x most per body, homogeneous,
        # zero-padded), and where each sphere lands among them (its body, its column): every centre is then one
        # product per body.
        count = np.bincount(self.body) if len(self.body) else np.zeros(0, int)
        most = int(count.max()) if len(count) else 0
        self._centres_by_body = np.zeros((len(count), 4, most))
        self._centres_by_body[:, 3] = 1.0
        self._column = np.zeros(len(self.body), int)
        filled = np.zeros(len(count), int)
        for sphere, body in enumerate(self.body):
            self._centres_by_body[body, :3, filled[body]] = self.centre_B[sphere]
            self._column[sphere] = filled[body]
            filled[body] += 1

    def pairs(self, inspector, group_a: SphereGroup, group_b: SphereGroup) -> tuple[np.ndarray, np.ndarray]:
        """Index pairs (i in group_a, j in group_b) of spheres whose geometries may collide (not filtered).

        With group_a == group_b, the pairs within the group (e.g. a hand and its own upper arm).
        """
        a, b = np.nonzero(self.group == group_a)[0], np.nonzero(self.group == group_b)[0]
        allowed = {}
        i_list, j_list = [], []
        for i in a:
            for j in b:
                if group_a == group_b and (j <= i or self.geometry[i] == self.geometry[j]):
                    continue  # within one group: each pair once, and never a geometry with itself
                key = (self.geometry[i], self.geometry[j])
                if key not in allowed:
                    allowed[key] = not inspector.CollisionFiltered(*key)
                if allowed[key]:
                    i_list.append(i)
                    j_list.append(j)
        return np.array(i_list, int), np.array(j_list, int)

    def centres_W(self, body_poses: np.ndarray) -> np.ndarray:
        """Sphere centres in W (B x S x 3) from the batch of body poses (B x L x 4 x 4): one product per body of
        its poses' rows (3B x 4) and its centres (4 x most), about 15 times faster than B x bodies small products
        on BatchedKinematics.body_poses' transposed layout."""
        bodies = len(self._centres_by_body)
        rows = body_poses[:, :bodies, :3].swapaxes(0, 1).reshape(bodies, -1, 4)  # bodies x 3B x 4
        centres = (rows @ self._centres_by_body).reshape(bodies, len(body_poses), 3, -1)  # bodies x B x 3 x most
        return centres.transpose(1, 0, 3, 2)[:, self.body, self._column]


BOX_SPHERE_SPACING = 0.04  # m: boxes thinner than this are covered by fewer, larger spheres


def shape_spheres(shape, X_BG: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres (in B) and radii of spheres that cover a primitive shape at pose X_BG."""
    if isinstance(shape, Sphere):
        local, radii = np.zeros((1, 3)), np.array([shape.radius()])
    elif isinstance(shape, (Capsule, Cylinder)):
        r, length = shape.radius(), shape.length()
        count = int(np.ceil(length / r)) + 1
        local = np.column_stack([np.zeros(count), np.zeros(count), np.linspace(-length / 2, length / 2, count)])
        # Grown to cover the waist between neighbouring centres (and a cylinder's rim).
        radii = np.full(count, np.hypot(r, length / (2 * (count - 1))))
    elif isinstance(shape, Box):
        size = np.array([shape.width(), shape.depth(), shape.height()])
        spacing = max(size.min(), BOX_SPHERE_SPACING)
        counts = np.maximum(1, np.ceil(size / spacing).astype(int))
        cell = size / counts
        axes = [(np.arange(n) + 0.5) * c - s / 2 for n, c, s in zip(counts, cell, size, strict=True)]
        local = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        radii = np.full(len(local), 0.5 * np.linalg.norm(cell))
    else:
        raise ValueError(f"no sphere cover for {type(shape).__name__}")
    return local @ X_BG[:3, :3].T + X_BG[:3, 3], radii


def robot_spheres(plant: MultibodyPlant, scene_graph, kinematics: BatchedKinematics, group_of_body) -> SphereModel:
    """Spheres covering every proximity geometry of the kinematics' bodies.

    Args:
        group_of_body: (body name, model instance) -> its SphereGroup.
    """
    inspector = scene_graph.model_inspector()
    bodies, centres, radii, groups, geometries = [], [], [], [], []
    for position, link in enumerate(kinematics.links):
        body = plant.get_body(link.body_index)
        for geometry in plant.GetCollisionGeometriesForBody(body):
            if inspector.GetProximityProperties(geometry) is None:
                continue
            X_BG = inspector.GetPoseInFrame(geometry).GetAsMatrix4()
            centre, radius = shape_spheres(inspector.GetShape(geometry), X_BG)
            bodies += [position] * len(radius)
            centres.append(centre)
            radii.append(radius)
            groups += [group_of_body(body.name(), body.model_instance())] * len(radius)
            geometries += [geometry] * len(radius)
    return SphereModel(np.array(bodies), np.vstack(centres), np.concatenate(radii), np.array(groups), geometries)
