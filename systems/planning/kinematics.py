"""Batched forward kinematics of Centauro's arms and hands, and the poses and Jacobians of their grasp frames.

STOMP evaluates thousands of configurations per iteration; one Drake call per
configuration is far too slow, so the kinematic tree is read once from the
MultibodyPlant and evaluated here in numpy for a whole batch (B x n) at once.
n is the number of planned joints: 14 for the arms, 15 with the torso yaw (last).

Every body of interest is reached from the world through the planned revolute joints;
all other joints (welds, the hands' fingers) keep the pose they have in the plant
context given at construction. Poses are 4 x 4 homogeneous matrices X_WB. The sphere model of their collision
geometry is systems/planning/sphere_model.py; their inverse dynamics, systems/planning/dynamics.py.
"""

from dataclasses import dataclass

import numpy as np
from pydrake.multibody.plant import MultibodyPlant


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
        # For the inverse dynamics (systems/planning/dynamics.py): each link's parent (-1 for a root), each driven
        # link's coordinate (-1 for a fixed one), and which links lie on the path from a root to each link (L x L:
        # link_path[l, k] when k is l or one of its ancestors, roots excluded).
        self.link_parent = parent
        self.link_dof = arm_dof
        self.link_path = np.zeros((len(self.links), len(self.links)))
        for i in range(len(self.links)):
            j = i
            while parent[j] >= 0:
                self.link_path[i, j] = 1.0
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

    def body_name(self, position: int) -> str:
        """The tracked link at `position` by name, its model instance's first ("left_hand finger_2", "centauro
        arm1_6"): the hands' bodies share their names."""
        body = self._plant.get_body(self.links[position].body_index)
        return f"{self._plant.GetModelInstanceName(body.model_instance())} {body.name()}"

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


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
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
        J_v = cross(J_w, X[:, :, None, :3, 3] - positions[:, None])
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
