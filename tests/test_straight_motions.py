"""Straight motions (approach, retreat): each keyframe tracked from the one before, on its branch; a free move
that rises straight up first where it finds no path from its start."""

import numpy as np
import pytest
from pydrake.math import RigidTransform

from diagrams.planning_scene import grasp_configuration, make_pick_motions
from systems.planning.reach_motions import RISE_M, ReachMotions
from systems.planning.straight_motions import APPROACH_STEPS, PlanningError
from tests.test_stomp import FOREARM_IN_TORSO

SIDES = ("left", "right")


def test_tracking_reaches_nearby_targets_on_the_branch_and_declines_far_ones(scenario):
    motions = make_pick_motions(scenario)
    q = grasp_configuration(scenario, motions)
    start = motions.world.grasp_frame_poses(q)
    back = {side: X @ RigidTransform([0.0, 0.0, -0.04]) for side, X in start.items()}  # 4 cm back along z_G
    tracked = motions.track(q, back)
    assert tracked is not None
    assert np.abs(tracked - q).max() < 0.3  # a small move of every joint, no jump
    assert np.all(tracked >= motions.world.lower) and np.all(tracked <= motions.world.upper)
    reached = motions.world.grasp_frame_poses(tracked)
    for side in SIDES:
        assert np.abs(reached[side].translation() - back[side].translation()).max() < 0.001
        assert (reached[side].rotation().inverse() @ back[side].rotation()).IsNearlyIdentity(0.01)
    far = {side: RigidTransform([3.0, 0.0, 1.0]) for side in SIDES}  # 3 m away: out of every reach
    assert motions.track(q, far) is None


def test_a_straight_retreat_is_a_line_of_tracked_keyframes(scenario):
    motions = make_pick_motions(scenario)
    q = grasp_configuration(scenario, motions)
    start = motions.world.grasp_frame_poses(q)
    targets = {side: X @ RigidTransform([0.0, 0.0, -0.1]) for side, X in start.items()}
    keyframes = motions.straight(q, targets)
    assert len(keyframes) == 4 and np.abs(np.diff(keyframes, axis=0)).max() < 0.6
    for k, keyframe in enumerate(keyframes):
        reached = motions.world.grasp_frame_poses(keyframe)
        for side in SIDES:  # on the line, at its share of it, the orientation kept
            expected = start[side].translation() + k / 3 * (targets[side].translation() - start[side].translation())
            np.testing.assert_allclose(reached[side].translation(), expected, atol=0.002)
            assert (reached[side].rotation().inverse() @ start[side].rotation()).IsNearlyIdentity(0.03)


def test_a_back_off_beyond_reach_goes_as_far_as_the_arms_reach_along_its_line(scenario):
    """An approach is the whole line or nothing; a back-off (min_steps) ends where the arms stop reaching along it,
    on the line, and still fails where not even its first step can be reached."""
    motions = make_pick_motions(scenario)
    q = grasp_configuration(scenario, motions)
    start = motions.world.grasp_frame_poses(q)
    targets = {side: X @ RigidTransform([0.0, 0.0, -0.8]) for side, X in start.items()}  # 80 cm back: too far
    with pytest.raises(PlanningError, match="IK failed"):
        motions.straight(q, targets, steps=8)
    keyframes = motions.straight(q, targets, steps=8, min_steps=1)
    assert 2 <= len(keyframes) < 9
    for k, keyframe in enumerate(keyframes):
        reached = motions.world.grasp_frame_poses(keyframe)
        for side in SIDES:
            expected = start[side].translation() + k / 8 * (targets[side].translation() - start[side].translation())
            np.testing.assert_allclose(reached[side].translation(), expected, atol=0.002)
    with pytest.raises(PlanningError, match="step 1 of 1"):
        motions.straight(q, targets, steps=1, min_steps=1)


