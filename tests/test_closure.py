"""The closure cost (paper equations (2)-(4)) and STOMP lifting a held object with the closure on."""

import dataclasses

import numpy as np
import pytest
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.tree import BodyIndex

from diagrams.generation.objects.library import resolve_object
from diagrams.planning_scene import grasp_configuration, make_pick_motions, object_surface_W
from diagrams.scenario import replace_object
from diagrams.station import object_pose_on_table
from systems.planning.closure import (
    ClosureConstraint,
    OrientationConstraint,
    deviations,
    orientation_deviations,
    rotation_angle,
    rpy_of,
    threshold_cost,
    tilt_angle,
    transition_costs,
)
from systems.planning.hand_constraints import bounded_step
from systems.planning.held_motions import HELD_GOAL_EXACT_TOLERANCES, HELD_SPEED_M_S, HELD_TURN_SPEED_RAD_S
from systems.planning.pick_motions import time_parameterise
from systems.planning.stomp import Stomp
from systems.planning.stomp_checks import interpolate_segments


def test_threshold_cost_below_at_and_beyond_the_maximum():
    deviation = np.array([0.0, 0.005, 0.01, 0.02])
    np.testing.assert_allclose(threshold_cost(deviation, 0.01, 1000.0), [0.0, 0.5, 1000 + 10.0, 1000 + 20.0])


def test_transition_cost_is_half_the_worst_translation_plus_half_the_worst_orientation():
    constraint = ClosureConstraint(t_max=0.01, o_max=0.1, C_ct=100.0, C_co=100.0)
    t_dev = np.array([[0.002, 0.004, 0.001]])  # the states along one transition
    o_dev = np.array([[0.01, 0.05, 0.2]])  # the last state breaks o_max
    expected = 0.5 * 0.4 + 0.5 * (100 + 100 * 0.2)
    np.testing.assert_allclose(transition_costs(t_dev, o_dev, constraint), [expected])


def test_rpy_matches_drake():
    rng = np.random.default_rng(0)
    for rpy in rng.uniform([-3, -1.5, -3], [3, 1.5, 3], size=(20, 3)):
        R = RotationMatrix(RollPitchYaw(rpy)).matrix()
        np.testing.assert_allclose(rpy_of(R[None])[0], RollPitchYaw(RotationMatrix(R)).vector(), atol=1e-9)


def test_orientation_deviation_is_the_rotation_angle_even_near_pitch_90_degrees():
    R_desired = RotationMatrix(RollPitchYaw(0.3, 1.55, -0.2))  # near the roll/yaw singularity
    tilt = RotationMatrix(AngleAxis(0.01, [1.0, 0.0, 0.0]))  # about the world x axis
    angle = rotation_angle((tilt @ R_desired).matrix()[None], R_desired.matrix())[0]
    assert angle == pytest.approx(0.01, abs=1e-9)
    rpy = np.abs(rpy_of((tilt @ R_desired).matrix()[None])[0] - rpy_of(R_desired.matrix()[None])[0])
    assert rpy.max() > 0.1  # what roll/pitch/yaw differences would have said


@pytest.fixture(scope="module")
def lift_problem(scenario):
    scenario = replace_object(scenario, category="watering_can", instance="test_0", yaw=0.0)  # a fixed problem
    model = resolve_object(scenario.object)
    X_WO = object_pose_on_table(scenario, model)
    motions = make_pick_motions(scenario, obstacle=model, X_WO=X_WO)
    q_grasp = grasp_configuration(scenario, motions)
    # The lift's goal: both hands 0.12 m higher, holding the object as they do at q_grasp.
    X = motions.world.grasp_frame_poses(q_grasp)
    up = RigidTransform([0.0, 0.0, 0.12])
    lifted = motions.ik.solve_held(up @ X["left"], X["left"].InvertAndCompose(X["right"]), q_grasp, 0.002, 0.03)
    assert lifted.success, lifted.message
    return motions, q_grasp, lifted.q, scenario


