"""Grasp frames built on the handles the camera sees, with the shape-space fit as their prior.

The part network labels the object's pixels with their functional parts (systems/messages.py's PartRole); each
hand takes one part: the left hand the LEFT_HANDLE (a can's top handle, a drill's side handle), the right hand the
RIGHT_HANDLE (a can's rear handle, a drill's pistol grip). For each hand, a straight tube is fitted to its part's
points about a seed (systems/perception/tube_fit.py: axis, radius, where the points lie along it; along an arch,
the tangent tube there), and the grasp frame G is built on it (x_G along the handle, y_G the fingers' closing
direction, z_G the approach: the generators' convention, diagrams/generation/objects/instance.py): its origin on
the axis; x_G the axis, turned to agree with the prior's x_G (a hand is symmetric about z_G: either way is one
grasp); z_G the category's approach for that hand (the canonical grasp's approach in O, turned by the fitted pose
X_WO) made perpendicular to x_G, so a top handle is taken from above whichever way it runs and a rear handle from
behind. The pre-grasp backs off along -z_G as the prior's does.

Where along the handle (the seed), and the rules between the seen part and the prior:
- The prior is sound (the fit is not poor: Registration.poor_fit) and its grasp lies on the seen handle (within
  PRIOR_ACROSS of the tube's axis): the grasp stays at the prior's place along the handle, moved onto the seen
  axis, its orientation kept (a handle's axis fitted to a partial, noisy view is less sure than a sound fit's
  frame). The part corrects the prior across the handle; it does not move a sound grasp along it. Where the camera
  did not see the handle there (no seen point within FINGER_HALF_SPAN of that place, or the grasp on the seen
  tube more than PRIOR_ACROSS from the prior's: hidden behind the body, beyond the image, or a few stray pixels
  given the handle's role), the sound prior's grasp stands as it is.
- The prior is poor but its grasp lies on the seen handle, nearer (POOR_PRIOR_ACROSS) than a sound one must: the
  grasp takes the prior's place along the handle, on the seen axis, its frame built on the tube as below. A fit poor
  as a whole is often right about one handle, and the seen part's middle is only a guess of where along a long
  handle (a loop, a side handle) the hand belongs. Not where the fit is turned end for end. On the tuning range's
  first pick frames (shop_100-119 at 3 yaws, both categories, and test_0-2 cans; kinect_v2) it took the grasp median
  from 23.5 to 16.4 mm (drills) and from 13.5 to 10.8 mm (cans); frames with a grasp over 3 cm off from 24 to 25
  and from 32 to 26; frames handed on from 50 to 50 and from 60 to 64. Not where that place stands on a sliver of
  the part beside the handle (_on_a_sliver: the tube at the handle's middle lies on another piece, seen far more
  densely): there the poor fit's grasp fell on a few pixels given the handle's role at the edge of the body or of
  another handle, and the middle decides.
- The prior is poor (and its grasp not on the seen handle), or a sound prior's grasp is not on the seen handle:
  the handle's middle decides (handle_middle: halfway between the ends of the part's points along their longest
  direction, an arch's or a D's chord, a grip's axis; where the generators put a grasp, and where a hand holds).
- The image's border cut the part (SeenPart.cut_off) and the prior is poor: the handle's middle is not seen, so
  the prior's place along it is taken, moved into the seen stretch until the fingers' span lies on it.
- A fit turned end for end (the seen spout or chuck lies behind it, or the rear handle ahead: turned_end_for_end)
  is a poor prior, and the approaches are turned back with it (half a turn about the vertical).
- A sound prior whose grasp lies more than OFF_HANDLE_M from every seen point of its own handle, seen well and not
  cut off by the image's border, is wrong about that handle (prior_off_seen_handle): the fit is taken as poor, and
  both hands' grasps are built as for a poor prior.
- A part not seen well (fewer than MIN_PART_POINTS, no tube of a handle's radius, a tube seen over less than
  MIN_SEEN_LENGTH, its points more than MAX_TUBE_RMS off the tube, or an approach running along it) leaves its
  hand to the prior, and only where the prior is sound; else the grasps are poor, and perception names why.
"""

import functools
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from systems.messages import SeenPart
from systems.perception.parts import PartRole
from systems.perception.tube_fit import Tube, fit_tube

