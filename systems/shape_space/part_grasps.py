"""Grasp frames built on the handles the camera sees, with the shape-space fit as their prior.

The part network labels the object's pixels with their functional parts (systems/perception/parts.py); each hand
takes one part: the left hand the LEFT_HANDLE (a can's top handle, a drill's side handle), the right hand the
RIGHT_HANDLE (a can's rear handle, a drill's pistol grip). For each hand:

1. The seed: the point of the hand's part nearest the prior's grasp (the shape-space fit's, registration.py).
2. A straight tube is fitted to the part's points about the seed (systems/perception/tube_fit.py): its axis, its
   radius, where the points lie along it.
3. The grasp frame G (x_G along the handle, y_G the fingers' closing direction, z_G the approach; the generators'
   convention, diagrams/generation/objects/instance.py) is built on the tube: its origin on the axis, at the foot
   of the prior's grasp moved along the axis until the fingers' span fits within the seen stretch (and the tube is
   fitted again there); x_G the axis, turned to agree with the prior's x_G (a hand is symmetric about z_G, so
   either way is one grasp); z_G the category's approach for that hand (the canonical grasp's approach in O, by
   the fitted pose X_WO) made perpendicular to x_G: a top handle is taken from above whichever way it runs, a
   rear handle from behind. The pre-grasp backs off along -z_G as the prior's does.

The rules between the seen part and the prior:
- A part seen well (PartFit.sound: enough points about the seed, a tube of a handle's radius that they lie on)
  decides its hand's grasp, whatever the prior says: the prior only seeds the fit and gives the approach.
- A part not seen well leaves its hand to the prior, and only where the prior is sound (the fit is not poor and
  the prior grasp is confirmed by the camera, Registration.poor_fit / unconfirmed); else the grasp is poor and the
  perception names why.
- An approach that runs along the seen handle (within MAX_APPROACH_ALONG_AXIS) cannot close across it: such a
  part is not used.
"""

from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from systems.perception.parts import PartRole
from systems.perception.tube_fit import Tube, fit_tube

HAND_PARTS = {"left": PartRole.LEFT_HANDLE, "right": PartRole.RIGHT_HANDLE}
MIN_PART_POINTS = 40  # seen points of a part, fewer: the part is not seen
FINGER_HALF_SPAN = 0.03  # m: the fingers' half width along the handle (sdf/centauro/hand.sdf: 6 cm pads)
MAX_TUBE_RMS = 0.005  # m: a part's points farther from the fitted tube than this (RMS) are no handle seen well
MIN_TUBE_POINTS = 30  # points the tube is fitted to, about the seed
# rad: an approach within this of the handle's axis cannot close the fingers across the handle
MAX_APPROACH_ALONG_AXIS = np.radians(20.0)


@dataclass(frozen=True)
class PartFit:
    """One hand's part as seen: the tube fitted to it (None where none was found) and how many points it had."""

    hand: str
    points: int
    tube: Tube | None = None
    reason: str = ""  # why the part does not decide the grasp ("" where it does)

    @property
    def sound(self) -> bool:
        return self.tube is not None and not self.reason


@dataclass
class PartGrasps:
    """Each hand's grasp and pre-grasp (POSE_NAMES -> X_WG), where each came from, and why a hand has none."""

    poses_W: dict[str, RigidTransform] = field(default_factory=dict)
    sources: dict[str, str] = field(default_factory=dict)  # hand -> "seen part" or "shape prior"
    fits: dict[str, PartFit] = field(default_factory=dict)
    poor: str = ""  # why a hand has no grasp to use ("" when both have one)

    @property
    def found(self) -> bool:
        return not self.poor

    def summary(self) -> str:
        return ", ".join(f"{hand} grasp from the {source}" for hand, source in self.sources.items())