def test_end_effector_relative_pose_matches_drake(lift_problem):
    motions, q_grasp, _, _ = lift_problem
    X = motions.world.grasp_frame_poses(q_grasp)
    expected = (X["left"].inverse() @ X["right"]).GetAsMatrix4()
    np.testing.assert_allclose(motions.world.end_effectors.relative(q_grasp[None])[0], expected, atol=1e-10)


def test_stomp_lifts_with_the_closure_kept_densely(lift_problem):
    motions, q_grasp, q_lift, scenario = lift_problem
    stomp = motions.stomp
    constraint = ClosureConstraint()
    X_desired = stomp.end_effectors.relative(q_grasp[None])[0]
    # The goal keeps the grasp's relative hand pose exactly (projected onto the closure manifold).
    goal = stomp.project(q_lift, X_desired, steps=18)[0]
    table = motions.world.table_obstacles()  # the object moves with the hands
    result = stomp.plan(q_grasp, goal, table, constraint)
    assert result.success, result.message
    check = stomp.checks.closure_within_limits(result.trajectory, (constraint, X_desired), steps=20)
    assert check.within and check.translation_m < constraint.t_max and check.orientation_rad < constraint.o_max
    # Drake's exact check against robot and table (the object moves with the hands, so it is left out).
    without_object = make_pick_motions(scenario)
    for q_from, q_to in zip(result.trajectory[:-1], result.trajectory[1:], strict=True):
        assert without_object.segment_is_free(q_from, q_to, max_step=0.01)


def test_stomp_bar_lift_keeps_closure_and_both_hand_orientations(lift_problem):
    motions, q_grasp, q_lift, _ = lift_problem
    stomp = motions.stomp
    X_desired = stomp.end_effectors.relative(q_grasp[None])[0]
    R_desired = [X[0, :3, :3] for X in stomp.end_effectors.poses(q_grasp[None])]
    goal = stomp.project(q_lift, X_desired, R_desired, steps=15)[0]
    table = motions.world.table_obstacles()
    closure, orientation = ClosureConstraint(), OrientationConstraint()
    result = stomp.plan(q_grasp, goal, table, closure, orientation)
    assert result.success, result.message
    within, worst = stomp.checks.orientation_within_limits(result.trajectory, (orientation, R_desired), steps=20)
    assert within and worst < orientation.o_max
    assert stomp.checks.closure_within_limits(result.trajectory, (closure, X_desired), steps=20).within
    # The hands really rise (the orientation is kept along a real motion).
    lift = stomp.end_effectors.poses(result.trajectory[[0, -1]])[0][:, 2, 3]
    assert lift[1] - lift[0] > 0.1


def test_the_closure_term_alone_keeps_the_closure_without_any_projection(lift_problem):
    """Projection off (no Gauss-Newton steps on rollouts, updates or the first trajectory): the same lift, same
    seed, with the closure term q_cc keeps the hands' relative pose densely; without it STOMP returns the straight
    joint-space line, which is collision-free but breaks the closure."""
    motions, q_grasp, _, _ = lift_problem
    X_desired = motions.stomp.end_effectors.relative(q_grasp[None])[0]
    # A higher lift than the fixture's (0.15 m): the straight joint-space line to it leaves the closure.
    X = motions.world.grasp_frame_poses(q_grasp)
    lifted = motions.ik.solve_held(
        RigidTransform([0, 0, 0.15]) @ X["left"], X["left"].InvertAndCompose(X["right"]), q_grasp, 0.002, 0.03
    )
    assert lifted.success, lifted.message
    goal = motions.stomp.project(lifted.q, X_desired, steps=18)[0]
    table = motions.world.table_obstacles()
    config = dataclasses.replace(
        motions.stomp.config,
        sampling=dataclasses.replace(
            motions.stomp.config.sampling, projection_steps=0, rollout_projection_steps=0, constrained_noise_std=0.15
        ),
        seed=1,
        time_limit_s=30,
    )
    stomp = Stomp(motions.world, config)
    with_term = stomp.plan(q_grasp, goal, table, ClosureConstraint())
    without_term = stomp.plan(q_grasp, goal, table)
    closure = (ClosureConstraint(), X_desired)
    assert with_term.success, with_term.message
    assert stomp.checks.closure_within_limits(with_term.trajectory, closure, steps=20).within
    assert without_term.success and without_term.iterations == 0  # the straight line
    check = stomp.checks.closure_within_limits(without_term.trajectory, closure, steps=20)
    assert not check.within, check


