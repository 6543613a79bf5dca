"""STOMP reaching around the table and the object, checked with Drake's exact collision queries."""

import dataclasses
import re

import numpy as np
import pytest
from scipy.spatial import cKDTree

from diagrams.generation.objects.library import resolve_object
from diagrams.planning_scene import make_pick_motions, make_planning_world, object_surface_W, true_grasp_poses
from diagrams.scenario import initial_positions
from diagrams.station import object_pose_on_table
from systems.planning import reach_motions
from systems.planning.closure import ClosureConstraint
from systems.planning.dynamics import Payload, joint_torques
from systems.planning.ik import DualArmIk
from systems.planning.obstacles import DistanceField, Obstacles
from systems.planning.sphere_model import SphereGroup
from systems.planning.stomp import Stomp
from systems.planning.stomp_costs import TERMS, StompProblem
from systems.planning.world import TOLERATED_DEEPENING_M

# Both hands start under the table top, at its front edge: the straight move collides.
BELOW_TABLE = np.array([0, 0.15, 0, -0.1, 0, 0, 0, 0, -0.15, 0, -0.1, 0, 0, 0.0, 0.0])  # the torso straight


@pytest.fixture(scope="module")
def planning(scenario):
    model = resolve_object(scenario.object)
    X_WO = object_pose_on_table(scenario, model)
    motions = make_pick_motions(scenario, obstacle=model, X_WO=X_WO)
    poses = true_grasp_poses(scenario)
    pregrasp = motions.ik.solve({s: poses[f"{s}_pregrasp"] for s in ("left", "right")}, initial_positions(scenario))
    assert pregrasp.success
    return motions, pregrasp.q


def test_box_distance_matches_hand_computed_values():
    obstacles = Obstacles().add_box(np.eye(4), [2.0, 2.0, 2.0])  # the cube [-1, 1]^3
    points = np.array([[0, 0, 2.0], [2, 2, 0], [0, 0, 0.5], [0, 0, 0]])
    np.testing.assert_allclose(obstacles.distance(points, cap=10), [1.0, np.sqrt(2), -0.5, -1.0])
    assert obstacles.distance(np.array([[0, 0, 9.0]]), cap=0.3)[0] == pytest.approx(0.3)


def test_stomp_reaches_from_under_the_table_without_collision(planning):
    motions, q_goal = planning
    world = motions.world
    assert not motions.segment_is_free(BELOW_TABLE, q_goal)
    result = motions.stomp.plan(BELOW_TABLE, q_goal, world.planning_obstacles())
    assert result.success, result.message
    trajectory = result.trajectory
    np.testing.assert_allclose(trajectory[0], BELOW_TABLE)
    np.testing.assert_allclose(trajectory[-1], q_goal)
    assert np.all(trajectory >= world.lower - 1e-9) and np.all(trajectory <= world.upper + 1e-9)
    for q_from, q_to in zip(trajectory[:-1], trajectory[1:], strict=True):
        assert motions.segment_is_free(q_from, q_to, max_step=0.01)  # Drake's exact geometry, densely


