"""The ground-truth pick end to end: IK plan from the true pose, simulated with contact, judged on ground truth."""

import itertools

import numpy as np
import pytest

from diagrams.hand_ik import DualArmIk
from diagrams.objects.library import resolve_object
from diagrams.oracle_pick import MIN_LIFT_HEIGHT, PlanningError, plan_oracle_pick
from diagrams.pick_simulation import LIFT_SUCCESS_M, run_oracle_pick
from diagrams.scenario import replace_object
from diagrams.station import object_pose_on_table


@pytest.mark.parametrize(("category", "instance", "yaw"), [("watering_can", "test_2", 0.25), ("drill", "test_1", 0.0)])
def test_oracle_pick_lifts_object_with_both_hands(scenario, category, instance, yaw):
    outcome = run_oracle_pick(replace_object(scenario, category=category, instance=instance, yaw=yaw))
    assert outcome.success, outcome.message
    assert outcome.min_hold_height_m >= LIFT_SUCCESS_M
    assert outcome.hands_in_contact == ["left", "right"]


def test_oracle_plan_reach_is_collision_free_and_within_limits(scenario):
    model = resolve_object(scenario.object)
    X_WO = object_pose_on_table(scenario, model)
    ik = DualArmIk(scenario, obstacle=model, X_WO=X_WO)
    plan = plan_oracle_pick(ik, np.array(scenario.initial_arm_positions), X_WO, model.info)
    reach_keyframes = [q for t, q in zip(plan.times, plan.arm_q, strict=True) if t <= plan.phases["reach"]]
    for q_from, q_to in itertools.pairwise(reach_keyframes):
        assert ik.segment_is_free(q_from, q_to)
    trajectory = plan.arm_trajectory()
    samples = np.column_stack([trajectory.value(t) for t in np.linspace(0, plan.duration, 400)])
    assert np.all(samples.T >= ik.lower - 1e-9) and np.all(samples.T <= ik.upper + 1e-9)
    speeds = np.abs(np.column_stack([trajectory.EvalDerivative(t) for t in np.linspace(0, plan.duration, 400)]))
    assert np.all(speeds.T <= ik.velocity_limits)
    # Both hands rise together by at least MIN_LIFT_HEIGHT and keep their relative pose (closed chain).
    grasped = ik.grasp_frame_poses(plan.configuration_at("close"))
    lifted = ik.grasp_frame_poses(plan.configuration_at("lift"))
    for side in ("left", "right"):
        rise = lifted[side].translation() - grasped[side].translation()
        assert rise[2] >= MIN_LIFT_HEIGHT - 0.002 and np.linalg.norm(rise[:2]) < 0.005


def test_unreachable_object_is_a_planning_error(scenario):
    far = replace_object(scenario, xy=[1.5, 0.0])
    model = resolve_object(far.object)
    X_WO = object_pose_on_table(far, model)
    with pytest.raises(PlanningError, match="pre-grasp"):
        plan_oracle_pick(DualArmIk(far), np.array(far.initial_arm_positions), X_WO, model.info)