def test_tangent_noise_and_projection_respect_the_constraints(lift_problem):
    """Noise moved into the constraints' tangent space changes the closure only to second order; a few
    Gauss-Newton steps then bring a configuration back within a micrometre."""
    motions, q_grasp, q_lift, _ = lift_problem
    stomp = motions.stomp
    X_desired = stomp.end_effectors.relative(q_grasp[None])[0]
    constraints = stomp.constraints(X_desired)
    q = constraints.project(np.stack([q_grasp, q_lift]), 15)
    assert np.abs(constraints.error_and_jacobian(q)[0]).max() < 1e-6
    dof = len(q_grasp)  # the arms and the torso
    step = 0.01 * np.random.default_rng(0).standard_normal((1, 2, dof))
    raw = np.abs(constraints.error_and_jacobian(q + step[0])[0]).max()
    tangent = np.abs(constraints.error_and_jacobian(q + constraints.tangent(q, step)[0])[0]).max()
    assert tangent < 0.05 * raw, (tangent, raw)
    assert np.abs(constraints.error_and_jacobian(constraints.project(q + step[0], 3))[0]).max() < 1e-6
    # The analytic Jacobian against finite differences.
    error, jacobian = constraints.error_and_jacobian(q[:1])
    for j in range(dof):
        shifted = q[:1].copy()
        shifted[0, j] += 1e-6
        np.testing.assert_allclose(
            (constraints.error_and_jacobian(shifted)[0] - error)[0] / 1e-6, jacobian[0, :, j], atol=1e-4
        )


def test_held_move_is_played_within_the_closure_constraint_densely(lift_problem, scenario):
    """The pick's lift as the planner stage plans it: STOMP with q_cc, time-parameterised, checked every 10 ms."""
    _, q_grasp, _, _ = lift_problem
    motions = make_pick_motions(scenario)  # the held object moves with the hands: no object here
    held = motions.held_move(q_grasp, RigidTransform([0.0, 0.0, 0.15]), min_fraction=0.8)
    trajectory = time_parameterise(held.keyframes, motions.world.velocity_limits, 2.0, 0.25)
    t_dev, o_dev = motions.closure_deviations(trajectory, held)
    assert t_dev < motions.closure.t_max and o_dev < motions.closure.o_max
    start, end = (motions.world.grasp_frame_poses(trajectory.value(t).ravel()) for t in (2.0, trajectory.end_time()))
    for side in ("left", "right"):
        assert end[side].translation()[2] - start[side].translation()[2] > 0.11  # at least 0.8 of 0.15 m, about
    times = np.arange(trajectory.start_time(), trajectory.end_time(), 0.01)
    q = np.array([trajectory.value(t).ravel() for t in times])
    assert np.all(q >= motions.world.lower - 1e-9) and np.all(q <= motions.world.upper + 1e-9)


