"""Benchmarks the STOMP planner on closed-chain and reaching problems, with Drake's KinematicTrajectoryOptimization
as a peer. Every returned trajectory is checked densely: Drake's exact clearance of the robot, the exact distance of
a carried can's surface points to the table and box, the closure (and hand orientation) at every state.

Held problems (both hands hold a test can; 3 cans in turn, seed = run; STOMP starts from the straight joint line):
  closure_off / closure_on: paper Table I, a 0.15 m lift without / with the closure constraint (the table
      is the only obstacle, the held can moves with the hands; self-collision counts).
  bar_lift: the lift keeping, besides the closure, both hands' world orientation.
  carry: the can lifted 0.10 m, then carried 0.40 m across the table over a 0.16 m box in its way, the
      closure and the hands' world orientation kept, the can itself kept clear of table and box.
  turn: the can lifted, then turned 90 degrees about the vertical between the hands (held nearer the robot than
      for the lift: from there the arms reach 80-90 % of the turn), the closure and the hands' tilt kept; where
      the chain of held configurations stops short (test_2: 80 %), the goal is its end (motion_fraction_min).
  carry_no_detours: the carry from the projected straight line alone (no detours over or around the box).
  carry_no_update_projection: the rollouts projected, the updates not (STOMP-New had neither).
  *_no_projection: the same with no Gauss-Newton projection (of rollouts, updates or the first trajectory's
      detours): only the tangent-space noise and the cost terms keep the constraints.
  peer_carry / peer_lift: KinematicTrajectoryOptimization on the carry / lift (deterministic: one run per can).
Reaching (from arms under the table top, where the straight line collides, to both hands' pre-grasps):
  reach: test cans and drills at random yaws; reach_kto: the peer on the first of them.
  reach_unseen: the 16 unseen generated instances extra_101-108 of both categories at yaws -0.3, 0, 0.3,
      around their surface points; counted where an IK goal exists.

python scripts/benchmark_planner.py --runs 50 --json planner.json
"""

import argparse
import dataclasses
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from json_report import write_json
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody import inverse_kinematics as drake_ik
from pydrake.planning import KinematicTrajectoryOptimization
from pydrake.solvers import SnoptSolver, Solve, SolverOptions
from pydrake.trajectories import BsplineTrajectory

from diagrams.generation.objects.library import resolve_object
from diagrams.planning_scene import (
    MakeRobotScene,
    grasp_configuration,
    make_pick_motions,
    object_surface_W,
    true_grasp_poses,
)
from diagrams.scenario import Scenario, initial_positions, load_scenario, replace_object
from diagrams.station import object_pose_on_table
from systems.planning.closure import ClosureConstraint, OrientationConstraint, deviations, orientation_deviations
from systems.planning.kinematics import Payload
from systems.planning.obstacles import Obstacles
from systems.planning.pick_motions import PickMotions, PlannerConfig
from systems.planning.stomp import Stomp, StompConfig, interpolate_segments
from systems.planning.world import PlanningWorld

BELOW_TABLE = np.array([0, 0.15, 0, -0.1, 0, 0, 0, 0, -0.15, 0, -0.1, 0, 0, 0.0, 0.0])  # the torso straight
TIME_LIMIT_S = 10.0
DENSE_STEPS = 20  # states checked per segment between keyframes
LIFT_M = 0.15
HELD_XY = (-0.12, 0.12)  # m, the can in the table top's frame for the lift and turn
CARRY_START_XY = (-0.12, 0.20)  # the carry: from here 0.40 m towards -y, over a box midway
CARRY_MOTION = (0.0, -0.40, 0.0)
CARRY_BOX_XY = [-0.12, 0.0]
CARRY_BOX_HEIGHT = 0.16  # m: the can, lifted CARRY_LIFT_M, would hit it going straight across
CARRY_LIFT_M = 0.10
TURN_RAD = np.pi / 2
# m, in the table top's frame: where the arms turn a held can by TURN_RAD (chosen with train_1 and train_3: from
# HELD_XY the hands reach 80-90 % of the turn, from here all of it)
TURN_XY = (-0.12, 0.06)
TURN_MIN_FRACTION = 0.8  # test_2's chain of held configurations ends at 80 % of the turn (72 degrees)
OBJECT_CHECK_POINTS = 1000
# SNOPT's default limits end the held problems early (kIterationLimit after about 1 s).
SNOPT_OPTIONS = SolverOptions()
SNOPT_OPTIONS.SetOption(SnoptSolver.id(), "Major iterations limit", 2000)
SNOPT_OPTIONS.SetOption(SnoptSolver.id(), "Iterations limit", 200000)
# A path, not an optimum: a looser optimality tolerance ends it once feasible and nearly still (27 s -> s on the lift).
SNOPT_OPTIONS.SetOption(SnoptSolver.id(), "Major optimality tolerance", 1e-3)
# Without any projection, the tangent-space noise must be small (the lift, 6 seeds: 5 solved at 0.15 rad, 2 of 3
# at 0.1, none of 3 at 0.03 or 0.8).
NO_PROJECTION_NOISE = 0.15
PEER_MIN_DISTANCE = 0.01  # m, at the peer's samples: with 5 mm, the can passed 1.2 mm into the box between them
UNSEEN = [f"extra_{i}" for i in range(101, 109)]
UNSEEN_YAWS = (-0.3, 0.0, 0.3)


