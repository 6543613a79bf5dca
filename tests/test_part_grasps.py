"""Grasps built on the seen handles (part_grasps.py): where along the handle, the frame, and the rules between the
seen part and the shape-space prior. Synthetic handles seen from one side with depth noise."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix

from systems.messages import PartRole, SeenPart
from systems.shape_space.part_grasps import (
    FINGER_HALF_SPAN,
    OFF_HANDLE_M,
    grasps_on_seen_parts,
    prior_off_seen_handle,
    turned_end_for_end,
)

VIEWPOINT = np.array([-0.6, 0.0, 1.4])
LEFT, RIGHT = PartRole.LEFT_HANDLE, PartRole.RIGHT_HANDLE
DOWN = np.array([0.0, 0.0, -1.0])
FORWARD = np.array([1.0, 0.0, 0.0])


def seen_tube(rng, start, end, radius=0.012, noise=0.0015, count=2500):
    """The camera-facing half of a straight tube from `start` to `end` (m, W), with depth noise."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    axis = (end - start) / np.linalg.norm(end - start)
    u = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    t, angle = rng.uniform(0, 1, count), rng.uniform(0, 2 * np.pi, count)
    normal = np.outer(np.cos(angle), u) + np.outer(np.sin(angle), v)
    points = start + np.outer(t, end - start) + radius * normal
    points = points[np.einsum("ij,ij->i", normal, VIEWPOINT - points) > 0]
    sight = (VIEWPOINT - points) / np.linalg.norm(VIEWPOINT - points, axis=1, keepdims=True)
    return points + sight * rng.normal(0.0, noise, len(points))[:, None]


def pose(origin, x, z) -> RigidTransform:
    x, z = np.asarray(x, float), np.asarray(z, float)
    return RigidTransform(RotationMatrix(np.column_stack([x, np.cross(z, x), z])), np.asarray(origin, float))


def prior_poses(left_origin, right_origin):
    """A shape prior's control poses: the left hand from above along x_W, the right from behind along z_W."""
    left, right = pose(left_origin, [1, 0, 0], DOWN), pose(right_origin, [0, 0, 1], FORWARD)
    back = RigidTransform([0.0, 0.0, -0.1])
    return {"left_grasp": left, "left_pregrasp": left @ back, "right_grasp": right, "right_pregrasp": right @ back}


# A can at the origin of W: a top handle ACROSS its body (along y) at 0.35 m, a rear handle (vertical) behind it.
TOP = ((0.0, -0.06, 0.35), (0.0, 0.06, 0.35))
REAR = ((-0.18, 0.0, 0.08), (-0.18, 0.0, 0.2))
APPROACHES = {"left": DOWN, "right": FORWARD}


def seen_can(rng, top=TOP, rear=REAR, cut_rear=False):
    return {LEFT: SeenPart(seen_tube(rng, *top)), RIGHT: SeenPart(seen_tube(rng, *rear), cut_off=cut_rear)}


def test_a_top_handle_across_the_body_is_taken_in_its_middle_from_above_closing_across_it():
    rng = np.random.default_rng(1)
    # The prior (a shape whose top handle runs along the body) is poor and 4 cm off the handle's middle.
    prior = prior_poses([0.04, 0.0, 0.33], [-0.17, 0.0, 0.13])
    grasps = grasps_on_seen_parts(seen_can(rng), VIEWPOINT, prior, APPROACHES, prior_sound=False, prior_poor="poor")
    assert grasps.found and grasps.sources == {"left": "seen part", "right": "seen part"}
    X_WG = grasps.poses_W["left_grasp"]
    assert np.linalg.norm(X_WG.translation() - [0.0, 0.0, 0.35]) < 0.01  # on the axis, in its middle
    R = X_WG.rotation().matrix()
    assert abs(R[:, 0] @ [0.0, 1.0, 0.0]) > np.cos(np.radians(5))  # x_G along the handle
    assert R[:, 2] @ DOWN > np.cos(np.radians(5))  # from above
    assert abs(R[:, 1] @ [1.0, 0.0, 0.0]) > np.cos(np.radians(5))  # the fingers close across the tube
    pregrasp = grasps.poses_W["left_pregrasp"].translation()
    assert np.allclose(pregrasp, X_WG.translation() - 0.1 * R[:, 2], atol=1e-9)
    # The poor prior's right grasp lies 1 cm beside the rear handle's axis: on it, so its place along it is kept.
    assert np.linalg.norm(grasps.poses_W["right_grasp"].translation() - [-0.18, 0.0, 0.13]) < 0.006


