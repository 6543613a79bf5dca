"""Batched forward kinematics of Centauro's arms and hands, and a sphere model of their collision geometry.

STOMP evaluates thousands of configurations per iteration; one Drake call per
configuration is far too slow, so the kinematic tree is read once from the
MultibodyPlant and evaluated here in numpy for a whole batch (B x n) at once.
n is the number of planned joints: 14 for the arms, 15 with the torso yaw (last).

Every body of interest is reached from the world through the planned revolute joints;
all other joints (welds, the hands' fingers) keep the pose they have in the plant
context given at construction. Poses are 4 x 4 homogeneous matrices X_WB.
"""

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box, Capsule, Cylinder, Sphere
from pydrake.multibody.plant import MultibodyPlant
from scipy.spatial import cKDTree


@dataclass
class _Link:
    body_index: int
    parent: int  # position of the parent in the link list, -1 for the fixed root
    arm_dof: int  # which planned coordinate drives it, -1 if fixed relative to its parent
    X_PF: np.ndarray  # parent body -> joint frame on parent (4 x 4)
    axis: np.ndarray  # revolute axis in F
    X_MB: np.ndarray  # joint frame on child -> child body (4 x 4)

    def __post_init__(self):
        # Rodrigues: the joint's rotation about its unit axis a is I + sin(q) [a]x + (1 - cos(q)) [a]x^2, so
        # X_PB(q) = X_PF (that) X_MB = fixed + sin(q) sine + (1 - cos(q)) versine, three constant 4 x 4 matrices.
        K, K2 = np.zeros((4, 4)), np.zeros((4, 4))
        K[:3, :3] = skew(self.axis)
        K2[:3, :3] = K[:3, :3] @ K[:3, :3]
        self.fixed = self.X_PF @ self.X_MB
        self.sine = self.X_PF @ K @ self.X_MB
        self.versine = self.X_PF @ K2 @ self.X_MB