def test_stomp_rejects_bad_goals_and_keeps_its_time_limit(planning):
    motions, q_goal = planning
    world = motions.world
    scene = world.planning_obstacles()
    outside = motions.stomp.plan(BELOW_TABLE, world.upper + 0.1, scene)
    assert not outside.success and "joint limits" in outside.message
    colliding = _colliding_configuration(world)
    in_collision = motions.stomp.plan(BELOW_TABLE, colliding, scene)
    # The message names the deepest contact (two of the robot's bodies, or one in the scene) and how deep it is.
    pattern = r"the goal configuration collides \((.+) (and|in) (.+), ([\d.]+) mm deep\)"
    said = re.fullmatch(pattern, in_collision.message)
    kinematics = motions.stomp.costs.kinematics
    bodies = {kinematics.body_name(position) for position in range(len(kinematics.links))}  # ("right_hand finger_2")
    assert said and said[1] in bodies and said[3] in bodies | {"the scene"}, in_collision.message
    assert float(said[4]) >= 1000 * -in_collision.min_clearance_m - 1  # (the deepest of what the plan's check found)
    # A goal nearer an obstacle than any plan keeps (2 mm of the required 5): no plan can end there; said at once.
    costs = motions.stomp.costs
    centres = costs.spheres.centres_W(costs.kinematics.body_poses(q_goal[None]))[0]
    top = int(np.argmax(centres[:, 2] + costs.spheres.radius))  # (nothing else of the robot reaches as high)
    above = centres[top] + [0.0, 0.0, costs.spheres.radius[top] + 0.002]
    too_near = motions.stomp.plan(BELOW_TABLE, q_goal, world.planning_obstacles().add_points(above[None]))
    assert not too_near.success and too_near.iterations == 0 and 0.0 < too_near.min_clearance_m <= 0.005
    assert "the goal configuration is" in too_near.message and "mm from an obstacle" in too_near.message

    config = motions.stomp.config
    config = dataclasses.replace(
        config,
        time_limit_s=0.05,
        max_iterations=100_000,
        sampling=dataclasses.replace(config.sampling, noise_std=1e-4),
        first_trajectories=dataclasses.replace(config.first_trajectories, via_candidates=0),
        restarts=dataclasses.replace(config.restarts, after=10**9),
    )
    # Almost no exploration from the colliding straight line (no via points): the time limit ends the search.
    timed_out = Stomp(world, config).plan(BELOW_TABLE, q_goal, scene)
    assert not timed_out.success and "no collision-free trajectory" in timed_out.message
    assert timed_out.seconds < 0.5


# Free by Drake's geometry, but the right upper arm's spheres overlap the torso's by 18 mm (found by seeded sampling
# about where the robot stood after a reach at a held-out can, the torso turned): the robot can stand there.
OVERLAPPING_SPHERES = np.array(
    [1.605, 1.368, 1.542, -1.391, -0.742, -1.519, 0.148, 0.119, -0.024, 0.971, -2.469, 0.595, 1.256, -0.371, -0.173]
)


def test_a_plan_starts_and_ends_where_drakes_geometry_is_free_though_the_robots_own_spheres_overlap_there(
    planning, scenario
):
    """Where the sphere model is coarser than the robot (its own spheres overlapping at a configuration Drake's
    geometry finds free), a plan from there, or to there (an IK goal), is not refused: those pairs may come as near
    as they are at that end, no nearer; the plan is free by Drake's geometry, and so is each of its segments as the
    reach checks them (the sphere model against the scene alone)."""
    motions, _ = planning
    world, stomp = motions.world, motions.stomp
    scene = world.planning_obstacles()
    home = initial_positions(scenario)
    assert not world.in_collision(OVERLAPPING_SPHERES) and world.beyond_limits(OVERLAPPING_SPHERES) <= 0
    assert stomp.clearance(OVERLAPPING_SPHERES[None], scene)[0] < -0.01
    for q_start, q_goal in ((OVERLAPPING_SPHERES, home), (home, OVERLAPPING_SPHERES)):
        result = stomp.plan(q_start, q_goal, scene)
        assert result.success, result.message
        trajectory = result.trajectory
        dense = np.concatenate([np.linspace(a, b, 20) for a, b in zip(trajectory[:-1], trajectory[1:], strict=True)])
        standing = stomp.costs.standing_ends(OVERLAPPING_SPHERES[None], scene)
        assert stomp.clearance(dense, standing).min() > 0  # no pair nearer than at the overlapping end
        for q_from, q_to in zip(trajectory[:-1], trajectory[1:], strict=True):
            assert motions.segment_is_free(q_from, q_to, scene, max_step=0.01)
    assert stomp.costs.standing_ends(home[None], scene) is scene  # clear ends: the scene itself
    colliding = _colliding_configuration(world)  # its own spheres overlap: allowed, were Drake's geometry free there
    assert stomp.costs.standing_ends(colliding[None], scene) is not scene
    assert stomp.standing_at_ends(home, colliding, scene) is scene