def test_a_held_move_with_an_exact_goal_ends_with_both_hands_on_their_moved_poses(lift_problem, scenario):
    """An aim's kind of held move (6 cm across, 8 cm up, 0.2 rad about the vertical): by default its path's goal holds
    the left hand within the path's tolerances of its moved pose (1 mm a side, 10 mrad), at their edge, and STOMP's
    plan ends both hands more than 1 mm off theirs (2026-12-07: the goal 1.7 mm and 10 mrad off, STOMP's end 2.2 and
    4.9 mm, 13 mrad). Asked for an exact goal, the path's goal is within HELD_GOAL_EXACT_TOLERANCES and STOMP's plan,
    its goal projected onto the closure, ends both hands within 1 mm and 3 mrad (0.4 and 0.5 mm, 1.8 mrad)."""
    _, q_grasp, _, _ = lift_problem
    motions = make_pick_motions(scenario)
    X_motion = RigidTransform(RotationMatrix.MakeZRotation(0.2), [0.0, -0.06, 0.08])
    start = motions.world.grasp_frame_poses(q_grasp)

    def off(q_end, side):
        """How far the hand is from its moved pose: (m, rad)."""
        X, target = motions.world.grasp_frame_poses(q_end)[side], X_motion @ start[side]
        turn = target.rotation().InvertAndCompose(X.rotation()).ToAngleAxis().angle()
        return np.linalg.norm(X.translation() - target.translation()), turn

    default = motions.held_path(q_grasp, X_motion, 1.0)
    assert off(default.configurations[-1], "left")[0] > 0.001  # (within 1 mm a side, not in norm)
    held = motions.held_move(q_grasp, X_motion)
    assert all(off(held.keyframes[-1], side)[0] > 0.001 for side in ("left", "right"))

    path = motions.held_path(q_grasp, X_motion, 1.0, exact_goal=True)
    held = motions.held_move(q_grasp, X_motion, exact_goal=True)
    position, angle = HELD_GOAL_EXACT_TOLERANCES
    assert path.reached == 1.0
    offset, turn = off(path.configurations[-1], "left")
    assert offset < np.sqrt(3) * position + 1e-6 and turn < angle + 1e-6
    for side in ("left", "right"):
        offset, turn = off(held.keyframes[-1], side)
        assert offset < 0.001 and turn < 0.003


# Both hands closed on one drill (unseen extra_1013 on the workspace map, as measured after the grasp): the
# fingers of the two hands overlap 1.4 mm in the sphere model, 0 in Drake's geometry.
HANDS_ON_ONE_DRILL = (
    [-1.204, 0.503, -1.58, -0.818, 0.889, 1.025, 0.027]  # left arm, rad
    + [-0.17, -0.236, -0.11, -0.355, 0.074, -0.939, -0.345]  # right arm
    + [-0.028]  # torso yaw
)


def test_a_held_move_does_not_count_the_gap_between_the_hands_the_grasp_made(scenario):
    """Under the closure constraint the hands keep their relative pose, so their spheres' gap cannot change."""
    motions = make_pick_motions(scenario)
    q = np.array(HANDS_ON_ONE_DRILL)
    scene, stomp = motions.world.table_obstacles(), motions.stomp
    assert not motions.world.in_collision(q)
    assert stomp.clearance(q, scene) < 0  # a free reach could not start here
    assert stomp.clearance(q, scene, held=True) > stomp.config.costs.required_clearance
    held = motions.held_move(q, RigidTransform([0.0, 0.0, 0.12]), min_fraction=0.8)
    rise = [motions.world.grasp_frame_poses(held.keyframes[-1])[side].translation()[2] for side in ("left", "right")]
    start = [motions.world.grasp_frame_poses(q)[side].translation()[2] for side in ("left", "right")]
    assert np.min(np.subtract(rise, start)) > 0.8 * 0.12
    # The pairs left out are exactly those between the bodies that move with one hand (the hand, its fingers, the
    # last arm link) and those that move with the other.
    plant, kinematics, spheres = motions.world.plant, motions.world.kinematics, motions.world.spheres

    def hand_of(sphere: int) -> str:
        body = plant.get_body(BodyIndex(kinematics.links[spheres.body[sphere]].body_index))
        owner = plant.GetModelInstanceName(body.model_instance())
        return {"left_hand": "left", "right_hand": "right"}.get(owner) or {"arm1_7": "left", "arm2_7": "right"}.get(
            body.name(), ""
        )

    for a, b, left_out in zip(stomp.costs.pair_a, stomp.costs.pair_b, stomp.costs.hand_to_hand, strict=True):
        assert left_out == ({hand_of(a), hand_of(b)} == {"left", "right"})
    assert stomp.costs.hand_to_hand.sum() == 529  # 4 bodies move with each hand: hand base, 2 fingers, last arm link