class BatchedKinematics:
    """World poses of chosen bodies for a batch of configurations of the planned joints."""

    def __init__(self, plant: MultibodyPlant, plant_context, arm_joints, bodies):
        """Args:
        plant, plant_context: the robot; joints other than `arm_joints` stay as in this context.
        arm_joints: the n planned revolute joints, in the order of the configuration vector.
        bodies: the bodies whose poses are wanted (each must hang from the world through them).
        """
        self.dof = len(arm_joints)
        self.arm_joint_of_body = {joint.child_body().index(): i for i, joint in enumerate(arm_joints)}
        self.inboard_joint = {}
        for joint_index in plant.GetJointIndices():
            joint = plant.get_joint(joint_index)
            self.inboard_joint[joint.child_body().index()] = joint
        self.links: list[_Link] = []
        self.position_of_body: dict[int, int] = {}
        self._plant, self._context = plant, plant_context
        for body in bodies:
            self._add(body)
        self.damping = np.array([joint.default_damping() for joint in arm_joints])  # N m s / rad
        self.masses = np.array([plant.get_body(link.body_index).default_mass() for link in self.links])
        self.coms_B = np.array([plant.get_body(link.body_index).default_com() for link in self.links])
        # Each body's rotational inertia about its centre of mass, in its frame (kg m^2).
        self.inertias_B = np.array(
            [
                plant.get_body(link.body_index)
                .default_spatial_inertia()
                .Shift(plant.get_body(link.body_index).default_com())
                .CalcRotationalInertia()
                .CopyToFullMatrix3()
                for link in self.links
            ]
        )
        self.gravity = np.asarray(plant.gravity_field().gravity_vector())
        # For each arm coordinate: its link, and every tracked link it carries (its subtree).
        self.dof_link = np.full(len(arm_joints), -1)
        for i, link in enumerate(self.links):
            if link.arm_dof >= 0:
                self.dof_link[link.arm_dof] = i
        self.carried = np.zeros((len(arm_joints), len(self.links)), bool)
        for i in range(len(self.links)):
            j = i
            while j >= 0:
                if self.links[j].arm_dof >= 0:
                    self.carried[self.links[j].arm_dof, i] = True
                j = self.links[j].parent
        # The D driven links' Rodrigues matrices (D x 3 x 16): a driven link's X_PB, flattened, is
        # [1, sin q, 1 - cos q] times its three rows, so that a batch's joint transforms are one product.
        driven = [i for i, link in enumerate(self.links) if link.arm_dof >= 0]
        self._driven = np.array(driven, int)
        self._driven_dof = np.array([self.links[i].arm_dof for i in driven], int)
        self._rodrigues = np.array(
            [[self.links[i].fixed, self.links[i].sine, self.links[i].versine] for i in driven]
        ).reshape(len(driven), 3, 16)
        # The tree by depth: the links of one depth are placed on their parents' poses in one operation.
        parent = np.array([link.parent for link in self.links], int)
        arm_dof = np.array([link.arm_dof for link in self.links], int)
        depth = []
        for link in self.links:  # (a parent is listed before its children)
            depth.append(0 if link.parent < 0 else depth[link.parent] + 1)
        by_depth = [np.nonzero(np.array(depth) == d)[0] for d in range(max(depth) + 1)]
        # Links no planned joint moves (e.g. the pelvis and, without the torso yaw, the torso) keep one pose: the
        # product of their fixed transforms (each such link's parent is one too, listed before it).
        moved = self.carried.any(axis=0)
        self._still = np.nonzero(~moved)[0]
        still_pose = {}
        for i in self._still:
            X_PF, up = self.links[i].X_PF, self.links[i].parent
            still_pose[i] = X_PF if up < 0 else still_pose[up] @ X_PF
        self._still_poses = np.array([still_pose[i] for i in self._still]).reshape(-1, 4, 4)
        self._groups = self._placing_groups([links[moved[links]] for links in by_depth], parent)
        # For the inverse dynamics: each link's parent (-1 for a root), each driven link's coordinate (-1 for a
        # fixed one), each coordinate's parent link, and which links lie on the path from a root to each link
        # (L x L: path[l, k] when k is l or one of its ancestors, roots excluded).
        self._parent = parent
        self._arm_dof = arm_dof
        self._path = np.zeros((len(self.links), len(self.links)))
        for i in range(len(self.links)):
            j = i
            while parent[j] >= 0:
                self._path[i, j] = 1.0
                j = parent[j]
        # Each arm joint's origin and axis in its child's frame B: a revolute joint's frames F and M share their
        # origin and its axis, so both are fixed in B (X_BM = X_MB^-1).
        X_BM = np.linalg.inv(np.array([self.links[i].X_MB for i in self.dof_link]))  # n x 4 x 4
        self.joint_origin_B = X_BM[:, :3, 3]  # n x 3, m
        self.joint_axis_B = np.einsum("jik,jk->ji", X_BM[:, :3, :3], [self.links[i].axis for i in self.dof_link])

    def _add(self, body) -> int:
        index = body.index()
        if index in self.position_of_body:
            return self.position_of_body[index]
        plant, context = self._plant, self._context
        dof = self.arm_joint_of_body.get(index, -1)
        if dof < 0:
            # Fixed relative to the nearest arm-driven ancestor (or the world): one constant transform.
            parent = self._driving_ancestor(body)
            X_WP = plant.EvalBodyPoseInWorld(context, parent) if parent is not None else None
            X_WB = plant.EvalBodyPoseInWorld(context, body)
            X_PB = (X_WP.inverse() @ X_WB if X_WP is not None else X_WB).GetAsMatrix4()
            parent_position = self._add(parent) if parent is not None else -1
            link = _Link(index, parent_position, -1, X_PB, np.zeros(3), np.eye(4))
        else:
            joint = self.inboard_joint[index]
            parent_position = self._add(joint.parent_body())
            X_PF = joint.frame_on_parent().GetFixedPoseInBodyFrame().GetAsMatrix4()
            X_BM = joint.frame_on_child().GetFixedPoseInBodyFrame()
            link = _Link(
                index, parent_position, dof, X_PF, np.asarray(joint.revolute_axis()), X_BM.inverse().GetAsMatrix4()
            )
        self.links.append(link)
        self.position_of_body[index] = len(self.links) - 1
        return len(self.links) - 1

    def _driving_ancestor(self, body):
        """The closest ancestor that an arm joint moves, or None when only fixed joints lead to the world."""
        current = body
        while current.index() in self.inboard_joint:
            current = self.inboard_joint[current.index()].parent_body()
            if current.index() in self.arm_joint_of_body:
                return current
        return None

    def driving_dof(self, position: int) -> int:
        """The planned coordinate that moves the tracked link at `position` last (its own joint or its nearest
        driven ancestor's): links with the same one move as one rigid body. -1 for links fixed to the world."""
        while position >= 0 and self.links[position].arm_dof < 0:
            position = self.links[position].parent
        return self.links[position].arm_dof if position >= 0 else -1

    def body_poses(self, q: np.ndarray) -> np.ndarray:
        """X_WB of every tracked body: an array (B x L x 4 x 4), in the order of `links` (a view of an array
        stored link by link, L x B x 4 x 4: each depth's links are placed on their parents' poses in one product)."""
        q = np.atleast_2d(q)[:, self._driven_dof].T  # D x B
        batch = q.shape[1]
        factors = np.empty(q.shape + (3,))  # D x B x 3
        factors[..., 0] = 1.0
        np.sin(q, out=factors[..., 1])
        np.subtract(1.0, np.cos(q), out=factors[..., 2])
        joints = (factors @ self._rodrigues).reshape(len(q), batch, 4, 4)  # each driven link's X_PB
        poses = np.empty((len(self.links), batch, 4, 4))
        if len(self._still):
            poses[self._still] = self._still_poses[:, None]
        for links, parents, driven, X_PB in self._groups:
            X = joints[driven] if X_PB is None else X_PB
            if parents is None:
                poses[links] = X
            elif isinstance(links, slice):
                np.matmul(poses[parents], X, out=poses[links])
            else:
                poses[links] = poses[parents] @ X
        return poses.transpose(1, 0, 2, 3)

    def _placing_groups(self, by_depth, parent) -> list:
        """The links of each depth (parents first) as up to two groups, each placed in one operation: the driven
        ones (with their positions among the driven links; X_PB None) and the fixed ones (with their constant X_PB,
        which is X_PF)."""
        driven_position = np.full(len(self.links), -1)
        driven_position[self._driven] = np.arange(len(self._driven))
        groups = []
        for links in by_depth:
            driven, fixed = links[driven_position[links] >= 0], links[driven_position[links] < 0]
            if len(driven):
                groups.append((driven, parent[driven], driven_position[driven], None))
            if len(fixed):
                groups.append((fixed, parent[fixed], None, np.array([self.links[i].X_PF for i in fixed])[:, None]))
        # Evenly spaced indices as slices (e.g. the two arms' links of one depth): views, not copies; a root's
        # parents None.
        return [
            (_as_slice(links), None if parents[0] < 0 else _as_slice(parents), _as_slice(driven), X)
            for links, parents, driven, X in groups
        ]