# Where a straight approach that ended short left the robot, backed off its pre-grasps at a held-out can at -0.25 rad:
# its right forearm 5.6 mm into the torso by Drake's geometry. The robot stands there: the next reach starts there.
FOREARM_IN_TORSO = np.array(
    [1.589638, 1.554991, 1.613615, -1.328366, -0.83018, -1.524596, 0.240361, 0.358376, -0.014, 0.846261, -2.479,
     0.566324, 1.453097, -0.300393, -0.386722]
)  # fmt: skip


def test_a_move_leaves_a_start_where_the_robot_touches_itself_no_deeper_than_it_stands(planning, scenario):
    """A start in contact by Drake's exact geometry (where the robot stands) does not make every path from it
    collide: the pairs in contact there may stay so, no deeper, as the move leaves; any other contact still counts."""
    motions, _ = planning
    world = motions.world
    standing = world.penetrations(FOREARM_IN_TORSO)
    assert len(standing) == 1 and 0.005 < next(iter(standing.values())) < 0.006
    home = initial_positions(scenario)
    keyframes = motions.reach_configuration(FOREARM_IN_TORSO, home)
    np.testing.assert_allclose(keyframes[-1], home)
    for q_from, q_to in zip(keyframes[:-1], keyframes[1:], strict=True):
        for q in np.linspace(q_from, q_to, 30):
            deeper = {pair: depth for pair, depth in world.penetrations(q).items() if depth > standing.get(pair, 0.0)}
            assert not deeper or max(deeper.values()) <= TOLERATED_DEEPENING_M, deeper
    assert not world.in_collision(home, standing)
    assert world.in_collision(_colliding_configuration(world), standing)  # another contact still counts


def _colliding_configuration(world) -> np.ndarray:
    """A configuration in collision under Drake's exact check (found by seeded sampling)."""
    rng = np.random.default_rng(0)
    for _ in range(2000):
        q = rng.uniform(world.lower, world.upper)
        if world.in_collision(q):
            return q
    raise AssertionError("no colliding sample found")


def test_the_least_clear_share_of_each_transition_is_where_the_dense_check_finds_it(planning):
    """What a held move's collision cost watches after its restart: per transition, the share of the way of the
    least clear of the states the dense check looks at (from under the table: some of them collide)."""
    motions, q_goal = planning
    stomp, obstacles = motions.stomp, motions.world.planning_obstacles()
    theta = np.linspace(BELOW_TABLE, q_goal, 16)
    shares = stomp.checks.least_clear_along(theta, obstacles)
    assert shares.shape == (15,) and np.all((shares > 0) & (shares < 1))
    for k, share in enumerate(shares):
        steps = max(4, int(np.ceil(np.abs(theta[k + 1] - theta[k]).max() / stomp.config.costs.segment_step_rad)))
        along = np.arange(1, steps) / steps
        clearance = stomp.clearance((1 - along)[:, None] * theta[k] + along[:, None] * theta[k + 1], obstacles, True)
        assert share == pytest.approx(along[np.argmin(clearance)])
    # A held move's cost then also counts each transition's collision there, at the keyframe it leads to.
    closure = (ClosureConstraint(), stomp.end_effectors.relative(theta[:1])[0])
    held = StompProblem(obstacles, closure)
    plain = stomp.costs.cost_terms(theta[None], held)[0, :, TERMS.index("collision")]
    watched = stomp.costs.cost_terms(theta[None], held, watched=shares)[0, :, TERMS.index("collision")]
    between = (1 - shares)[:, None] * theta[:-1] + shares[:, None] * theta[1:]
    shortfall = stomp.costs.clearances(between, obstacles, held=True)[1]
    assert shortfall.sum() > 0 and watched[0] == plain[0]
    np.testing.assert_allclose(watched[1:] - plain[1:], shortfall, rtol=1e-9, atol=1e-12)