def test_a_poor_prior_on_the_seen_handle_keeps_its_place_along_it_and_one_beside_it_gives_way_to_the_middle():
    rng = np.random.default_rng(5)
    # Poor, 3 cm along the top handle from its middle and 1 cm beside its axis: the fit is right about this handle.
    prior = prior_poses([0.0, 0.03, 0.36], [-0.18, 0.0, 0.12])
    grasps = grasps_on_seen_parts(seen_can(rng), VIEWPOINT, prior, APPROACHES, prior_sound=False, prior_poor="poor")
    X_WG = grasps.poses_W["left_grasp"]
    assert np.linalg.norm(X_WG.translation() - [0.0, 0.03, 0.35]) < 0.006
    assert X_WG.rotation().col(2) @ DOWN > np.cos(np.radians(5))  # the frame built on the tube, from above
    # 2.5 cm beside the axis it is not on the handle: the middle decides.
    prior = prior_poses([0.0, 0.03, 0.375], [-0.18, 0.0, 0.12])
    grasps = grasps_on_seen_parts(seen_can(rng), VIEWPOINT, prior, APPROACHES, prior_sound=False, prior_poor="poor")
    assert np.linalg.norm(grasps.poses_W["left_grasp"].translation() - [0.0, 0.0, 0.35]) < 0.01
    # Nor where the fit is turned end for end (its grasps lie at the wrong ends).
    prior = prior_poses([0.0, 0.03, 0.36], [-0.18, 0.0, 0.12])
    grasps = grasps_on_seen_parts(
        seen_can(rng), VIEWPOINT, prior, APPROACHES, prior_sound=False, prior_poor="turned", poor_prior_places=False
    )
    assert np.linalg.norm(grasps.poses_W["left_grasp"].translation() - [0.0, 0.0, 0.35]) < 0.01


@pytest.mark.parametrize("sliver_points", [250, 2500])
def test_a_poor_prior_on_a_sliver_beside_the_handle_gives_way_to_the_middle(sliver_points):
    rng = np.random.default_rng(7)
    # The rear handle's part also holds a piece 7 cm beside the grip (pixels given its role at the body's edge), and
    # the poor prior's grasp lies on that piece. Seen far more sparsely than the grip, it is a sliver: the grip's
    # middle decides; seen as densely, it may be the handle, and the prior's place on it is kept.
    beside = ((-0.18, 0.07, 0.08), (-0.18, 0.07, 0.2))
    parts = seen_can(rng)
    parts[RIGHT] = SeenPart(np.vstack([parts[RIGHT].points_W, seen_tube(rng, *beside, count=sliver_points)]))
    prior = prior_poses([0.0, 0.0, 0.35], [-0.18, 0.07, 0.12])
    grasps = grasps_on_seen_parts(parts, VIEWPOINT, prior, APPROACHES, prior_sound=False, prior_poor="poor")
    right = grasps.poses_W["right_grasp"].translation()
    expected = [-0.18, 0.0, 0.14] if sliver_points < 1000 else [-0.18, 0.07, 0.12]
    assert np.linalg.norm(right - expected) < 0.01


