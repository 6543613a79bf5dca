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