def fit_part(hand: str, points_W: np.ndarray, viewpoint_W: np.ndarray, prior_W: RigidTransform) -> PartFit:
    """The hand's part seen in `points_W` (N x 3, m), fitted as a tube about the prior grasp's nearest part point,
    moved along the axis until the fingers' span fits within what was seen, and fitted again there."""
    points_W = np.asarray(points_W, float).reshape(-1, 3)
    count = len(points_W)
    if count < MIN_PART_POINTS:
        return PartFit(hand, count, reason=f"{count} points seen (at least {MIN_PART_POINTS} expected)")
    prior = prior_W.translation()
    seed = points_W[np.argmin(np.linalg.norm(points_W - prior, axis=1))]
    tube = fit_tube(points_W, viewpoint_W, seed)
    if tube is not None:
        along = np.clip(tube.along(prior), tube.extent[0] + FINGER_HALF_SPAN, tube.extent[1] - FINGER_HALF_SPAN)
        if tube.extent[1] - tube.extent[0] < 2 * FINGER_HALF_SPAN:
            along = 0.5 * (tube.extent[0] + tube.extent[1])
        moved = tube.point + along * tube.axis
        refitted = fit_tube(points_W, viewpoint_W, points_W[np.argmin(np.linalg.norm(points_W - moved, axis=1))])
        tube = refitted or tube
    if tube is None or tube.points < MIN_TUBE_POINTS:
        return PartFit(hand, count, tube, f"no tube of a handle's radius fits the {count} points")
    if tube.rms_m > MAX_TUBE_RMS:
        return PartFit(hand, count, tube, f"the points lie {1000 * tube.rms_m:.1f} mm (RMS) off the fitted tube")
    return PartFit(hand, count, tube)


def grasp_on_tube(tube: Tube, approach_W: np.ndarray, prior_W: RigidTransform, pregrasp_m: float):
    """(grasp X_WG, pre-grasp X_WP) on the tube, or None where the approach runs along it: origin on the axis at the
    tube's point, x_G along the axis (the prior's way round), z_G the approach made perpendicular to the axis."""
    x = tube.axis if np.dot(tube.axis, prior_W.rotation().col(0)) >= 0 else -tube.axis
    a = np.asarray(approach_W, float) / np.linalg.norm(approach_W)
    if abs(np.dot(a, x)) > np.cos(MAX_APPROACH_ALONG_AXIS):
        return None
    z = a - np.dot(a, x) * x
    z /= np.linalg.norm(z)
    X_WG = RigidTransform(RotationMatrix(np.column_stack([x, np.cross(z, x), z])), tube.point)
    return X_WG, X_WG @ RigidTransform([0.0, 0.0, -pregrasp_m])


def grasps_on_seen_parts(
    part_points_W: dict[PartRole, np.ndarray],
    viewpoint_W: np.ndarray,
    prior_poses_W: dict[str, RigidTransform],
    approaches_W: dict[str, np.ndarray],
    prior_sound: bool,
    prior_poor: str = "",
) -> PartGrasps:
    """Each hand's grasp on its seen part, or from the prior where the part is not seen well (module docstring).

    Args:
        part_points_W: the object's seen points of each part (N x 3 each, m, W); parts not seen may be missing.
        viewpoint_W: the camera's position (3,), m.
        prior_poses_W: the shape-space fit's control poses (POSE_NAMES -> X_WG).
        approaches_W: each hand's approach direction by the category's rule (3,), in W.
        prior_sound: whether the prior's grasps may be used alone (the fit is not poor, its grasps confirmed).
        prior_poor: why the prior is not sound (for the message).
    """
    result = PartGrasps()
    for hand, role in HAND_PARTS.items():
        prior_grasp, prior_pregrasp = prior_poses_W[f"{hand}_grasp"], prior_poses_W[f"{hand}_pregrasp"]
        fit = fit_part(hand, part_points_W.get(role, np.zeros((0, 3))), viewpoint_W, prior_grasp)
        grasp = None
        if fit.sound:
            pregrasp_m = float(np.linalg.norm(prior_grasp.translation() - prior_pregrasp.translation()))
            grasp = grasp_on_tube(fit.tube, approaches_W[hand], prior_grasp, pregrasp_m)
            if grasp is None:
                fit = PartFit(hand, fit.points, fit.tube, "the approach runs along the seen handle")
        result.fits[hand] = fit
        if grasp is not None:
            result.poses_W[f"{hand}_grasp"], result.poses_W[f"{hand}_pregrasp"] = grasp
            result.sources[hand] = "seen part"
        elif prior_sound:
            result.poses_W[f"{hand}_grasp"], result.poses_W[f"{hand}_pregrasp"] = prior_grasp, prior_pregrasp
            result.sources[hand] = "shape prior"
        elif not result.poor:
            result.poor = f"the {hand} hand's handle is not seen well ({fit.reason}), and {prior_poor or 'the prior'}"
    return result