HAND_PARTS = {"left": PartRole.LEFT_HANDLE, "right": PartRole.RIGHT_HANDLE}
MIN_PART_POINTS = 40  # seen points of a part, fewer: the part is not seen
MAX_TUBE_RMS = 0.005  # m: a part's points farther from the fitted tube than this (RMS) are no handle seen well
MIN_TUBE_POINTS = 30  # points the tube is fitted to, about the seed
SIDE_M = 0.03  # m: a part this far ahead of or behind the object's centre says which way the object faces
MIN_SEEN_LENGTH = 0.02  # m: a tube whose points span less than this along its axis is no handle seen well
FINGER_HALF_SPAN = 0.03  # m: the fingers' half width along the handle (sdf/centauro/hand.sdf: 6 cm pads)
STRETCH_MARGIN = 0.006  # m: a part's point this near the fitted tube's surface lies on its straight stretch
PRIOR_ACROSS = 0.03  # m: a prior grasp farther than this across the seen handle's axis is not on it
# m: a poor prior's grasp within this of the seen handle's axis keeps its place along it (the middle decides where
# it is farther). Chosen on the tuning range's first pick frames (module docstring): at 3 cm more drill grips went
# 6-9 cm off (33 frames with a grasp over 3 cm off, against 25); 1.5 cm helped the cans less.
POOR_PRIOR_ACROSS = 0.02
# m: a sound prior's grasp farther than this from every seen point of its own handle (seen well) is not on it. A
# handle partly hidden by the body leaves its true grasp up to 7 cm from its seen points (the test cans' rear
# handles at yaw 0, kinect_v2; 98 first pick frames of test_0-2 and shop_100-119, none past 8 cm; 2026-12-04).
OFF_HANDLE_M = 0.08
# Of the points the tube at the handle's middle is fitted to: a tube at a poor prior's place on another piece of the
# part, fitted to fewer, stands on a sliver of label beside the handle (_on_a_sliver). Chosen on the tuning range's
# first pick frames (shop_100-119 drills, 3 yaws, kinect_v2, 2026-12-07): where the two disagreed, the prior's tube
# had 10-29 % of the middle's points in the 7 frames whose prior lay 6-9 cm off the true grip, 49-96 % in the 3 others;
# the cans' (test_0-2, shop_100-119) only where the middle's tube was the body's (HANDLE_RADIUS_MAX).
SLIVER_SHARE = 0.4
# m: a tube of a larger radius is no handle a hand holds (handles are 1.6-4 cm thick) but a body's curve (the tubes at
# the handle's middle where the drill's side handle's or the can's rear handle's role ran onto the body: radius 23-25
# mm, on the same frames)
HANDLE_RADIUS_MAX = 0.02
MIDDLE_BAND = 0.01  # m: a handle's middle slice, this far either side of halfway along it
MIDDLE_STEPS = (0.015, -0.015, 0.03, -0.03)  # m along the part, where to try when no tube fits at its middle
# rad: an approach within this of the handle's axis cannot close the fingers across the handle
MAX_APPROACH_ALONG_AXIS = np.radians(20.0)


@dataclass(frozen=True)
class PartFit:
    """One hand's part as seen: the tube fitted to it (None where none was found) and how many points it had."""

    hand: str
    points: int
    tube: Tube | None = None
    reason: str = ""  # why the part does not decide the grasp ("" where it does)
    cut_off: bool = False  # the image's border cut the part: its place along the handle is the prior's

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


def handle_middle(points_W: np.ndarray) -> np.ndarray:
    """The point of a handle's seen points (N x 3, m) in its middle: along the part's longest principal direction
    (an arch's or a D's chord, a grip's or a bar's axis), the slice of points halfway between its ends, and of that
    slice the point nearest its centre."""
    centred = points_W - points_W.mean(axis=0)
    _, vectors = np.linalg.eigh(centred.T @ centred)
    along = centred @ vectors[:, -1]
    low, high = np.percentile(along, [2, 98])
    middle = 0.5 * (low + high)
    band = points_W[np.abs(along - middle) < MIDDLE_BAND]
    if len(band) == 0:
        band = points_W[[np.argmin(np.abs(along - middle))]]
    return band[np.argmin(np.linalg.norm(band - band.mean(axis=0), axis=1))]