def test_tilt_angle_ignores_turns_about_the_vertical_only():
    R0 = RollPitchYaw(0.3, -0.2, 0.5).ToRotationMatrix()
    turned = RotationMatrix.MakeZRotation(0.7) @ R0
    tipped = RotationMatrix.MakeXRotation(0.1) @ R0
    angles = tilt_angle(np.stack([turned.matrix(), tipped.matrix()]), R0.matrix())
    np.testing.assert_allclose(angles, [0.0, 0.1], atol=1e-9)
    assert rotation_angle(turned.matrix()[None], R0.matrix())[0] == pytest.approx(0.7)


def test_carry_that_turns_the_object_keeps_the_hands_upright_and_slow(lift_problem, scenario):
    """A held move 15 cm sideways, turning the object 0.3 rad about the vertical: the hands turn with it but do
    not tip (the upright-only orientation constraint), and the played trajectory moves them no faster than
    the held-object speeds."""
    _, _, q_lift, _ = lift_problem
    motions = make_pick_motions(scenario)
    X_WG = motions.world.grasp_frame_poses(q_lift)["left"]
    turn = RotationMatrix.MakeZRotation(0.3)
    about_hand = RigidTransform(X_WG.translation()) @ RigidTransform(turn) @ RigidTransform(-X_WG.translation())
    held = motions.held_move(q_lift, RigidTransform([0.0, -0.15, 0.0]) @ about_hand)
    durations = motions.held_segment_durations(held.keyframes)
    trajectory = time_parameterise(held.keyframes, motions.world.velocity_limits, 0.0, durations)
    q = np.array([trajectory.value(t).ravel() for t in np.arange(0.0, trajectory.end_time(), 0.01)])
    end_effectors = motions.world.end_effectors
    R_start = [X[0, :3, :3] for X in end_effectors.poses(q[:1])]
    assert orientation_deviations(end_effectors, q, R_start, upright_only=True).max() < motions.orientation.o_max
    turned = rotation_angle(end_effectors.poses(q[-1:])[0][:, :3, :3], R_start[0])[0]
    assert turned == pytest.approx(0.3, abs=0.05)
    t_dev, o_dev = motions.closure_deviations(trajectory, held)
    assert t_dev < motions.closure.t_max and o_dev < motions.closure.o_max
    for X in end_effectors.poses(q):  # as played, every 10 ms (0.074 and 0.083 m/s at most when written)
        assert np.linalg.norm(np.diff(X[:, :3, 3], axis=0), axis=1).max() / 0.01 <= HELD_SPEED_M_S
    assert trajectory.end_time() >= max(0.15 / HELD_SPEED_M_S, 0.3 / HELD_TURN_SPEED_RAD_S)


# A can held at 10 cm above where it stood (tune table 8 of the clear, 2026-12-07; the hands' pose as the lift left
# them), and the carry to its spot in the drop zone: 5 cm forward, 23 cm to the robot's left of W's origin after a
# turn of -1.03 rad about W's vertical (the zone lies on the robot's right).
CAN_HELD_FOR_THE_ZONE = [0.4615, 1.388, 0.5198, -2.0144, 1.7623, 1.1694, 1.0015,
                         0.2863, -0.0263, 0.4618, -2.2111, 0.1463, 1.1218, -0.0437, 0.0551]  # fmt: skip
CARRY_TO_THE_ZONE = RigidTransform(RotationMatrix.MakeZRotation(-1.0271), [0.0507, 0.2267, 0.0])