def test_a_sound_prior_on_the_seen_handle_keeps_its_place_along_it_and_moves_onto_its_axis():
    rng = np.random.default_rng(2)
    # Sound: 2 cm along the top handle from its middle, 8 mm beside its axis.
    prior = prior_poses([0.0, 0.02, 0.358], [-0.18, 0.0, 0.12])
    grasps = grasps_on_seen_parts(seen_can(rng), VIEWPOINT, prior, APPROACHES, prior_sound=True)
    assert np.linalg.norm(grasps.poses_W["left_grasp"].translation() - [0.0, 0.02, 0.35]) < 0.005
    # A sound prior 4 cm across the seen handle is not on it: the handle's middle decides.
    prior = prior_poses([0.0, 0.02, 0.39], [-0.18, 0.0, 0.12])
    grasps = grasps_on_seen_parts(seen_can(rng), VIEWPOINT, prior, APPROACHES, prior_sound=True)
    assert np.linalg.norm(grasps.poses_W["left_grasp"].translation() - [0.0, 0.0, 0.35]) < 0.01


def test_a_handle_the_image_cut_keeps_the_prior_place_moved_into_the_seen_stretch():
    rng = np.random.default_rng(3)
    # Only the rear handle's upper 7 cm is in the image; the prior grasp lies below what was seen.
    seen = seen_can(rng, rear=((-0.18, 0.0, 0.13), (-0.18, 0.0, 0.2)), cut_rear=True)
    prior = prior_poses([0.0, 0.0, 0.35], [-0.17, 0.0, 0.10])
    grasps = grasps_on_seen_parts(seen, VIEWPOINT, prior, APPROACHES, prior_sound=False, prior_poor="poor")
    assert grasps.fits["right"].cut_off and grasps.sources["right"] == "seen part"
    origin = grasps.poses_W["right_grasp"].translation()
    assert abs(origin[0] + 0.18) < 0.006 and abs(origin[1]) < 0.006  # on the seen axis
    assert 0.13 + FINGER_HALF_SPAN - 0.005 < origin[2] < 0.17  # the fingers' span on the seen stretch


def test_a_sound_prior_where_its_handle_was_not_seen_stands_as_it_is():
    rng = np.random.default_rng(5)
    # Only the rear handle's upper 7 cm is seen (its foot hidden); the sound prior grasps it 6 cm below that.
    seen = seen_can(rng, rear=((-0.18, 0.0, 0.13), (-0.18, 0.0, 0.2)))
    prior = prior_poses([0.0, 0.0, 0.35], [-0.18, 0.0, 0.07])
    grasps = grasps_on_seen_parts(seen, VIEWPOINT, prior, APPROACHES, prior_sound=True)
    assert grasps.sources == {"left": "seen part", "right": "shape prior"}
    assert "not seen" in grasps.fits["right"].reason
    assert grasps.poses_W["right_grasp"].IsExactlyEqualTo(prior["right_grasp"])


def test_an_unseen_handle_takes_the_prior_only_where_the_prior_is_sound():
    rng = np.random.default_rng(4)
    seen = {LEFT: SeenPart(seen_tube(rng, *TOP))}  # the rear handle not seen
    prior = prior_poses([0.0, 0.0, 0.35], [-0.18, 0.0, 0.14])
    sound = grasps_on_seen_parts(seen, VIEWPOINT, prior, APPROACHES, prior_sound=True)
    assert sound.found and sound.sources == {"left": "seen part", "right": "shape prior"}
    assert sound.poses_W["right_grasp"].IsExactlyEqualTo(prior["right_grasp"])
    poor = grasps_on_seen_parts(seen, VIEWPOINT, prior, APPROACHES, prior_sound=False, prior_poor="a poor fit: 60%")
    assert not poor.found and "right hand's handle is not seen well" in poor.poor and "a poor fit: 60%" in poor.poor


@pytest.mark.parametrize("points", [0, 20])
def test_too_few_points_of_a_part_are_not_seen_well(points):
    rng = np.random.default_rng(5)
    seen = seen_can(rng)
    seen[RIGHT] = SeenPart(seen[RIGHT].points_W[:points])
    grasps = grasps_on_seen_parts(seen, VIEWPOINT, prior_poses(TOP[0], REAR[0]), APPROACHES, prior_sound=False)
    assert not grasps.found and f"{points} points seen" in grasps.poor