def seen_points(part: SeenPart | None) -> np.ndarray:
    """A part's finite seen points, N x 3 in W (none where the part was not seen)."""
    points_W = np.zeros((0, 3)) if part is None else np.asarray(part.points_W, float).reshape(-1, 3)
    return points_W[np.all(np.isfinite(points_W), axis=1)]


def fit_part(
    hand: str,
    part: SeenPart | None,
    viewpoint_W: np.ndarray,
    prior_W: RigidTransform,
    prior_sound: bool,
    poor_prior_place: bool = True,
) -> PartFit:
    """The hand's part as seen, fitted as a tube, and where along it the grasp goes (PartFit.tube.point): about the
    handle's middle (handle_middle); or, where the prior grasp lies on the seen handle (a sound prior: within
    PRIOR_ACROSS of its axis; a poor one, with poor_prior_place: within POOR_PRIOR_ACROSS, not on a sliver beside
    the handle, _on_a_sliver), at the prior's place along it; or, where the image's border cut the part (its
    middle unseen), about the seen point nearest the prior grasp, at the prior's place along the handle moved into
    the seen stretch until the fingers' span lies on it."""
    points_W = seen_points(part)
    count = len(points_W)
    if count < MIN_PART_POINTS:
        return PartFit(hand, count, reason=f"{count} points seen (at least {MIN_PART_POINTS} expected)")
    cut_off, prior = part.cut_off, prior_W.translation()
    middle = functools.cache(lambda: _tube_near_middle(points_W, viewpoint_W))  # (fitted once, where asked)
    # (_sees_prior_place needs a seen point within FINGER_HALF_SPAN of the grasp on the axis, so within
    # POOR_PRIOR_ACROSS + FINGER_HALF_SPAN of the prior's: where there is none, no tube is fitted at the prior's place)
    if (
        not prior_sound
        and poor_prior_place
        and np.min(np.linalg.norm(points_W - prior, axis=1)) <= POOR_PRIOR_ACROSS + FINGER_HALF_SPAN
    ):
        tube = _at_prior_place(points_W, viewpoint_W, prior, into_seen_stretch=False)
        if (
            tube is not None
            and _sees_prior_place(points_W, tube, prior, POOR_PRIOR_ACROSS)
            and not _on_a_sliver(tube, middle())
        ):
            fit = _checked(hand, count, tube, cut_off)
            if fit.sound:
                return fit
    tube = None
    if prior_sound or cut_off:
        tube = _at_prior_place(points_W, viewpoint_W, prior, into_seen_stretch=not prior_sound)
        if tube is not None and prior_sound and not _sees_prior_place(points_W, tube, prior, PRIOR_ACROSS):
            return PartFit(hand, count, tube, "the prior's place on the handle is not seen", cut_off)
    if tube is None and not cut_off:
        tube = middle()
    return _checked(hand, count, tube, cut_off)


def _checked(hand: str, count: int, tube: Tube | None, cut_off: bool) -> PartFit:
    """The part's fit with its tube, and why that tube is no handle seen well ("" where it is)."""
    if tube is None or tube.points < MIN_TUBE_POINTS:
        return PartFit(hand, count, tube, f"no tube of a handle's radius fits the {count} points", cut_off)
    if tube.extent[1] - tube.extent[0] < MIN_SEEN_LENGTH:
        reason = f"{1000 * (tube.extent[1] - tube.extent[0]):.0f} mm of it seen"
        return PartFit(hand, count, tube, reason, cut_off)
    if tube.rms_m > MAX_TUBE_RMS:
        reason = f"the points lie {1000 * tube.rms_m:.1f} mm (RMS) off the fitted tube"
        return PartFit(hand, count, tube, reason, cut_off)
    return PartFit(hand, count, tube, cut_off=cut_off)