def _as_slice(indices: np.ndarray | None):
    """The indices (at least two, evenly spaced and increasing) as a slice, else as they are."""
    if indices is None or len(indices) < 2:
        return indices
    step = indices[1] - indices[0]
    if step > 0 and np.all(np.diff(indices) == step):
        return slice(int(indices[0]), int(indices[-1]) + 1, int(step))
    return indices


def skew(v: np.ndarray) -> np.ndarray:
    """[v]x for vectors (... x 3): matrices (... x 3 x 3) with [v]x w = v x w."""
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return out


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis (np.cross is slow on many small arrays)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), np.result_type(a, b))
    np.subtract(a1 * b2, a2 * b1, out=out[..., 0])
    np.subtract(a2 * b0, a0 * b2, out=out[..., 1])
    np.subtract(a0 * b1, a1 * b0, out=out[..., 2])
    return out


def joint_axes(kinematics: "BatchedKinematics", poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each arm joint's position p_j on its axis and unit axis a_j in W (each B x n x 3), from the bodies' poses."""
    X_WB = poses[:, kinematics.dof_link, :3]  # each joint's child, B x n x 3 x 4
    positions = np.einsum("bjik,jk->bji", X_WB[..., :3], kinematics.joint_origin_B) + X_WB[..., 3]
    return positions, np.einsum("bjik,jk->bji", X_WB[..., :3], kinematics.joint_axis_B)


def rotated(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R v for rotations (... x 3 x 3) and vectors (... x 3) (numpy's sums over short axes are slow)."""
    return R[..., :, 0] * v[..., 0, None] + R[..., :, 1] * v[..., 1, None] + R[..., :, 2] * v[..., 2, None]


def _rotated_back(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R^T v for rotations (... x 3 x 3) and vectors (... x 3)."""
    return R[..., 0, :] * v[..., 0, None] + R[..., 1, :] * v[..., 1, None] + R[..., 2, :] * v[..., 2, None]


def gravity_torques(kinematics: "BatchedKinematics", q: np.ndarray, poses: np.ndarray | None = None) -> np.ndarray:
    """Generalized gravity forces on the arm joints (B x n, N m), as Drake's CalcGravityGeneralizedForces: the
    negated inverse dynamics at rest. `poses`: the bodies' poses at q if already computed."""
    if poses is None:
        poses = kinematics.body_poses(np.atleast_2d(q))
    still = np.zeros((len(poses), len(kinematics.dof_link)))
    return -joint_torques(kinematics, poses, still, still)


@dataclass
class Payload:
    """A held object as point masses, each fixed to one tracked body (e.g. half its mass in each hand)."""

    slots: np.ndarray  # P, the bodies' positions in BatchedKinematics.links
    points_B: np.ndarray  # P x 3, where each mass sits in its body's frame, m
    masses: np.ndarray  # P, kg


def joint_torques(
    kinematics: "BatchedKinematics",
    poses: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    payload: Payload | None = None,
) -> np.ndarray:
    """Inverse dynamics of the arms (B x n, N m): the joint torques that give accelerations qdd at velocities qd
    (each B x n, rad/s and rad/s^2) against gravity, with the payload's masses, as Drake's CalcInverseDynamics
    with every other joint still (the arm joints' damping included).

    Newton-Euler, every link at once: each link's angular velocity and acceleration are the sums of the joints'
    contributions along its path from the root (a joint's axis times its rate, and its rate turned by the
    velocity of what carries it), its origin's acceleration the sum of each link's increment over its parent
    along the path (gravity as an upward acceleration of the root); then each link's inertial force and moment
    about its centre of mass, and each joint's torque the axial moment, about its axis, of the forces of
    everything it carries. Arrays are link-major (L x B x 3), as body_poses stores them.
    """
    parent, arm_dof = kinematics._parent, kinematics._arm_dof
    carried = kinematics.carried.astype(float)  # n x L
    positions, axes = (x.swapaxes(0, 1) for x in joint_axes(kinematics, poses))  # n x B x 3
    poses = poses.swapaxes(0, 1)  # L x B x 4 x 4
    R, origin = poses[..., :3, :3], poses[..., :3, 3]
    qd, qdd = qd.T[..., None], qdd.T[..., None]  # n x B x 1
    spin = axes * qd

    def summed(matrix, per_item):  # matrix (M x K) times per_item (K x B x 3): M x B x 3
        return (matrix @ per_item.reshape(len(per_item), -1)).reshape(len(matrix), *per_item.shape[1:])

    omega = summed(carried.T, spin)  # L x B x 3
    carrier = parent[kinematics.dof_link]  # each coordinate's parent link, whose velocity turns its axis
    omega_before = np.where((carrier >= 0)[:, None, None], omega[carrier], 0.0)
    alpha = summed(carried.T, axes * qdd + _cross(omega_before, spin))
    # Each link's origin's acceleration over its parent's: about the parent's motion to the link's joint's axis
    # (its origin, for a fixed link), then the link's own motion from there.
    moving = parent >= 0
    parents = np.where(moving, parent, 0)
    pivot = origin.copy()
    driven = arm_dof >= 0
    pivot[driven] = positions[arm_dof[driven]]
    w_p, a_p = omega[parents], alpha[parents]
    to_pivot, from_pivot = pivot - origin[parents], origin - pivot
    increment = (
        _cross(a_p, to_pivot)
        + _cross(w_p, _cross(w_p, to_pivot))
        + _cross(alpha, from_pivot)
        + _cross(omega, _cross(omega, from_pivot))
    )
    increment[~moving] = 0.0
    accel = summed(kinematics._path, increment) - kinematics.gravity  # of each body's origin, W
    offset = rotated(R, kinematics.coms_B[:, None, :])
    com = origin + offset
    com_accel = accel + _cross(alpha, offset) + _cross(omega, _cross(omega, offset))
    force = kinematics.masses[:, None, None] * com_accel
    # Euler's equation in each body's frame, turned back into W.
    omega_B, alpha_B = _rotated_back(R, omega), _rotated_back(R, alpha)
    inertia = kinematics.inertias_B[:, None]  # L x 1 x 3 x 3
    moment_B = rotated(inertia, alpha_B) + _cross(omega_B, rotated(inertia, omega_B))
    moment = rotated(R, moment_B) + _cross(com, force)  # about W's origin
    total_force, total_moment = summed(carried, force), summed(carried, moment)  # n x B x 3
    if payload is not None:
        s = payload.slots
        offset = rotated(R[s], payload.points_B[:, None, :])
        w = omega[s]
        mass_accel = accel[s] + _cross(alpha[s], offset) + _cross(w, _cross(w, offset))
        point_force = payload.masses[:, None, None] * mass_accel
        total_force += summed(carried[:, s], point_force)
        total_moment += summed(carried[:, s], _cross(origin[s] + offset, point_force))
    axial = (total_moment - _cross(positions, total_force)) * axes
    torques = (axial[..., 0] + axial[..., 1] + axial[..., 2]).T  # B x n
    return torques + kinematics.damping * qd[..., 0].T


def off_the_robot(points_W: np.ndarray, robot_spheres_W: np.ndarray, margin: float) -> np.ndarray:
    """The points (N x 3 in W) farther than `margin` (m) from every sphere (S x 4: centre in W, radius; m)."""
    if not len(robot_spheres_W) or not len(points_W):
        return points_W
    on_robot = np.zeros(len(points_W), bool)
    for index in cKDTree(points_W).query_ball_point(robot_spheres_W[:, :3], robot_spheres_W[:, 3] + margin):
        on_robot[index] = True
    return points_W[~on_robot]


@dataclass
class SphereModel:
    """Spheres bounding the robot's collision geometry, attached to bodies."""

    body: np.ndarray  # S, position of each sphere's body in BatchedKinematics.links
    centre_B: np.ndarray  # S x 3, in the body frame
    radius: np.ndarray  # S
    group: np.ndarray  # S, which rigid group (arm side) the sphere belongs to: 0 torso, 1 left, 2 right
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

    def pairs(self, inspector, group_a: int, group_b: int) -> tuple[np.ndarray, np.ndarray]:
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
        group_of_body: body name -> group id (0 torso, 1 left arm and hand, 2 right).
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


def centauro_kinematics(plant: MultibodyPlant, scene_graph, plant_context, arm_joints: list[str], hands: dict):
    """Batched kinematics of both arms with the hands, and their sphere model.

    Args:
        arm_joints: the planned joints' names: the left arm (arm1_*), the right (arm2_*), and the torso yaw if
            it is planned.
        hands: {"left": model instance, "right": model instance} of the hands.

    Groups: 0 pelvis/torso/head, 1 left arm + left hand, 2 right arm + right hand.
    """
    joints = [plant.GetJointByName(name) for name in arm_joints]
    bodies = [joint.child_body() for joint in joints]
    for hand in hands.values():
        bodies += [plant.get_body(b) for b in plant.GetBodyIndices(hand)]
    bodies += [plant.GetBodyByName("torso"), plant.GetBodyByName("pelvis")]
    kinematics = BatchedKinematics(plant, plant_context, joints, bodies)

    def group(name, model_instance):
        if model_instance == hands["left"] or name.startswith("arm1_"):
            return 1
        if model_instance == hands["right"] or name.startswith("arm2_"):
            return 2
        return 0

    return kinematics, robot_spheres(plant, scene_graph, kinematics, group)


class EndEffectors:
    """World poses of the two hands' grasp frames for batches of arm configurations."""

    def __init__(self, kinematics: BatchedKinematics, frames):
        """Args:
        frames: the two end-effector frames (left, right), each fixed to a tracked body.
        """
        self.kinematics = kinematics
        self.positions = [kinematics.position_of_body[frame.body().index()] for frame in frames]
        self.X_BE = np.array([frame.GetFixedPoseInBodyFrame().GetAsMatrix4() for frame in frames])  # 2 x 4 x 4
        # 2 x n x 1: 1 for the joints that move each frame
        self._moved_by = np.array(
            [kinematics.carried[:, position].astype(float)[:, None] for position in self.positions]
        )

    def poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(X_WE1, X_WE2), each B x 4 x 4."""
        return self.from_body_poses(self.kinematics.body_poses(q))

    def from_body_poses(self, body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(X_WE1, X_WE2), each ... x 4 x 4, from the tracked bodies' poses (... x L x 4 x 4)."""
        return tuple(body[..., p, :, :] @ X for p, X in zip(self.positions, self.X_BE, strict=True))

    def jacobians(self, q: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """((X_WE1, X_WE2), (J_E1, J_E2)): the poses (B x 4 x 4) and geometric Jacobians (B x 6 x n, rows angular
        then translational velocity in W) of both end-effectors. Joint j at p_j with axis a_j moves E by
        J_w = a_j, J_v = a_j x (p_E - p_j) if it carries E, else not at all."""
        body = self.kinematics.body_poses(q)
        positions, axes = joint_axes(self.kinematics, body)
        X = body[:, self.positions] @ self.X_BE  # B x 2 x 4 x 4: both hands in one product
        J_w = axes[:, None] * self._moved_by  # B x 2 x n x 3
        J_v = _cross(J_w, X[:, :, None, :3, 3] - positions[:, None])
        J = np.concatenate([J_w, J_v], axis=3).transpose(0, 1, 3, 2)  # B x 2 x 6 x n
        return (X[:, 0], X[:, 1]), (J[:, 0], J[:, 1])

    def relative(self, q: np.ndarray) -> np.ndarray:
        """X_E1E2 (B x 4 x 4): the right end-effector's pose seen from the left one's."""
        X1, X2 = self.poses(q)
        return relative_pose(X1, X2)


def relative_pose(X1: np.ndarray, X2: np.ndarray) -> np.ndarray:
    """X_12 = X_W1^-1 X_W2 for batches of poses (B x 4 x 4)."""
    inverse = np.zeros_like(X1)
    inverse[:, :3, :3] = np.transpose(X1[:, :3, :3], (0, 2, 1))
    inverse[:, :3, 3] = -np.einsum("bji,bj->bi", X1[:, :3, :3], X1[:, :3, 3])
    inverse[:, 3, 3] = 1.0
    return inverse @ X2
