"""Straight motions (approach, retreat): each keyframe tracked from the one before, on its branch."""

import numpy as np
from pydrake.math import RigidTransform

from diagrams.planning_scene import grasp_configuration, make_pick_motions

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