def test_a_straight_move_stops_where_the_arms_would_touch_the_robot(scenario):
    """Tracking keeps the hands on their lines, not the forearms off the torso: a straight move into contact by
    Drake's exact geometry fails (or, where a part of it may do, ends before the contact); leaving a contact the
    robot stands in is allowed."""
    motions = make_pick_motions(scenario)
    world = motions.world
    poses = world.grasp_frame_poses(FOREARM_IN_TORSO)
    moved = {side: RigidTransform([0.0, -0.05, 0.0]) @ X for side, X in poses.items()}
    out = motions.straight(FOREARM_IN_TORSO, moved)[-1]  # leaving the contact
    assert world.penetrations(FOREARM_IN_TORSO) and not world.penetrations(out)
    back_in = {side: RigidTransform([0.0, 0.01, 0.0]) @ X for side, X in poses.items()}  # 1 cm past where it stood
    with pytest.raises(PlanningError, match="step 2 of 3: the arms would touch the robot"):
        motions.straight(out, back_in)
    partial = motions.straight(out, back_in, min_steps=1)
    assert len(partial) == 2
    for q_from, q_to in zip(partial[:-1], partial[1:], strict=True):
        assert world.segment_is_free(q_from, q_to, max_step=0.005)


# The held-out compact drill's grasps at +0.25 rad (seed 3): its side handle and grip stand so close that the two
# hands' finger pads meet, 0.8 mm deep at the planning opening.
HANDS_MEET = np.array(
    [-1.210001, 0.653173, -1.649187, -1.403513, 0.769956, 1.220614, 0.290115, -0.105217, -0.074898, -0.265815,
     -0.224245, 0.042539, -1.199568, -0.057432, 0.195074]
)  # fmt: skip


def test_the_hands_meeting_at_close_handles_do_not_stop_the_approach(scenario):
    """The contacts a grasp makes (the two hands' fingers at close handles, a hand with the object) are the grasps'
    to judge, not the line's: the approach to them is not refused for them; the robot's other contacts still count."""
    motions = make_pick_motions(scenario)
    world = motions.world
    touching = world.penetrations(HANDS_MEET)
    assert len(touching) == 1 and 0.0005 < next(iter(touching.values())) < 0.0015
    assert world.in_collision(HANDS_MEET) and not world.in_collision(HANDS_MEET, grasp_contacts=False)
    grasps = world.grasp_frame_poses(HANDS_MEET)
    back = motions.straight(HANDS_MEET, {side: X @ RigidTransform([0.0, 0.0, -0.05]) for side, X in grasps.items()})
    approach = motions.straight(back[-1], grasps)
    reached = world.grasp_frame_poses(approach[-1])
    for side in SIDES:
        assert np.abs(reached[side].translation() - grasps[side].translation()).max() < 0.001
    assert not world.segment_is_free(approach[-2], approach[-1])  # counting every contact, the last step touches


def test_a_free_move_with_no_path_from_where_it_starts_rises_first(scenario, monkeypatch):
    """Home from beside the object: where no path leaves the start (made so here), both hands go straight up
    RISE_M and the path starts from there."""
    motions = make_pick_motions(scenario)
    q = grasp_configuration(scenario, motions)
    home = q.copy()
    home[:7] += 0.2  # somewhere else for the left arm
    original = ReachMotions._reach_path

    def no_path_from_the_grasp(self, q_from, q_to, obstacles, checked):
        if np.allclose(q_from, q):
            raise PlanningError("no path from here")
        return original(self, q_from, q_to, obstacles, checked)

    monkeypatch.setattr(ReachMotions, "_reach_path", no_path_from_the_grasp)
    keyframes = motions.reach_configuration(q, home)
    np.testing.assert_array_equal(keyframes[0], q)
    np.testing.assert_allclose(keyframes[-1], home)
    start = motions.world.grasp_frame_poses(q)
    risen = motions.world.grasp_frame_poses(keyframes[APPROACH_STEPS])  # the rise's last keyframe
    for side in SIDES:
        np.testing.assert_allclose(risen[side].translation(), start[side].translation() + [0, 0, RISE_M], atol=0.002)

    def no_path(*args):
        raise PlanningError("none")

    monkeypatch.setattr(ReachMotions, "_reach_path", no_path)
    with pytest.raises(PlanningError, match="none; from 0.15 m higher: none"):
        motions.reach_configuration(q, home)