def test_a_held_move_whose_path_ends_with_an_elbow_in_the_pelvis_ends_on_another_branch(scenario):
    """The held path, solved along the carry from the start, keeps the right arm on its branch and ends with its
    forearm (arm2_5) in the pelvis: STOMP refuses that goal. The held move's goal is solved again, clear of the
    robot itself, holding the object where the path's goal holds it."""
    motions = make_pick_motions(scenario)
    q0 = np.array(CAN_HELD_FOR_THE_ZONE)
    path = motions.held_path(q0, CARRY_TO_THE_ZONE, 1.0)
    assert motions.world.in_collision(path.configurations[-1])  # the path's own goal
    held = motions.held_move(q0, CARRY_TO_THE_ZONE, 1.0)
    goal = held.keyframes[-1]
    assert not motions.world.in_collision(goal)
    path_end, held_end = (motions.world.grasp_frame_poses(q) for q in (path.configurations[-1], goal))
    # The left hand where the path's goal has it (within the held path's 1 mm and 0.04 rad, from its projection onto
    # the closure), the right one where the grasps hold it from the left.
    assert np.linalg.norm(held_end["left"].translation() - path_end["left"].translation()) < 0.003
    assert (held_end["left"].rotation().inverse() @ path_end["left"].rotation()).ToAngleAxis().angle() < 0.045
    t_dev, o_dev = deviations(motions.world.end_effectors, goal[None], held.X_E1E2)
    assert t_dev.max() < 0.001 and o_dev.max() < 0.01


def test_a_bounded_step_holds_a_joint_at_its_limit_where_clipping_stalls():
    """e = q0 + q1 - 1 from q = 0 with q0 at most 0.2: the plain step (0.5, 0.5) clipped leaves e = -0.3; the
    bounded step holds q0 at its limit and moves q1 alone, reaching e = 0 at once."""
    q = np.zeros((1, 2))
    jacobian = np.ones((1, 1, 2))
    lower, upper = np.zeros(2), np.array([0.2, 1.0])
    moved = bounded_step(q, np.array([[-1.0]]), jacobian, lower, upper)
    np.testing.assert_allclose(moved, [[0.2, 0.8]], atol=1e-5)
    capped = bounded_step(q, np.array([[-1.0]]), jacobian, lower, upper, max_step=0.1)
    np.testing.assert_allclose(capped, [[0.1, 0.1]], atol=1e-6)


def test_moved_raises_the_held_object_as_far_as_the_constraints_allow(lift_problem):
    """HandConstraints.moved: both hands 5 cm higher, the closure and their orientation kept (from the grasp; from
    the lift a joint at its limit stops the hands 4.2 cm up)."""
    motions, q_grasp, _, _ = lift_problem
    stomp = motions.stomp
    X_desired = stomp.end_effectors.relative(q_grasp[None])[0]
    R_WE = [X[0, :3, :3] for X in stomp.end_effectors.poses(q_grasp[None])]
    constraints = stomp.constraints(X_desired, R_WE)
    start = constraints.project(q_grasp[None], 15)
    moved = constraints.moved(start, np.array([[0.0, 0.0, 0.05]]))
    assert np.abs(constraints.error_and_jacobian(moved)[0]).max() < 1e-4
    rise = [X[0, :3, 3] - X0[0, :3, 3] for X, X0 in zip(*map(stomp.end_effectors.poses, (moved, start)), strict=True)]
    for side in rise:
        np.testing.assert_allclose(side, [0.0, 0.0, 0.05], atol=0.005)


