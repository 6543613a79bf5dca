"""Grasp alternatives: a grasp rolled about its handle, and the reach that tries them where the grasp as given
is out of a hand's reach."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw

from diagrams.planning_scene import make_pick_motions, true_grasp_poses
from diagrams.scenario import initial_positions, replace_object
from systems.planning.pick_motions import PlanningError
from systems.planning.stomp_planner import GRASP_ROLLS, grasp_rolls

SIDES = ("left", "right")


def test_a_rolled_pre_grasp_pivots_about_the_handle_through_the_grasp():
    X_WG = RigidTransform(RollPitchYaw(0.3, -0.2, 1.0), [0.7, 0.1, 0.9])
    X_GP = RigidTransform([0.0, 0.0, -0.1])  # the pre-grasp 10 cm back along the approach axis
    X_WP = X_WG @ X_GP
    alternatives = grasp_rolls(X_GP)
    assert len(alternatives) == 1 + len(GRASP_ROLLS)
    assert alternatives[0].IsExactlyIdentity()
    for A, angle in zip(alternatives[1:], GRASP_ROLLS, strict=True):
        X_WP_rolled = X_WP @ A
        # Still 10 cm from the grasp, on its own approach axis, which now meets the handle turned by `angle`.
        ahead = X_WP_rolled.multiply([0.0, 0.0, 0.1])
        np.testing.assert_allclose(ahead, X_WG.translation(), atol=1e-12)
        R_rel = (X_WG.rotation().inverse() @ X_WP_rolled.rotation()).matrix()
        np.testing.assert_allclose(R_rel[:, 0], [1, 0, 0], atol=1e-12)  # the handle axis kept
        assert np.arccos(np.clip(R_rel[2, 2], -1, 1)) == pytest.approx(abs(angle))


def test_the_reach_rolls_a_grasp_the_hand_cannot_reach_as_given(scenario):
    """An unseen drill at a random placement (extra_1005 of the workspace map: x -0.04 m, y 0.04 m, yaw 0.5
    rad): the right hand reaches its pre-grasp at no torso yaw as perceived; rolled about the handle, it does."""
    drill = replace_object(scenario, category="drill", instance="extra_1005", xy=[-0.04, 0.04], yaw=0.5)
    motions = make_pick_motions(drill)
    poses = true_grasp_poses(drill)
    pregrasps = {side: poses[f"{side}_pregrasp"] for side in SIDES}
    q0 = initial_positions(drill)
    with pytest.raises(PlanningError, match="right hand: target out of reach"):
        motions.reach(q0, pregrasps)
    rolls = {side: grasp_rolls(poses[f"{side}_grasp"].inverse() @ pregrasps[side]) for side in SIDES}
    keyframes = motions.reach(q0, pregrasps, alternatives=rolls)
    reached = motions.world.grasp_frame_poses(keyframes[-1])
    used = {}
    for side in SIDES:  # each hand at one of its pre-grasps (the grasp kept, the approach turned)
        candidates = [pregrasps[side] @ A for A in rolls[side]]
        gaps = [np.linalg.norm(reached[side].translation() - X.translation()) for X in candidates]
        assert min(gaps) < 0.004  # the IK holds each coordinate within 2 mm
        used[side] = int(np.argmin(gaps))
    assert used["right"] > 0  # a rolled one