def test_cost_terms_match_hand_computation(planning):
    motions, q_goal = planning
    world, stomp = motions.world, motions.stomp
    trajectory = np.linspace(BELOW_TABLE, q_goal, stomp.config.keyframes)[None]
    free_space = Obstacles()
    terms = stomp.costs.cost_terms(trajectory, StompProblem(free_space))[0]
    np.testing.assert_allclose(terms[:, TERMS.index("collision")], stomp.costs.clearances(trajectory, free_space)[1][0])
    # q_l: zero a limit margin inside the limits, growing to 1 per joint at a limit.
    to_limit = np.minimum(trajectory[0] - world.lower, world.upper - trajectory[0])
    expected = (np.clip(1 - to_limit / stomp.config.costs.limit_margin, 0, None) ** 2).sum(axis=1)
    np.testing.assert_allclose(terms[:, TERMS.index("limits")], expected)
    at_limit = stomp.costs.cost_terms(np.repeat(world.upper[None, None], 3, axis=1), StompProblem(free_space))
    at_limit = at_limit[0, :, TERMS.index("limits")]
    np.testing.assert_allclose(at_limit, len(world.upper))  # 1 per planned joint (15: the arms and the torso)
    # Torques: inverse dynamics along the keyframes' timing, each step at least segment_s (at rest at both ends).
    steps = np.diff(trajectory[0], axis=0)
    seconds = np.maximum(stomp.config.costs.segment_s, (np.abs(steps) / world.velocity_limits).max(axis=1))
    velocity = np.zeros_like(trajectory[0])
    velocity[1:-1] = 0.5 * (steps[:-1] / seconds[:-1, None] + steps[1:] / seconds[1:, None])
    acceleration = np.zeros_like(velocity)
    acceleration[1:] = np.diff(velocity, axis=0) / seconds[:, None]
    poses = stomp.costs.kinematics.body_poses(trajectory[0])
    load = np.abs(joint_torques(stomp.costs.kinematics, poses, velocity, acceleration)) / world.effort_limits
    expected = (load**2).sum(axis=1) + stomp.config.costs.torque_limit_penalty * np.maximum(load - 1, 0).sum(axis=1)
    np.testing.assert_allclose(terms[:, TERMS.index("torque")], expected, rtol=1e-9)
    np.testing.assert_allclose(terms[1:, TERMS.index("duration")], (np.abs(steps) / world.velocity_limits).max(axis=1))
    assert terms[0, TERMS.index("duration")] == 0
    assert not terms[:, [TERMS.index("closure"), TERMS.index("orientation")]].any()  # no hand constraint asked


def test_batched_sphere_centres_and_the_broad_phase_agree_with_one_sphere_at_a_time(planning):
    """A batch's sphere centres are each body's pose times the sphere's centre, every sphere pair within the
    margin in some configuration of the batch passes the broad phase, and the scene's broad phase (bodies'
    bounding spheres) leaves every clearance below the margin exact."""
    motions, q_goal = planning
    stomp = motions.stomp
    rng = np.random.default_rng(4)
    q = np.clip(q_goal + 0.8 * rng.standard_normal((24, stomp.dof)), stomp.lower, stomp.upper)
    poses = stomp.costs.kinematics.body_poses(q)
    spheres = stomp.costs.spheres
    centres = spheres.centres_W(poses)
    X_WB = poses[:, spheres.body]  # B x S x 4 x 4: each sphere's body
    expected = np.einsum("bsij,sj->bsi", X_WB[..., :3, :3], spheres.centre_B) + X_WB[..., :3, 3]
    np.testing.assert_allclose(centres, expected, atol=1e-12)
    gaps = np.linalg.norm(centres[:, stomp.costs.pair_a] - centres[:, stomp.costs.pair_b], axis=2) - (
        spheres.radius[stomp.costs.pair_a] + spheres.radius[stomp.costs.pair_b]
    )
    within = np.nonzero((gaps < stomp.config.costs.margin).any(axis=0))[0]
    assert len(within) > 0
    assert set(within) <= set(stomp.costs.near_sphere_pairs(stomp.costs.body_bounds(poses)))
    # Against a box among the arms: every sphere's clearance to it exact below the margin, the shortfall as if each
    # sphere were placed alone.
    X_WB = np.eye(4)
    X_WB[:3, 3] = centres[:, spheres.group == SphereGroup.LEFT].mean(axis=(0, 1))
    scene = Obstacles().add_box(X_WB, [0.3, 0.3, 0.3])
    to_box = scene.distance(centres) - spheres.radius
    all_gaps = np.concatenate([to_box, np.where(gaps < stomp.config.costs.margin, gaps, np.inf)], axis=1)
    smallest, shortfall = stomp.costs.clearances(q, scene, poses)
    assert (to_box < 0).any() and (to_box > stomp.config.costs.margin).any()
    np.testing.assert_allclose(shortfall, np.maximum(stomp.config.costs.margin - all_gaps, 0).sum(axis=1), rtol=1e-5)
    exact = all_gaps.min(axis=1)
    np.testing.assert_allclose(
        smallest[exact < stomp.config.costs.margin], exact[exact < stomp.config.costs.margin], atol=1e-6
    )
    assert np.all(smallest[exact >= stomp.config.costs.margin] >= stomp.config.costs.margin - 1e-9)