def test_a_carry_over_a_box_starts_from_a_detour_clear_of_it(scenario):
    """The benchmark's carry on a training can: the can held 10 cm up is moved 40 cm across the table with a 16 cm
    box midway. The projected straight line puts the can into the box; STOMP's first trajectory is a detour clear
    of it (up or across), and the plan keeps the can clear of the box and the closure densely."""
    box = dataclasses.replace(scenario.obstacle, present=True, xy=[-0.12, 0.0], size=[0.16, 0.03, 0.16])
    scenario = replace_object(scenario, category="watering_can", instance="train_1", yaw=0.0)
    scenario = dataclasses.replace(
        scenario, obstacle=box, object=dataclasses.replace(scenario.object, xy=[-0.12, 0.20])
    )
    model = resolve_object(scenario.object)
    X_WO = object_pose_on_table(scenario, model)
    q_grasp = grasp_configuration(scenario, make_pick_motions(scenario, obstacle=model, X_WO=X_WO))
    motions = make_pick_motions(scenario)
    stomp = motions.stomp
    q_start = motions.held_path(q_grasp, RigidTransform([0, 0, 0.10]), 1.0).configurations[-1]
    points = object_surface_W(model, RigidTransform([0, 0, 0.10]) @ X_WO, 500)[0]
    scene = motions.world.table_obstacles().carrying(motions.carried(q_start, points))
    X_desired = stomp.end_effectors.relative(q_start[None])[0]
    q_across = motions.held_path(q_start, RigidTransform([0, -0.40, 0]), 1.0).configurations[-1]
    q_goal = stomp.project(q_across, X_desired, steps=15)[0]
    straight = np.linspace(q_start, q_goal, stomp.config.keyframes)
    closure = (ClosureConstraint(), X_desired)
    orientation = (OrientationConstraint(), [X[0, :3, :3] for X in stomp.end_effectors.poses(q_start[None])])
    constraints = stomp.constraints(X_desired, orientation[1])
    straight[1:-1] = constraints.project(straight[1:-1], 3)
    assert stomp.clearance(straight, scene).min() < -0.01  # the can goes through the box
    first_only = Stomp(motions.world, dataclasses.replace(stomp.config, max_iterations=0))
    first = first_only.plan(
        q_start, q_goal, scene, ClosureConstraint(), OrientationConstraint(), payload=motions.payload(q_start)
    )
    assert first.success and first.iterations == 0, first.message  # the first trajectory: a detour, a solution
    assert stomp.clearance(first.trajectory, scene).min() > stomp.config.costs.required_clearance
    result = stomp.plan(q_start, q_goal, scene, ClosureConstraint(), OrientationConstraint())
    assert result.success, result.message
    states = interpolate_segments(result.trajectory, 20)
    assert stomp.clearance(states, scene).min() > 0.0
    check = stomp.checks.closure_within_limits(result.trajectory, closure, steps=20)
    assert check.within, check


def test_keyframes_off_the_closure_are_brought_back_onto_it_for_playing(lift_problem, scenario):
    """STOMP's threshold cost leaves keyframes anywhere within t_max of the closure; onto_closure projects the interior
    ones (the ends stay) and, with midpoints, halves every segment first."""
    _, q_grasp, _, _ = lift_problem
    motions = make_pick_motions(scenario)
    held = motions.held_move(q_grasp, RigidTransform([0.0, 0.0, 0.15]), min_fraction=0.8)
    rng = np.random.default_rng(3)
    keyframes = held.keyframes.copy()
    keyframes[1:-1] += 0.01 * rng.standard_normal(keyframes[1:-1].shape)  # about 1 cm off the closure
    before = deviations(motions.world.end_effectors, keyframes, held.X_E1E2)[0]
    assert before[1:-1].max() > 0.005
    projected = motions.onto_closure(keyframes, held)
    np.testing.assert_array_equal(projected[[0, -1]], keyframes[[0, -1]])
    assert deviations(motions.world.end_effectors, projected, held.X_E1E2)[0].max() < 1e-4
    halved = motions.onto_closure(keyframes, held, midpoints=True)
    assert len(halved) == 2 * len(keyframes) - 1
    assert deviations(motions.world.end_effectors, halved, held.X_E1E2)[0].max() < 1e-4
    assert np.all(halved >= motions.world.lower - 1e-9) and np.all(halved <= motions.world.upper + 1e-9)