def summary(rows: list[dict]) -> dict:
    times = np.array([r["runtime_s"] for r in rows])
    result = {
        "runs": len(rows),
        "success_rate": float(np.mean([r["success"] for r in rows])),
        "runtime_s_median": float(np.median(times)),
        "runtime_s_mean": float(times.mean()),
        "runtime_s_std": float(times.std()),
        "min_clearance_m": float(min(r["min_clearance_m"] for r in rows)),
    }
    if "motion_fraction" in rows[0]:  # the share of the asked motion planned (a turn's goal may fall short)
        result["motion_fraction_min"] = float(min(r["motion_fraction"] for r in rows))
    if "iterations" in rows[0]:
        result["iterations_median"] = float(np.median([r["iterations"] for r in rows]))
    successes = [r for r in rows if r["success"]]
    if "max_translation_dev_m" in rows[0]:
        # Over the successful runs: a failed plan is never executed.
        result["max_translation_dev_m"] = max((r["max_translation_dev_m"] for r in successes), default=np.nan)
        result["max_orientation_dev_rad"] = max((r["max_orientation_dev_rad"] for r in successes), default=np.nan)
    return result


@dataclass
class HeldProblem:
    """Both hands hold a can; STOMP moves them from q_start to q_goal (on the closure manifold) in `scene`."""

    motions: PickMotions  # its world holds no object: the held object moves with the hands
    q_start: np.ndarray
    q_goal: np.ndarray
    scene: Obstacles  # the table (and a box); the carried can's points when it is kept clear of them
    object_points_W: np.ndarray | None  # the can's surface at q_start, checked against the scene's boxes
    orientation: OrientationConstraint | None
    ik_chain: np.ndarray  # configurations holding the can along the Cartesian motion (the peer's initial guess)
    payload: Payload
    scenario: Scenario
    X_WO: RigidTransform  # the can's pose at q_start
    fraction: float  # the share of the Cartesian motion that q_goal reaches


def _held_scenario(instance: str, xy, box_height: float = 0.0):
    scenario = replace_object(load_scenario(), category="watering_can", instance=instance, yaw=0.0)
    scenario = dataclasses.replace(scenario, object=dataclasses.replace(scenario.object, xy=list(xy)))
    if box_height:
        box = dataclasses.replace(scenario.obstacle, present=True, xy=CARRY_BOX_XY, size=[0.16, 0.03, box_height])
        scenario = dataclasses.replace(scenario, obstacle=box)
    return scenario