def test_an_approach_along_the_seen_handle_does_not_use_it():
    rng = np.random.default_rng(6)
    prior = prior_poses([0.0, 0.0, 0.35], [-0.18, 0.0, 0.14])
    along_rear = {"left": DOWN, "right": np.array([0.0, 0.0, 1.0])}  # up the vertical rear handle
    grasps = grasps_on_seen_parts(seen_can(rng), VIEWPOINT, prior, along_rear, prior_sound=False)
    assert not grasps.found and "approach runs along" in grasps.poor


def test_a_fit_turned_end_for_end_is_told_by_the_seen_spout_and_rear_handle():
    rng = np.random.default_rng(6)
    spout = seen_tube(rng, (0.15, 0.0, 0.15), (0.25, 0.0, 0.3))
    seen = seen_can(rng) | {PartRole.TOOL: SeenPart(spout)}
    body = np.concatenate([seen_tube(rng, (0.0, 0.0, 0.0), (0.0, 0.0, 0.3), radius=0.1), spout])
    prior_right = np.array([-0.18, 0.0, 0.14])  # the fit's own rear grasp, behind the centre as it should be
    assert not turned_end_for_end(seen, body, np.array([1.0, 0.0, 0.0]), prior_right)
    assert turned_end_for_end(seen, body, np.array([-1.0, 0.0, 0.0]), -prior_right * [1, 1, -1])  # x_O backwards
    assert not turned_end_for_end({}, body, np.array([-1.0, 0.0, 0.0]), prior_right)  # no part seen: no word


def test_a_sound_prior_whose_grasp_lies_off_a_handle_seen_well_is_doubted_by_name():
    rng = np.random.default_rng(7)
    seen = seen_can(rng)
    # Both grasps on their handles (the rear one 5 cm below its seen stretch, as a handle hidden by the body leaves
    # it): no doubt.
    assert prior_off_seen_handle(seen, VIEWPOINT, prior_poses([0.0, 0.02, 0.35], [-0.18, 0.0, 0.03])) == ""
    # The right grasp on the far side of the body (a wrong fit): named.
    off = prior_off_seen_handle(seen, VIEWPOINT, prior_poses([0.0, 0.02, 0.35], [0.16, 0.0, 0.12]))
    assert off.startswith("the fit's right grasp lies") and "from its handle as seen" in off
    # The same grasp beside a rear handle cut off by the image's border, or seen in too few points: no doubt.
    far = prior_poses([0.0, 0.02, 0.35], [-0.18 + OFF_HANDLE_M + 0.1, 0.0, 0.12])
    assert prior_off_seen_handle(seen_can(rng, cut_rear=True), VIEWPOINT, far) == ""
    few = {LEFT: seen[LEFT], RIGHT: SeenPart(seen[RIGHT].points_W[:20])}
    assert prior_off_seen_handle(few, VIEWPOINT, far) == ""


def test_the_registrar_doubts_a_sound_fit_its_seen_handles_contradict_and_only_with_part_grasps():
    from types import SimpleNamespace

    from systems.messages import ObjectEstimate
    from systems.perception.shape_registrar import fit_doubt

    rng = np.random.default_rng(8)
    estimate = ObjectEstimate(True, "watering_can", viewpoint_W=VIEWPOINT, parts=seen_can(rng))
    wrong = SimpleNamespace(poor_fit="", grasp_poses_W=prior_poses([0.0, 0.02, 0.35], [0.16, 0.0, 0.12]))
    assert fit_doubt(estimate, wrong).startswith("the fit's right grasp lies")
    assert fit_doubt(estimate, wrong, part_grasps=False) == ""
    poor = SimpleNamespace(poor_fit="a poor fit: 60%", grasp_poses_W=wrong.grasp_poses_W)
    assert fit_doubt(estimate, poor) == "a poor fit: 60%"
