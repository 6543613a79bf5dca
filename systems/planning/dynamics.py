"""Inverse dynamics of Centauro's arms for batches of configurations (STOMP's torque term), and a held payload."""

from dataclasses import dataclass

import numpy as np

from systems.planning.kinematics import BatchedKinematics, cross, joint_axes, rotated


def _rotated_back(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R^T v for rotations (... x 3 x 3) and vectors (... x 3)."""
    return R[..., 0, :] * v[..., 0, None] + R[..., 1, :] * v[..., 1, None] + R[..., 2, :] * v[..., 2, None]


def gravity_torques(kinematics: BatchedKinematics, q: np.ndarray, poses: np.ndarray | None = None) -> np.ndarray:
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
    kinematics: BatchedKinematics,
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
    parent, arm_dof = kinematics.link_parent, kinematics.link_dof
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
    alpha = summed(carried.T, axes * qdd + cross(omega_before, spin))
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
        cross(a_p, to_pivot)
        + cross(w_p, cross(w_p, to_pivot))
        + cross(alpha, from_pivot)
        + cross(omega, cross(omega, from_pivot))
    )
    increment[~moving] = 0.0
    accel = summed(kinematics.link_path, increment) - kinematics.gravity  # of each body's origin, W
    offset = rotated(R, kinematics.coms_B[:, None, :])
    com = origin + offset
    com_accel = accel + cross(alpha, offset) + cross(omega, cross(omega, offset))
    force = kinematics.masses[:, None, None] * com_accel
    # Euler's equation in each body's frame, turned back into W.
    omega_B, alpha_B = _rotated_back(R, omega), _rotated_back(R, alpha)
    inertia = kinematics.inertias_B[:, None]  # L x 1 x 3 x 3
    moment_B = rotated(inertia, alpha_B) + cross(omega_B, rotated(inertia, omega_B))
    moment = rotated(R, moment_B) + cross(com, force)  # about W's origin
    total_force, total_moment = summed(carried, force), summed(carried, moment)  # n x B x 3
    if payload is not None:
        s = payload.slots
        offset = rotated(R[s], payload.points_B[:, None, :])
        w = omega[s]
        mass_accel = accel[s] + cross(alpha[s], offset) + cross(w, cross(w, offset))
        point_force = payload.masses[:, None, None] * mass_accel
        total_force += summed(carried[:, s], point_force)
        total_moment += summed(carried[:, s], cross(origin[s] + offset, point_force))
    axial = (total_moment - cross(positions, total_force)) * axes
    torques = (axial[..., 0] + axial[..., 1] + axial[..., 2]).T  # B x n
    return torques + kinematics.damping * qd[..., 0].T