def prior_off_seen_handle(
    parts: dict[PartRole, SeenPart], viewpoint_W: np.ndarray, prior_poses_W: dict[str, RigidTransform]
) -> str:
    """Why a sound prior is wrong about a handle the camera saw well: its grasp lies more than OFF_HANDLE_M from
    every seen point of that hand's part, a part seen well (fit_part) and not cut off by the image's border; ""
    where no hand's part says so."""
    for hand, role in HAND_PARTS.items():
        part, prior_W = parts.get(role), prior_poses_W[f"{hand}_grasp"]
        points_W = seen_points(part)
        if len(points_W) == 0 or part.cut_off:
            continue
        distance = float(np.min(np.linalg.norm(points_W - prior_W.translation(), axis=1)))
        # (the tube is fitted only where the prior is that far off: the distance is the cheap test)
        if distance > OFF_HANDLE_M and fit_part(hand, part, viewpoint_W, prior_W, False, poor_prior_place=False).sound:
            return f"the fit's {hand} grasp lies {100 * distance:.0f} cm from its handle as seen"
    return ""


def _at_prior_place(
    points_W: np.ndarray, viewpoint_W: np.ndarray, prior: np.ndarray, into_seen_stretch: bool
) -> Tube | None:
    """The tube about the seen point nearest the prior grasp, its point at the prior's place along it (with
    into_seen_stretch, moved into the seen stretch by the fingers' half span); None where no tube fits there or the
    prior lies farther across the seen axis than PRIOR_ACROSS (then the prior's place is not on this handle)."""
    seed = _nearest(points_W, prior)
    tube = fit_tube(points_W, viewpoint_W, seed)
    if tube is None:
        return None
    along = tube.along(prior)
    if np.linalg.norm(prior - tube.point - along * tube.axis) > PRIOR_ACROSS:
        return None
    if into_seen_stretch:
        low, high = _seen_stretch(points_W, tube)
        along = (
            0.5 * (low + high)
            if high - low < 2 * FINGER_HALF_SPAN
            else np.clip(along, low + FINGER_HALF_SPAN, high - FINGER_HALF_SPAN)
        )
    moved = tube.point + along * tube.axis
    moved_seed = _nearest(points_W, moved)
    if not np.array_equal(moved_seed, seed):  # (the same seed fits the same tube)
        tube = fit_tube(points_W, viewpoint_W, moved_seed) or tube
    return replace(tube, point=tube.point + tube.along(moved) * tube.axis)


def _tube_near_middle(points_W: np.ndarray, viewpoint_W: np.ndarray) -> Tube | None:
    """The tube about the handle's middle (handle_middle) or, where none fits there (a few of the body's pixels
    given the handle's role can leave the middle on the body), about the nearest of the points MIDDLE_STEPS along
    the part's longest direction from it that gives one of a handle's radius, seen well."""
    middle = handle_middle(points_W)
    centred = points_W - points_W.mean(axis=0)
    longest = np.linalg.eigh(centred.T @ centred)[1][:, -1]
    for step in (0.0, *MIDDLE_STEPS):
        tube = fit_tube(points_W, viewpoint_W, _nearest(points_W, middle + step * longest))
        if tube is not None and tube.points >= MIN_TUBE_POINTS and tube.rms_m <= MAX_TUBE_RMS:
            return tube
    return fit_tube(points_W, viewpoint_W, middle)


def _on_a_sliver(tube: Tube, middle: Tube | None) -> bool:
    """Whether the tube at a poor prior's place stands on a sliver of the part beside the handle: the tube at the
    handle's middle (`middle`: _tube_near_middle's) is a handle's (seen well, at most HANDLE_RADIUS_MAX thick) on
    another piece (its point more than PRIOR_ACROSS from this tube's axis), and the camera saw that piece far more
    densely (this tube fitted to fewer than SLIVER_SHARE of its points): pixels given the handle's role at the edge
    of a neighbouring part, where the poor fit's grasp fell."""
    if middle is None or middle.points < MIN_TUBE_POINTS or middle.rms_m > MAX_TUBE_RMS:
        return False
    if middle.radius > HANDLE_RADIUS_MAX:  # (the middle stands on the body: its tube is no handle's)
        return False
    across = middle.point - tube.point - tube.along(middle.point) * tube.axis
    return bool(np.linalg.norm(across) > PRIOR_ACROSS and tube.points < SLIVER_SHARE * middle.points)


def _sees_prior_place(points_W: np.ndarray, tube: Tube, prior: np.ndarray, across_m: float) -> bool:
    """Whether the camera saw the handle where the prior grasps it: the grasp on the tube lies within across_m of
    the prior's, and a seen point within FINGER_HALF_SPAN of it."""
    near = np.min(np.linalg.norm(points_W - tube.point, axis=1)) <= FINGER_HALF_SPAN
    return near and np.linalg.norm(tube.point - prior) <= across_m