def test_a_held_payload_loads_the_arms_as_its_weight_would(planning):
    """Two point masses in the hands cost the arms the torque of their weight through the hands' Jacobians."""
    motions, q_goal = planning
    kinematics, end_effectors = motions.world.kinematics, motions.world.end_effectors
    q = q_goal[None]
    poses = kinematics.body_poses(q)
    still = np.zeros_like(q)
    (X1, X2), (J1, J2) = end_effectors.jacobians(q)
    payload = Payload(np.array(end_effectors.positions), np.stack([X[:3, 3] for X in end_effectors.X_BE]), np.ones(2))
    added = joint_torques(kinematics, poses, still, still, payload) - joint_torques(kinematics, poses, still, still)
    weight = -kinematics.gravity  # what each 1 kg hand must hold up, N
    np.testing.assert_allclose(added[0], J1[0, 3:].T @ weight + J2[0, 3:].T @ weight, atol=1e-9)


def test_point_set_distance_field_matches_exact_distances():
    rng = np.random.default_rng(2)
    sphere = rng.normal(size=(4000, 3))
    sphere = 0.1 * sphere / np.linalg.norm(sphere, axis=1, keepdims=True)  # a 0.1 m sphere's surface
    queries = np.array([[0.15, 0.0, 0.0], [0.0, 0.0, 0.2], [0.05, 0.05, 0.0], [2.0, 0.0, 0.0]])
    exact = np.abs(np.linalg.norm(queries, axis=1) - 0.1)  # up to the samples' spacing
    distances = Obstacles().add_points(sphere, inflation=0.002).distance(queries, cap=0.3)
    np.testing.assert_allclose(distances[:3], exact[:3] - 0.002, atol=0.006)
    assert distances[3] == pytest.approx(0.3)  # far outside the grid: the cap


def test_a_point_set_field_holds_exact_distances_where_clearances_are_judged():
    """At its nodes within NEAR of the points (the largest arm sphere plus STOMP's margin), the exact distance;
    farther, the distance transform's, within half a cell's diagonal of it."""
    rng = np.random.default_rng(3)
    points = rng.uniform([-0.1, -0.05, 0.0], [0.1, 0.05, 0.25], size=(2000, 3))
    field_ = DistanceField(points)
    nodes = field_.lower + field_.cell * np.stack(np.indices(field_.values.shape), axis=-1).reshape(-1, 3)
    exact = cKDTree(points).query(nodes)[0]
    values = field_.values.ravel()
    near = exact < DistanceField.NEAR
    assert near.sum() > 10000 and (~near).sum() > 10000
    np.testing.assert_array_equal(values[near], exact[near])
    np.testing.assert_allclose(values[~near], exact[~near], atol=0.5 * np.sqrt(3) * field_.cell)


