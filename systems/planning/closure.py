"""The kinematic-chain closure cost of STOMP-New (paper §IV-B, equations (2)-(4)).

When both hands hold an object, the pose of one end-effector relative to the other
must stay as it was at the first configuration theta_0. Per configuration, t_dev is
the largest component of |t_desired - t_j| (translation between the end-effectors,
here expressed in the left one's frame) and o_dev the deviation of the relative
orientation. The paper takes the largest of |o_desired - o_j| over roll, pitch and yaw;
here o_dev is the angle of the rotation between o_desired and o_j, which bounds the same
thing (each roll/pitch/yaw difference of a small rotation is at most its angle, away from
the singularity) but stays meaningful near pitch = +-90 degrees, where roll and yaw
differences blow up for tiny rotations (grasp frames there made a 0.01 rad tilt read as
0.15 rad). Each is scored as

    q(dev) = dev / max                 if dev <  max    (in [0, 1))
             C + C * dev               if dev >= max    (C >> 1)

and a transition theta_i -> theta_{i+1} costs
q_cc = 1/2 max_j q_ct(theta_j) + 1/2 max_j q_co(theta_j) over the states j along it.
"""

from dataclasses import dataclass

import numpy as np

from systems.planning.kinematics import EndEffectors


@dataclass
class ClosureConstraint:
    t_max: float = 0.01  # m
    o_max: float = 0.05  # rad
    C_ct: float = 1000.0
    C_co: float = 1000.0


def rpy_of(R: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (B x 3) of rotation matrices (B x 3 x 3), the convention of Drake's RollPitchYaw."""
    roll = np.arctan2(R[:, 2, 1], R[:, 2, 2])
    pitch = np.arcsin(np.clip(-R[:, 2, 0], -1.0, 1.0))
    yaw = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    return np.column_stack([roll, pitch, yaw])


def rotation_angle(R: np.ndarray, R_desired: np.ndarray) -> np.ndarray:
    """The angle (rad) of the rotation between each of R (B x 3 x 3) and R_desired."""
    trace = np.einsum("ij,bij->b", R_desired, R)  # trace(R_desired^T R)
    return np.arccos(np.clip(0.5 * (trace - 1.0), -1.0, 1.0))


def deviations(end_effectors: EndEffectors, q: np.ndarray, X_E1E2_desired: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t_dev, o_dev) of each configuration (B x n): the largest translation component deviation (m) and
    the relative orientation's deviation angle (rad)."""
    return relative_deviations(end_effectors.relative(q), X_E1E2_desired)


def relative_deviations(X_E1E2: np.ndarray, X_E1E2_desired: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t_dev, o_dev) of relative hand poses X_E1E2 (B x 4 x 4), as deviations()."""
    t_dev = np.abs(X_E1E2[:, :3, 3] - X_E1E2_desired[:3, 3]).max(axis=1)
    return t_dev, rotation_angle(X_E1E2[:, :3, :3], X_E1E2_desired[:3, :3])


def threshold_cost(deviation: np.ndarray, maximum: float, C: float) -> np.ndarray:
    """Equations (3)/(4): dev / max below the threshold, C + C * dev at or beyond it."""
    return np.where(deviation >= maximum, C + C * deviation, deviation / maximum)


def transition_costs(t_dev: np.ndarray, o_dev: np.ndarray, constraint: ClosureConstraint) -> np.ndarray:
    """Equation (2) for each transition, given deviations at the states along it (... x transitions x states)."""
    q_ct = threshold_cost(t_dev, constraint.t_max, constraint.C_ct)
    q_co = threshold_cost(o_dev, constraint.o_max, constraint.C_co)
    return 0.5 * q_ct.max(axis=-1) + 0.5 * q_co.max(axis=-1)


@dataclass
class OrientationConstraint:
    """STOMP-New's end-effector orientation constraint: both hands keep their world orientation from theta_0.
    With upright_only, only their tilt is kept (the world's vertical as seen from each hand): the hands, and
    the object they hold, may turn about the vertical but do not tip (a carry that turns the object)."""

    o_max: float = 0.05  # rad
    C: float = 1000.0
    upright_only: bool = False


def orientation_deviations(
    end_effectors: EndEffectors, q: np.ndarray, R_desired, upright_only: bool = False
) -> np.ndarray:
    """Largest deviation (rad) of either hand from its desired world orientation (the rotation's angle), or with
    upright_only the angle between the vertical seen from the hand and from R_desired, per configuration."""
    return hand_orientation_deviations(end_effectors.poses(q), R_desired, upright_only)


def hand_orientation_deviations(hand_poses, R_desired, upright_only: bool = False) -> np.ndarray:
    """orientation_deviations() of the hands' poses (X_WE1, X_WE2), each B x 4 x 4."""
    angle = tilt_angle if upright_only else rotation_angle
    return np.max([angle(X[:, :3, :3], R) for X, R in zip(hand_poses, R_desired, strict=True)], axis=0)


def tilt_angle(R: np.ndarray, R_desired: np.ndarray) -> np.ndarray:
    """The angle (rad) between the world z axis seen in each of R (B x 3 x 3) and in R_desired: R's tilt away
    from R_desired, whatever it turned about the vertical."""
    cosine = R[:, 2, :] @ R_desired[2, :]  # (R^T e_z) . (R_desired^T e_z)
    return np.arccos(np.clip(cosine, -1.0, 1.0))
