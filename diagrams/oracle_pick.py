"""The ground-truth ("oracle") pick: true object pose + true grasp frames -> IK -> joint plan.

It proves the robot, the hands, the objects and contact before perception and
planning exist. The plan is a list of joint-space keyframes played by Drake's
TrajectorySource through the station's position ports:

  start -> [STOMP keyframes] -> pre-grasp -> grasp (straight approach) -> close hands -> lift -> hold

The IK model holds the object as an obstacle, so the reach to the pre-grasp is
checked for collisions; when the straight joint-space move would hit the object or
the table, STOMP plans around them.
"""

import logging

import numpy as np
from pydrake.math import RigidTransform

from diagrams.hand_ik import SIDES, DualArmIk
from diagrams.objects.instance import ObjectInfo
from systems.joint_plan import JointPlan, move_duration

# Shortest duration of one move between keyframes, seconds.
MIN_SEGMENT_S = 0.8
OPEN_WIDTH = 0.1  # m
CLOSED_WIDTH = 0.0  # m: the fingers stop on the handle; the joint effort limit sets the squeeze
CLOSE_S = 1.0
LIFT_HEIGHT = 0.15  # m: aimed for
MIN_LIFT_HEIGHT = 0.12  # m: lifting stops early, but not below this, where the arms run out of reach
LIFT_STEPS = 6
# Orientation tolerances of the hands during the lift, tried in turn, rad.
LIFT_ANGLE_TOLERANCES = (0.08, 0.15)
APPROACH_STEPS = 3
HOLD_S = 2.5


class PlanningError(RuntimeError):
    """No plan: names the phase that failed and why."""


def world_grasps(X_WO: RigidTransform, info: ObjectInfo, kind: str) -> dict[str, RigidTransform]:
    """X_WG of each hand's `kind` ("pregrasp" or "grasp") for an object at X_WO."""
    return {side: X_WO @ getattr(info.grasps[side], kind).GetDeterministicValue() for side in SIDES}


def plan_oracle_pick(ik: DualArmIk, q_start: np.ndarray, X_WO: RigidTransform, info: ObjectInfo) -> JointPlan:
    """Plans the pick from the true object pose.

    Raises:
        PlanningError: naming the phase whose IK failed.
    """
    plan = JointPlan()
    plan.append(q_start, OPEN_WIDTH, 0.0)
    plan.append(q_start, OPEN_WIDTH, 0.5)  # let the object settle
    pregrasp = ik.solve(world_grasps(X_WO, info, "pregrasp"), q_start, restarts=12)
    if not pregrasp.success:
        raise PlanningError(f"pre-grasp: no collision-free IK solution ({pregrasp.message})")
    for q in _reach_path(ik, q_start, pregrasp.q):
        plan.append(q, OPEN_WIDTH, move_duration(plan.arm_q[-1], q, ik.velocity_limits, MIN_SEGMENT_S))
    plan.phases["reach"] = plan.duration

    # Straight approach along each hand's z axis, keeping the solution branch.
    q = pregrasp.q
    start_poses = ik.grasp_frame_poses(q)
    goal_poses = world_grasps(X_WO, info, "grasp")
    for step in range(1, APPROACH_STEPS + 1):
        s = step / APPROACH_STEPS
        targets = {
            side: RigidTransform(
                start_poses[side].rotation(),
                (1 - s) * start_poses[side].translation() + s * goal_poses[side].translation(),
            )
            for side in SIDES
        }
        result = ik.solve(targets, q, min_distance=None, allow_half_turn=False, restarts=0)
        if not result.success:
            raise PlanningError(f"approach step {step}: IK failed ({result.message})")
        plan.append(result.q, OPEN_WIDTH, move_duration(q, result.q, ik.velocity_limits, MIN_SEGMENT_S))
        q = result.q
    plan.phases["approach"] = plan.duration
    plan.append(q, CLOSED_WIDTH, CLOSE_S)
    plan.append(q, CLOSED_WIDTH, 0.5)
    plan.phases["close"] = plan.duration

    # Lift both hands together: the hands keep their relative pose (closed chain).
    grasp_poses = ik.grasp_frame_poses(q)
    lifted = 0.0
    for height in np.linspace(0.0, LIFT_HEIGHT, LIFT_STEPS + 1)[1:]:
        up = RigidTransform([0.0, 0.0, height])
        targets = {side: up @ grasp_poses[side] for side in SIDES}
        # Where the hands cannot keep their orientation (the arms near the edge of their reach), let them tilt more.
        for tolerance in LIFT_ANGLE_TOLERANCES:
            result = ik.solve(
                targets, q, angle_tolerance=tolerance, min_distance=None, allow_half_turn=False, restarts=12
            )
            if result.success:
                break
        if not result.success:
            if lifted >= MIN_LIFT_HEIGHT:
                break
            raise PlanningError(f"lift to {height:.3f} m: IK failed ({result.message})")
        plan.append(result.q, CLOSED_WIDTH, move_duration(q, result.q, ik.velocity_limits, MIN_SEGMENT_S))
        q, lifted = result.q, height
    plan.phases["lift"] = plan.duration
    plan.append(q, CLOSED_WIDTH, HOLD_S)
    plan.phases["hold"] = plan.duration
    logging.info("oracle plan: %.1f s, phases %s", plan.duration, plan.phases)
    return plan


def _reach_path(ik: DualArmIk, q_start: np.ndarray, q_pregrasp: np.ndarray) -> list[np.ndarray]:
    """Keyframes after q_start that end at q_pregrasp along collision-free joint-space segments.

    The straight move if it is free; otherwise a STOMP trajectory, shortened to as few
    keyframes as Drake's own collision checks allow.

    Raises:
        PlanningError: STOMP found no collision-free trajectory.
    """
    if ik.segment_is_free(q_start, q_pregrasp):
        return [q_pregrasp]
    result = ik.stomp.plan(q_start, q_pregrasp, ik.planning_obstacles)
    if not result.success:
        raise PlanningError(f"reach: {result.message}")
    logging.info("reach: STOMP, %d iterations, %.2f s", result.iterations, result.seconds)
    keyframes = shortcut(ik, list(result.trajectory))
    if keyframes is None:
        raise PlanningError("reach: the STOMP trajectory collides under Drake's exact check")
    return keyframes[1:]


def shortcut(ik: DualArmIk, keyframes: list[np.ndarray]) -> list[np.ndarray] | None:
    """Greedily drops keyframes while each remaining segment is collision-free (None if some segment is not)."""
    kept, i = [keyframes[0]], 0
    while i < len(keyframes) - 1:
        j = next((j for j in range(len(keyframes) - 1, i, -1) if ik.segment_is_free(keyframes[i], keyframes[j])), None)
        if j is None:
            return None
        kept.append(keyframes[j])
        i = j
    return kept