def _seen_stretch(points_W: np.ndarray, tube: Tube) -> tuple[float, float]:
    """Where along the tube's axis (from its point, m) the part's points on the tube lie (within STRETCH_MARGIN of
    its surface; 2nd and 98th percentiles): the straight stretch seen, not only the points about the seed."""
    offset = points_W - tube.point
    along = offset @ tube.axis
    across = np.linalg.norm(offset - np.outer(along, tube.axis), axis=1)
    on_tube = np.abs(across - tube.radius) < STRETCH_MARGIN
    if np.count_nonzero(on_tube) < MIN_TUBE_POINTS:
        return tube.extent
    low, high = np.percentile(along[on_tube], [2, 98])
    return float(low), float(high)


def _nearest(points: np.ndarray, point: np.ndarray) -> np.ndarray:
    return points[np.argmin(np.linalg.norm(points - point, axis=1))]


def turned_end_for_end(
    parts: dict[PartRole, SeenPart], points_W: np.ndarray, x_WO: np.ndarray, prior_right_W: np.ndarray
) -> bool:
    """Whether the seen parts say a fitted pose whose x axis is x_WO is turned end for end. Along x_WO's horizontal
    part, from the seen points' centre: the tool (a can's spout, a drill's chuck) lies ahead in every category's
    frame, and the right hand's handle on the side the fit's own right grasp (prior_right_W) lies. Each part seen
    well (MIN_PART_POINTS) and more than SIDE_M from the centre votes; turned where more vote against the fit."""
    forward = np.array([x_WO[0], x_WO[1], 0.0])
    if np.linalg.norm(forward) < 0.5:
        return False
    forward /= np.linalg.norm(forward)
    centre = np.median(points_W, axis=0)
    expected_right = (np.asarray(prior_right_W) - centre) @ forward
    expected = {PartRole.TOOL: 1.0, PartRole.RIGHT_HANDLE: np.sign(expected_right) * (abs(expected_right) > SIDE_M)}
    votes = 0.0
    for role, sign in expected.items():
        seen_W = seen_points(parts.get(role))
        if len(seen_W) < MIN_PART_POINTS or not sign:
            continue
        side = (np.median(seen_W, axis=0) - centre) @ forward
        if abs(side) > SIDE_M:
            votes += np.sign(side) * sign
    return bool(votes < 0)


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
    parts: dict[PartRole, SeenPart],
    viewpoint_W: np.ndarray,
    prior_poses_W: dict[str, RigidTransform],
    approaches_W: dict[str, np.ndarray],
    prior_sound: bool,
    prior_poor: str = "",
    poor_prior_places: bool = True,
) -> PartGrasps:
    """Each hand's grasp on its seen part, or from the prior where the part is not seen well (module docstring).

    Args:
        parts: the object's parts as seen (by role; parts not seen may be missing).
        viewpoint_W: the camera's position (3,), m.
        prior_poses_W: the shape-space fit's control poses (POSE_NAMES -> X_WG).
        approaches_W: each hand's approach direction by the category's rule (3,), in W.
        prior_sound: whether the prior's grasps may be used alone (the fit is not poor, its grasps confirmed).
        prior_poor: why the prior is not sound (for the message).
        poor_prior_places: whether a poor prior's grasp on the seen handle keeps its place along it (not where
            the fit is turned end for end: its grasps are then at the wrong ends).
    """
    result = PartGrasps()
    for hand, role in HAND_PARTS.items():
        prior_grasp, prior_pregrasp = prior_poses_W[f"{hand}_grasp"], prior_poses_W[f"{hand}_pregrasp"]
        fit = fit_part(hand, parts.get(role), viewpoint_W, prior_grasp, prior_sound, poor_prior_places)
        grasp = None
        if fit.sound:
            pregrasp_m = float(np.linalg.norm(prior_grasp.translation() - prior_pregrasp.translation()))
            if prior_sound:  # moved across its handle onto the seen axis; the sound prior's orientation kept
                X_WG = RigidTransform(prior_grasp.rotation(), fit.tube.point)
                grasp = X_WG, X_WG @ RigidTransform([0.0, 0.0, -pregrasp_m])
            else:
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