def test_the_scene_field_is_exact_near_the_seen_points_and_only_approximate_far_from_them():
    """A face the camera saw (points 5 mm apart on the plane x = 0.503, off the 1 cm grid) is where it was seen:
    within a millimetre near it (no cube's half-side beyond it), within a grid cell far from it."""
    grid = np.arange(-0.1, 0.1, 0.005)
    y, z = np.meshgrid(grid, grid)
    face = np.stack([np.full(y.size, 0.503), y.ravel(), z.ravel()], axis=-1)
    scene = Obstacles().add_scene(face, cell=0.01, inflation=0.005)
    near = np.array([[0.523, 0.0, 0.0], [0.533, 0.0213, -0.0187], [0.478, 0.05, 0.05]])
    np.testing.assert_allclose(scene.distance(near), [0.015, 0.025, 0.020], atol=0.001)
    far = np.array([[0.603, 0.0, 0.0], [0.503, 0.0, 0.2]])
    np.testing.assert_allclose(scene.distance(far), [0.095, 0.095], atol=0.01)


def test_planning_model_places_every_body_where_drakes_collision_model_does(scenario):
    # A fresh world: its kinematics was read from the context at the default positions.
    world = make_planning_world(scenario)
    q = np.random.default_rng(4).uniform(world.lower, world.upper)
    poses = world.kinematics.body_poses(q)[0]
    world.plant.SetPositions(world.plant_context, world.full_positions(q))
    for link, X in zip(world.kinematics.links, poses, strict=True):
        X_drake = world.plant.EvalBodyPoseInWorld(world.plant_context, world.plant.get_body(link.body_index))
        np.testing.assert_allclose(X, X_drake.GetAsMatrix4(), atol=1e-9)


def test_a_cold_cache_leaves_the_planner_as_a_warm_one(scenario, tmp_path, monkeypatch):
    """Building the IK seed table (cold cache) and loading it (warm) leave the planner's context alike: a
    pick's outcome cannot depend on whether the machine ran one before (left at the table's last sample, a
    cold one lifted its can 1.3e-12 m lower and Ray's records differed from one process's)."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    cold = DualArmIk(make_planning_world(scenario))
    warm = DualArmIk(make_planning_world(scenario))
    assert list((tmp_path / "dualarm" / "ik_seeds").iterdir())  # the second one loaded what the first built
    np.testing.assert_array_equal(cold.world.plant.GetPositions(cold.world.plant_context), warm.world.q_default)
    np.testing.assert_array_equal(cold.world.q_default, warm.world.q_default)


def test_obstacles_are_arguments_not_state(planning):
    """The world's scene is fixed: each reach's obstacles are built for it, and changing them changes no world."""
    motions, _ = planning
    world = motions.world
    boxes = len(world.table_boxes)
    seen = world.planning_obstacles(np.zeros((10, 3)))
    seen.add_box(np.eye(4), [1.0, 1.0, 1.0])
    assert len(seen.fields) == 2  # the points as seen and the welded object's surface
    assert len(world.table_obstacles().boxes) == boxes
    assert len(world.planning_obstacles().fields) == 1  # the welded object's surface alone
    with pytest.raises(dataclasses.FrozenInstanceError):
        motions.stomp.config.seed = 1  # a planner's settings are given when it is built


def test_a_reach_whose_scene_is_built_beside_its_first_ik_goal_is_the_reach_built_one_after_the_other(
    scenario, monkeypatch
):
    """The reach builds the sphere model's scene (the object as seen) beside its first IK goal: the same keyframes,
    to the bit, as with the two one after the other (from under the table: a path STOMP plans)."""
    model = resolve_object(scenario.object)
    points, _ = object_surface_W(model, object_pose_on_table(scenario, model), 2000)
    poses = true_grasp_poses(scenario)
    pregrasps = {side: poses[f"{side}_pregrasp"] for side in ("left", "right")}
    motions = make_pick_motions(scenario)
    beside = motions.reach(BELOW_TABLE, pregrasps, points).keyframes
    monkeypatch.setattr(reach_motions, "parallel_calls", lambda *functions: [f() for f in functions])
    after = motions.reach(BELOW_TABLE, pregrasps, points).keyframes
    assert len(beside) > 2  # (a path STOMP planned, not the straight move alone)
    np.testing.assert_array_equal(beside, after)