def held_problem(kind: str, instance: str) -> HeldProblem:
    """lift: the paper's 0.15 m lift (table only, the can moves with the hands and is not checked);
    carry: the can lifted, then carried 0.40 m across the table over a box taller than it is lifted;
    turn: the can lifted, then turned TURN_RAD about the vertical between the hands.
    Start and goal are on the closure manifold; STOMP starts from the straight joint-space line."""
    xy = {"carry": CARRY_START_XY, "turn": TURN_XY}.get(kind, HELD_XY)
    scenario = _held_scenario(instance, xy, CARRY_BOX_HEIGHT * (kind == "carry"))
    model = resolve_object(scenario.object)
    X_WO = object_pose_on_table(scenario, model)
    q_grasp = grasp_configuration(scenario, make_pick_motions(scenario, obstacle=model, X_WO=X_WO))
    motions = make_pick_motions(scenario)  # the held object moves with the hands
    world, stomp = motions.world, motions.stomp
    X_E1E2 = world.end_effectors.relative(q_grasp[None])[0]
    if kind == "lift":
        q_start, motion, lifted = q_grasp, RigidTransform([0, 0, LIFT_M]), RigidTransform()
    else:
        q_start = motions.held_path(q_grasp, RigidTransform([0, 0, CARRY_LIFT_M]), 1.0)[0][-1]
        lifted = RigidTransform([0, 0, CARRY_LIFT_M])
        if kind == "carry":
            motion = RigidTransform(CARRY_MOTION)
        else:
            hands = world.grasp_frame_poses(q_start)
            pivot = 0.5 * (hands["left"].translation() + hands["right"].translation())
            motion = (
                RigidTransform(pivot) @ RigidTransform(RollPitchYaw(0, 0, TURN_RAD), [0, 0, 0]) @ RigidTransform(-pivot)
            )
    # The turn's goal is as far as the IK chain holding the can gets (at least TURN_MIN_FRACTION of it).
    chain, fraction, _ = motions.held_path(q_start, motion, TURN_MIN_FRACTION if kind == "turn" else 1.0)
    q_goal = stomp.project(chain[-1], X_E1E2, None, steps=15)[0]
    chain[-1] = q_goal
    orientation = OrientationConstraint(upright_only=kind == "turn")
    if kind == "lift":  # the paper's Table I: the closure alone
        orientation = None
    scene, points = world.table_obstacles(), None
    if kind != "lift":
        points = object_surface_W(model, lifted @ X_WO, OBJECT_CHECK_POINTS)[0]
        scene = scene.carrying(motions.carried(q_start, points))
    payload = motions.payload(q_start)
    return HeldProblem(
        motions, q_start, q_goal, scene, points, orientation, chain, payload, scenario, lifted @ X_WO, fraction
    )


def held_experiment(
    kind: str, runs: int, closure: bool = True, projection: str = "all", fixed_orientation=None, detours: bool = True
):
    """STOMP on `runs` held problems (the 3 test cans in turn, seed = run), every result checked densely; without
    `detours`, STOMP starts from the projected straight line alone."""
    problems = [held_problem(kind, f"test_{i}") for i in range(3)]
    rows = []
    for run in range(runs):
        problem = problems[run % 3]
        config = dataclasses.replace(problem.motions.stomp.config, seed=run, time_limit_s=TIME_LIMIT_S)
        if not detours:
            config = dataclasses.replace(config, detour_heights=())
        if projection == "rollouts":  # the rollouts projected, the update not
            config = dataclasses.replace(config, projection_steps=0)
        if projection == "none":
            config = dataclasses.replace(  # no detours either: they are projected
                config,
                projection_steps=0,
                rollout_projection_steps=0,
                constrained_noise_std=NO_PROJECTION_NOISE,
                detour_heights=(),
            )
        stomp = Stomp(problem.motions.world, config)
        orientation = problem.orientation if fixed_orientation is None else fixed_orientation
        result = stomp.plan(
            problem.q_start,
            problem.q_goal,
            problem.scene,
            ClosureConstraint() if closure else None,
            orientation,
            payload=problem.payload,
        )
        row = check_held(problem, result.trajectory, orientation, closure)
        row.update(
            success=bool(result.success and row["valid"]),
            runtime_s=result.seconds,
            iterations=result.iterations,
            motion_fraction=problem.fraction,
        )
        rows.append(row)
    return rows


