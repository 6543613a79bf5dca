"""The dual-arm IK (systems/planning/ik.py): batched Gauss-Newton per arm against SNOPT, judged in Drake's frames."""

import numpy as np
import pytest
from pydrake.math import RigidTransform

from diagrams.generation.planning_problems import make_problem
from diagrams.planning_scene import make_pick_motions, true_grasp_poses
from diagrams.scenario import initial_positions, replace_object
from systems.planning.ik import HALF_TURN, LAST_RESORT_MAJOR_ITERATIONS
from systems.planning.pick_motions import PlannerConfig
from systems.planning.world import SIDES

MARGIN = 0.1  # rad, as the reach asks for its goals first (REACH_LIMIT_MARGIN)


@pytest.fixture(scope="module")
def motions(scenario):
    return {batched: make_pick_motions(scenario, PlannerConfig(batched_ik=batched)) for batched in (True, False)}


def _reached(world, q, targets, position_tolerance=0.002, angle_tolerance=0.03) -> bool:
    """Whether Drake puts each grasp frame at its target (or its half turn) at q."""
    for side, X in world.grasp_frame_poses(q).items():
        for target in (targets[side], targets[side] @ HALF_TURN):
            if np.abs(X.translation() - target.translation()).max() <= position_tolerance + 1e-9 and (
                X.rotation().InvertAndCompose(target.rotation()).ToAngleAxis().angle() <= angle_tolerance + 1e-9
            ):
                break
        else:
            return False
    return True


@pytest.mark.parametrize(("category", "instance", "yaw"), [("watering_can", "test_1", 0.0), ("drill", "test_2", -0.25)])
def test_batched_ik_reaches_the_pregrasps_within_tolerance_limits_and_clearance(
    scenario, motions, category, instance, yaw
):
    """Where SNOPT reaches both pre-grasps, the batched IK does too: each grasp frame within 2 mm and 0.03 rad in
    Drake's kinematics, every joint MARGIN inside its limits, 5 mm clear in Drake's geometry."""
    placed = replace_object(scenario, category=category, instance=instance, yaw=yaw)
    poses = true_grasp_poses(placed)
    targets = {side: poses[f"{side}_pregrasp"] for side in SIDES}
    q0 = initial_positions(placed)
    assert motions[False].ik.solve(targets, q0, restarts=12, limit_margin=MARGIN).success
    result = motions[True].ik.solve(targets, q0, restarts=12, limit_margin=MARGIN)
    assert result.success, result.message
    world = motions[True].world
    assert _reached(world, result.q, targets)
    assert np.all(result.q >= world.lower + MARGIN - 1e-9) and np.all(result.q <= world.upper - MARGIN + 1e-9)
    assert world.clearance(result.q) >= 0.005


def test_batched_ik_names_a_hand_out_of_reach(scenario, motions):
    poses = true_grasp_poses(scenario)
    far = RigidTransform([1.5, 0.0, 0.0])
    targets = {"left": poses["left_pregrasp"], "right": far @ poses["right_pregrasp"]}
    result = motions[True].ik.solve(targets, initial_positions(scenario), restarts=4)
    assert not result.success and result.message == "right hand: target out of reach"


def test_the_last_resorts_cap_on_snopts_iterations_stops_a_solve_and_keeps_a_reachable_answer(scenario, motions):
    """SNOPT's last resort runs at most LAST_RESORT_MAJOR_ITERATIONS major iterations: one is not enough to reach a
    pre-grasp from the start, the cap gives the same answer as no cap."""
    ik = motions[True].ik
    target = {"left": true_grasp_poses(scenario)["left_pregrasp"]}
    q0 = initial_positions(scenario)

    def solved(major_iterations):
        return ik._solve_once(target, q0, q0, 0.002, 0.03, None, MARGIN, major_iterations=major_iterations)

    free = solved(None)
    assert free.success, free.message
    assert not solved(1).success
    capped = solved(LAST_RESORT_MAJOR_ITERATIONS)
    assert capped.success and np.array_equal(capped.q, free.q)


def test_the_planning_problems_are_drawn_with_snopt_ik_alone(motions):
    with pytest.raises(ValueError, match="drawn with SNOPT"):
        make_problem(motions[True], "reach", "tune", 0)


def test_an_accept_test_passes_over_the_answers_it_refuses_for_another_way(scenario, motions):
    """The IK's answers besides the nearest (each arm's elbow elsewhere) stand in for those `accept` refuses; where it
    refuses every one, the failure says so."""
    ik, world = motions[True].ik, motions[True].world
    poses = true_grasp_poses(scenario)
    targets = {side: poses[f"{side}_pregrasp"] for side in SIDES}
    q0 = initial_positions(scenario)
    nearest = ik.solve(targets, q0, restarts=12, limit_margin=MARGIN)
    assert nearest.success, nearest.message

    def elsewhere(q):  # the right arm not as in the nearest answer
        return bool(np.abs(q[7:14] - nearest.q[7:14]).max() > 0.1)

    other = ik.solve(targets, q0, restarts=12, limit_margin=MARGIN, accept=elsewhere)
    assert other.success, other.message
    assert elsewhere(other.q) and _reached(world, other.q, targets) and world.clearance(other.q) >= 0.005
    refused = ik.solve(targets, q0, restarts=12, limit_margin=MARGIN, accept=lambda q: False)
    assert not refused.success and "are refused" in refused.message


def test_a_reach_whose_nearest_goal_stands_in_the_scene_reaches_the_same_targets_another_way(
    scenario, motions, monkeypatch
):
    """Points where the nearest goal has its right elbow (an object the camera saw there, say one set down beside
    the next): the reach's goal is another of the IK's ways to the same targets, clear of them (report table 0 of the
    clear, 2026-12-07: the right forearm 21 mm into a can set down in the drop zone, and the drill never taken)."""
    pick = motions[True]
    world = pick.world
    poses = true_grasp_poses(scenario)
    targets = {side: poses[f"{side}_pregrasp"] for side in SIDES}
    q0 = initial_positions(scenario)
    nearest = pick.ik.solve(targets, q0, restarts=12, limit_margin=0.15)
    world.plant.SetPositions(world.plant_context, world.full_positions(nearest.q))
    elbow = world.plant.EvalBodyPoseInWorld(world.plant_context, world.plant.GetBodyByName("arm2_4")).translation()
    steps = np.linspace(-0.03, 0.03, 7)
    scene = elbow + np.array([[x, y, z] for x in steps for y in steps for z in steps])
    obstacles = world.planning_obstacles(None, scene)

    def clearance(q):
        return pick.stomp.clearance(q[None], obstacles, robot_pairs=False)[0]

    assert clearance(nearest.q) < 0.0
    planned_to = []  # every goal handed to the path planner
    reach_path = pick.reaches._reach_path

    def recorded(q_start, q_goal, *args, **kwargs):
        planned_to.append(q_goal)
        return reach_path(q_start, q_goal, *args, **kwargs)

    monkeypatch.setattr(pick.reaches, "_reach_path", recorded)
    reach = pick.reach(q0, targets, scene_W=scene)
    goal = reach.keyframes[-1]
    assert _reached(world, goal, targets, 0.003, 0.04)
    assert min(clearance(q) for q in planned_to) > 0.005  # none in the scene: the nearest passed over at once
