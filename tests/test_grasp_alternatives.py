"""Grasp alternatives: a grasp rolled about its handle or slid along it, and the reach that tries them where the
grasp as given is out of a hand's reach."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw

from diagrams.generation.objects.library import resolve_object
from diagrams.planning_scene import make_pick_motions, object_surface_W, true_grasp_poses
from diagrams.scenario import initial_positions, replace_object
from diagrams.station import object_pose_on_table
from systems.planning.grasp_alternatives import (
    GRASP_ROLLS,
    HANDLE_SLIDES,
    grasp_alternatives,
    handle_slides,
    pregrasp_alternatives,
)
from systems.planning.ik import IkResult
from systems.planning.pick_motions import PlanningError
from systems.planning.reach_motions import SCREENING_ITERATIONS, _FirstLookFailed

SIDES = ("left", "right")


def test_a_rolled_pre_grasp_pivots_about_the_handle_through_the_grasp():
    X_WG = RigidTransform(RollPitchYaw(0.3, -0.2, 1.0), [0.7, 0.1, 0.9])
    X_GP = RigidTransform([0.0, 0.0, -0.1])  # the pre-grasp 10 cm back along the approach axis
    X_WP = X_WG @ X_GP
    alternatives = pregrasp_alternatives(X_GP, grasp_alternatives(X_WG, None))  # no points: no slides
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
    rolls = {
        side: pregrasp_alternatives(
            poses[f"{side}_grasp"].inverse() @ pregrasps[side], grasp_alternatives(poses[f"{side}_grasp"], None)
        )
        for side in SIDES
    }
    reach = motions.reach(q0, pregrasps, alternatives=rolls)
    reached = motions.world.grasp_frame_poses(reach.keyframes[-1])
    for side in SIDES:  # each hand at the pre-grasp it chose (the grasp kept, the approach turned)
        chosen = pregrasps[side] @ rolls[side][reach.choice[side]]
        assert np.linalg.norm(reached[side].translation() - chosen.translation()) < 0.004  # IK: 2 mm a coordinate
    assert reach.choice["right"] > 0  # a rolled one


def _handle_and_housing(handle_end: float, housing: bool) -> np.ndarray:
    """Points (N x 3, in the grasp frame G) of a handle of radius 17 mm along x from -5 cm to handle_end, and, with
    `housing`, of a disc of radius 5 cm across its axis just past its end (where a drill's housing sits)."""
    rng = np.random.default_rng(0)
    x = rng.uniform(-0.05, handle_end, 3000)
    angle = rng.uniform(0, 2 * np.pi, 3000)
    points = [np.stack([x, 0.017 * np.cos(angle), 0.017 * np.sin(angle)], axis=1)]
    if housing:
        radius, angle = 0.05 * np.sqrt(rng.uniform(0, 1, 2000)), rng.uniform(0, 2 * np.pi, 2000)
        points.append(np.stack([np.full(2000, handle_end), radius * np.cos(angle), radius * np.sin(angle)], axis=1))
    return np.concatenate(points)


def test_a_grasp_slides_along_its_handle_only_as_far_as_the_fingers_stay_on_it():
    X_WG = RigidTransform(RollPitchYaw(0.3, -0.2, 1.0), [0.7, 0.1, 0.9])
    free = X_WG.multiply(_handle_and_housing(0.05, housing=False).T).T
    assert handle_slides(free, X_WG) == list(HANDLE_SLIDES)  # the fingers may overhang an end by 1 cm or less
    # A housing 5 cm up the handle: the fingers (6 cm wide) may slide 1.5 cm up, not 3.
    blocked = X_WG.multiply(_handle_and_housing(0.05, housing=True).T).T
    assert handle_slides(blocked, X_WG) == [0.015, -0.015, -0.03]
    short = X_WG.multiply(_handle_and_housing(0.025, housing=True).T).T  # 5 mm past the fingers at the grasp
    assert handle_slides(short, X_WG) == [-0.015, -0.03]
    assert handle_slides(np.zeros((0, 3)), X_WG) == []
    assert handle_slides(free + [0.0, 0.0, 1.0], X_WG) == []  # no handle at the grasp
    family = grasp_alternatives(X_WG, blocked)
    assert len(family) == 1 + len(GRASP_ROLLS) + 3
    np.testing.assert_allclose(family[-1].translation(), [-0.03, 0.0, 0.0])


def test_the_reach_looks_briefly_at_later_goals_before_giving_any_its_full_budget(scenario, monkeypatch):
    """The first goal STOMP plans to gets all its iterations; every later one a first look (SCREENING_ITERATIONS),
    and only then, in the same order, all of them: one goal STOMP cannot reach costs its budget once, not once per
    goal."""
    motions = make_pick_motions(scenario)
    q0 = initial_positions(scenario)
    goals = [IkResult(True, np.full_like(q0, k), choice={"left": k}) for k in range(4)]
    monkeypatch.setattr(motions.reaches, "_goal_specs", lambda *args: iter(range(len(goals))))
    monkeypatch.setattr(motions.reaches, "_goal", lambda q_start, targets_W, spec, accept=None: goals[spec])
    looks = []

    def reach_path(q_start, q_goal, obstacles, checked, max_iterations=None):
        goal = int(q_goal[0])
        looks.append((goal, max_iterations))
        if (goal, max_iterations) == (2, None):
            return np.stack([q_start, q_goal])
        raise (PlanningError if max_iterations is None else _FirstLookFailed)(f"no path to goal {goal}")

    monkeypatch.setattr(motions.reaches, "_reach_path", reach_path)
    reach = motions.reach(q0, {})
    screen = SCREENING_ITERATIONS
    assert looks == [(0, None), (1, screen), (2, screen), (3, screen), (1, None), (2, None)]
    assert reach.choice["left"] == 2
    goals[2] = IkResult(False, q0, "out of reach")  # now no goal has a path: the first goal's failure is named
    looks.clear()
    with pytest.raises(PlanningError, match="no path to goal"):
        motions.reach(q0, {})
    assert looks == [(0, None), (1, screen), (3, screen), (1, None), (3, None)]


def test_grasps_in_reach_but_not_a_centimetre_deeper_are_approached_to_the_grasps_themselves(scenario):
    """A drill at the edge of the arms' reach (tune table 8 of the clear's first object: training drill 0 at x -0.03
    m, y 0.03 m, yaw -0.23 rad): the right hand's approach reaches its grasp but not the perception margin's
    centimetre past it. The reach then approaches the grasps themselves: the X_GG' it returns take the centimetre
    back off, so that the approach the pick plays (to grasp @ X_GG' @ deeper) ends at a grasp of the family."""
    drill = replace_object(scenario, category="drill", instance="train_0", xy=[-0.0315, 0.0269], yaw=-0.232)
    motions = make_pick_motions(drill)
    poses = true_grasp_poses(drill)
    q0 = initial_positions(drill)
    pregrasps = {side: poses[f"{side}_pregrasp"] for side in SIDES}
    grasps = {side: poses[f"{side}_grasp"] for side in SIDES}
    model = resolve_object(drill.object)
    surface, _ = object_surface_W(model, object_pose_on_table(drill, model), 2000)  # (as the clear's tables check)
    deeper = RigidTransform([0.0, 0.0, 0.01])
    keyframes, chosen = motions.reach_pregrasps(q0, pregrasps, grasps, surface, surface, deeper=deeper)
    families = {side: grasp_alternatives(grasps[side], surface) for side in SIDES}
    for side in SIDES:
        X_GG = chosen[side] @ deeper  # where the approach ends, in the grasp's frame: a grasp of its family
        assert any(X_GG.IsNearlyEqualTo(member, 1e-9) for member in families[side])
    ends = {side: grasps[side] @ chosen[side] @ deeper for side in SIDES}
    motions.straight(keyframes[-1], ends)  # the approach the pick plays reaches them
    with pytest.raises(PlanningError, match="out of reach"):  # a centimetre deeper, it does not
        motions.straight(keyframes[-1], {side: X @ deeper for side, X in ends.items()})