def check_held(problem: HeldProblem, trajectory: np.ndarray, orientation, closure: bool = True) -> dict:
    """Dense checks of a held move: Drake's exact clearance of the robot, the exact distance of the can's surface
    points to the scene's boxes, and the closure (unless not asked for) and orientation deviations at every
    state."""
    world = problem.motions.world
    end_effectors = world.end_effectors
    states = interpolate_segments(trajectory, DENSE_STEPS)
    X_desired = end_effectors.relative(problem.q_start[None])[0]
    t_dev, o_dev = deviations(end_effectors, states, X_desired)
    orientation_dev = 0.0
    if orientation is not None:
        R_WE = [X[0, :3, :3] for X in end_effectors.poses(problem.q_start[None])]
        orientation_dev = float(orientation_deviations(end_effectors, states, R_WE, orientation.upright_only).max())
    clearance = min(world.clearance(q) for q in states[:: max(1, len(states) // 200)])
    if problem.object_points_W is not None:
        clearance = min(clearance, object_clearance(problem, states))
    constraint = ClosureConstraint()
    valid = clearance > 0 and (not closure or (t_dev.max() < constraint.t_max and o_dev.max() < constraint.o_max))
    valid = valid and orientation_dev < OrientationConstraint().o_max
    return {
        "valid": bool(valid),
        "min_clearance_m": float(clearance),
        "max_translation_dev_m": float(t_dev.max()),
        "max_orientation_dev_rad": float(o_dev.max()),
        "max_hand_orientation_dev_rad": orientation_dev,
    }


def object_clearance(problem: HeldProblem, states: np.ndarray) -> float:
    """Smallest distance (m) of the can's surface points, moving with the left hand, to the scene's boxes."""
    world = problem.motions.world
    slot = world.end_effectors.positions[0]
    X_start = world.kinematics.body_poses(problem.q_start[None])[0, slot]
    points_B = (problem.object_points_W - X_start[:3, 3]) @ X_start[:3, :3]
    X = world.kinematics.body_poses(states)[:, slot]
    points = np.einsum("bij,mj->bmi", X[:, :3, :3], points_B) + X[:, None, :3, 3]
    boxes = Obstacles()
    boxes.boxes = problem.scene.boxes
    return float(boxes.distance(points, cap=1.0).min())


def reach_problems(runs: int, seed: int):
    """(motions, q_start, q_goal) per run: a test can or drill at a random yaw, seeded."""
    rng = np.random.default_rng(seed)
    base = load_scenario()
    problems = []
    for run in range(runs):
        category = ("watering_can", "drill")[run % 2]
        scenario = replace_object(
            base, category=category, instance=f"test_{rng.integers(3)}", yaw=float(rng.uniform(-0.45, 0.45))
        )
        motions, goal = reach_goal(scenario, initial_positions(scenario))
        if goal.success:
            problems.append((motions, BELOW_TABLE, goal.q))
    return problems


def reach_goal(scenario: Scenario, q_guess: np.ndarray, restarts: int = 4):
    """The planning core around the scenario's object (STOMP limited to TIME_LIMIT_S), and its IK solution at both
    pre-grasps (`restarts` as DualArmIk.solve's)."""
    model = resolve_object(scenario.object)
    config = PlannerConfig(stomp=StompConfig(time_limit_s=TIME_LIMIT_S))
    motions = make_pick_motions(scenario, config, obstacle=model, X_WO=object_pose_on_table(scenario, model))
    poses = true_grasp_poses(scenario)
    pregrasps = {side: poses[f"{side}_pregrasp"] for side in ("left", "right")}
    return motions, motions.ik.solve(pregrasps, q_guess, restarts=restarts)


def check_dense(world: PlanningWorld, trajectory: np.ndarray) -> float:
    states = interpolate_segments(trajectory, DENSE_STEPS)
    return min(world.clearance(q) for q in states)


def reach_stomp(problems) -> list[dict]:
    rows = []
    for motions, q_start, q_goal in problems:
        result = motions.stomp.plan(q_start, q_goal, motions.world.planning_obstacles())
        clearance = check_dense(motions.world, result.trajectory)
        success = bool(result.success and clearance > 0)
        rows.append(
            {
                "success": success,
                "runtime_s": result.seconds,
                "iterations": result.iterations,
                "min_clearance_m": clearance,
                "message": result.message,
            }
        )
    return rows


def kto_program(world: PlanningWorld, plant, q_start, q_goal, guess_path: np.ndarray, control_points: int):
    """KinematicTrajectoryOptimization over `plant`'s positions (the fingers held as they are) from q_start to
    q_goal: joint position and velocity limits, 0.5-10 s, duration and path-length costs, control points started
    evenly along `guess_path` (K x n configurations of the planned joints)."""
    trajopt = KinematicTrajectoryOptimization(plant.num_positions(), control_points)
    full_start, full_goal = world.full_positions(q_start), world.full_positions(q_goal)
    lower, upper = full_start.copy(), full_start.copy()
    lower[world.arm_indices], upper[world.arm_indices] = world.lower, world.upper
    trajopt.AddPositionBounds(lower, upper)
    velocity = np.zeros(plant.num_positions())
    velocity[world.arm_indices] = world.velocity_limits
    trajopt.AddVelocityBounds(-velocity, velocity)
    trajopt.AddDurationConstraint(0.5, 10.0)
    trajopt.AddDurationCost(1.0)
    trajopt.AddPathLengthCost(1.0)
    trajopt.AddPathPositionConstraint(full_start, full_start, 0)
    trajopt.AddPathPositionConstraint(full_goal, full_goal, 1)
    path = np.array([world.full_positions(q) for q in guess_path])
    along = np.linspace(0, 1, len(path))
    guess = np.array([np.interp(np.linspace(0, 1, control_points), along, column) for column in path.T])
    trajopt.SetInitialGuess(BsplineTrajectory(trajopt.basis(), guess))
    return trajopt


def kto_keyframes(world: PlanningWorld, trajopt, result, count: int = 16) -> np.ndarray:
    """The solved B-spline's arm configurations at `count` evenly spaced times (count x n)."""
    path = trajopt.ReconstructTrajectory(result)
    times = np.linspace(path.start_time(), path.end_time(), count)
    return np.array([path.value(t).ravel()[world.arm_indices] for t in times])


def reach_kto(problems, control_points: int = 10, samples: int = 25) -> list[dict]:
    """Drake's KinematicTrajectoryOptimization: B-spline, collision as minimum-distance constraints at samples."""
    rows = []
    for motions, q_start, q_goal in problems:
        world = motions.world
        plant, context = world.plant, world.plant_context
        start = time.perf_counter()
        trajopt = kto_program(world, plant, q_start, q_goal, np.stack([q_start, q_goal]), control_points)
        prog = trajopt.get_mutable_prog()
        collision = drake_ik.MinimumDistanceLowerBoundConstraint(plant, 0.005, context)
        for s in np.linspace(0, 1, samples):
            trajopt.AddPathPositionConstraint(collision, s)
        result = Solve(prog)
        seconds = time.perf_counter() - start
        keyframes = kto_keyframes(world, trajopt, result)
        clearance = check_dense(world, keyframes)
        success = bool(result.is_success() and clearance > 0)
        rows.append({"success": success, "runtime_s": seconds, "min_clearance_m": clearance})
    return rows


def peer_held(problem: HeldProblem, control_points: int = 12, samples: int = 24) -> dict:
    """Drake's KinematicTrajectoryOptimization on a held problem, tuned until it solves the lift and carry: a
    B-spline whose control points start on the IK chain holding the can along its Cartesian motion; at `samples`
    path points the closure (right grasp frame within half of t_max and o_max of its pose in the left one), the
    hands' world orientation (or tilt) within half of o_max, and MinimumDistanceLowerBoundConstraint
    (PEER_MIN_DISTANCE) over robot, table, box and the can (welded to the left hand, not checked against the hands
    that hold it)."""
    world = problem.motions.world
    scene = held_scene(problem)
    plant, context = scene.plant, scene.plant.GetMyMutableContextFromRoot(scene.diagram.CreateDefaultContext())
    start = time.perf_counter()
    trajopt = kto_program(world, plant, problem.q_start, problem.q_goal, problem.ik_chain, control_points)
    prog = trajopt.get_mutable_prog()
    left, right = (plant.GetFrameByName("grasp_frame", scene.hands[side]) for side in ("left", "right"))
    X_WG = world.grasp_frame_poses(problem.q_start)
    X_LR = X_WG["left"].InvertAndCompose(X_WG["right"])
    limits = ClosureConstraint()
    p_LR, tolerance = X_LR.translation(), np.full(3, 0.5 * limits.t_max)
    closure = [
        drake_ik.PositionConstraint(plant, left, p_LR - tolerance, p_LR + tolerance, right, np.zeros(3), context),
        drake_ik.OrientationConstraint(
            plant, left, X_LR.rotation(), right, RotationMatrix(), 0.5 * limits.o_max, context
        ),
    ]
    hands = []
    if problem.orientation is not None and not problem.orientation.upright_only:
        for frame, side in ((left, "left"), (right, "right")):
            R = X_WG[side].rotation()
            hands.append(
                drake_ik.OrientationConstraint(plant, plant.world_frame(), R, frame, RotationMatrix(), 0.025, context)
            )
    elif problem.orientation is not None:
        for frame, side in ((left, "left"), (right, "right")):
            up = X_WG[side].rotation().inverse() @ np.array([0, 0, 1.0])
            hands.append(
                drake_ik.AngleBetweenVectorsConstraint(
                    plant, plant.world_frame(), [0, 0, 1.0], frame, up, 0, 0.025, context
                )
            )
    collision = drake_ik.MinimumDistanceLowerBoundConstraint(plant, PEER_MIN_DISTANCE, context, None, 0.05)
    for s in np.linspace(0, 1, samples)[1:-1]:
        for constraint in (*closure, *hands, collision):
            trajopt.AddPathPositionConstraint(constraint, s)
    result = Solve(prog, solver_options=SNOPT_OPTIONS)
    seconds = time.perf_counter() - start
    keyframes = kto_keyframes(world, trajopt, result)
    row = check_held(problem, keyframes, problem.orientation)
    row.update(
        success=bool(result.is_success() and row["valid"]),
        runtime_s=seconds,
        solved=result.is_success(),
        status=str(result.get_solution_result()),
    )
    return row


def held_scene(problem: HeldProblem):
    """The problem's robot scene with the can welded to the left hand as at q_start."""
    X_WG = problem.motions.world.grasp_frame_poses(problem.q_start)["left"]
    model = resolve_object(problem.scenario.object)
    return MakeRobotScene(problem.scenario, held_object=model, X_GO=X_WG.InvertAndCompose(problem.X_WO))


def reach_unseen_problems():
    """(motions, q_start, q_goal) for the unseen instances of both categories at UNSEEN_YAWS, where an IK goal exists;
    also how many had none."""
    base = load_scenario()
    problems, without_goal = [], 0
    for category in ("watering_can", "drill"):
        for instance in UNSEEN:
            for yaw in UNSEEN_YAWS:
                scenario = replace_object(base, category=category, instance=instance, yaw=yaw)
                motions, goal = reach_goal(scenario, BELOW_TABLE, restarts=12)
                if goal.success:
                    problems.append((motions, BELOW_TABLE, goal.q))
                else:
                    without_goal += 1
    return problems, without_goal


def main():
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=50, help="runs of each held problem")
    parser.add_argument("--reach-runs", type=int, default=20)
    parser.add_argument("--kto-runs", type=int, default=3, help="KTO is slow: fewer runs")
    parser.add_argument("--only", nargs="*", help="experiments to run (default all)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    experiments = {
        "closure_off": lambda: held_experiment("lift", args.runs, closure=False),
        "closure_on": lambda: held_experiment("lift", args.runs),
        "closure_on_no_projection": lambda: held_experiment("lift", args.runs, projection="none"),
        "bar_lift": lambda: held_experiment("lift", args.runs, fixed_orientation=OrientationConstraint()),
        "carry": lambda: held_experiment("carry", args.runs),
        "carry_no_detours": lambda: held_experiment("carry", args.runs, detours=False),
        "carry_no_projection": lambda: held_experiment("carry", args.runs, projection="none"),
        "carry_no_update_projection": lambda: held_experiment("carry", args.runs, projection="rollouts"),
        "turn": lambda: held_experiment("turn", args.runs),
        "turn_no_projection": lambda: held_experiment("turn", args.runs, projection="none"),
        "peer_lift": lambda: [peer_held(held_problem("lift", f"test_{i % 3}")) for i in range(args.kto_runs)],
        "peer_carry": lambda: [peer_held(held_problem("carry", f"test_{i % 3}")) for i in range(args.kto_runs)],
        "reach": lambda: reach_stomp(reach_problems(args.reach_runs, args.seed)),
        "reach_kto": lambda: reach_kto(reach_problems(args.reach_runs, args.seed)[: args.kto_runs]),
        "reach_unseen": lambda: reach_unseen(),
    }
    results = {}
    for name, experiment in experiments.items():
        if args.only and name not in args.only:
            continue
        start = time.perf_counter()
        results[name] = summary(experiment())
        print(f"{name}: {results[name]['success_rate']:.2f} in {time.perf_counter() - start:.0f} s", flush=True)
    header = ("runs", "success", "median s", "mean s", "std s", "iterations", "min clear m", "max dev m / rad")
    print(f"\n{'experiment':25s} " + " ".join(f"{h:>12s}" for h in header))
    for name, r in results.items():
        dev = (
            f"{r['max_translation_dev_m']:.4f} / {r['max_orientation_dev_rad']:.3f}"
            if "max_translation_dev_m" in r
            else ""
        )
        print(
            f"{name:25s} {r['runs']:12d} {r['success_rate']:12.2f} {r['runtime_s_median']:12.3f} "
            f"{r['runtime_s_mean']:12.3f} {r['runtime_s_std']:12.3f} {r.get('iterations_median', np.nan):12.1f} "
            f"{r['min_clearance_m']:12.4f} {dev:>16s}"
        )
    if args.json:
        write_json(args.json, results)


def reach_unseen() -> list[dict]:
    problems, without_goal = reach_unseen_problems()
    logging.warning("reach_unseen: %d problems, %d without an IK goal (not counted)", len(problems), without_goal)
    return reach_stomp(problems)


if __name__ == "__main__":
    main()
