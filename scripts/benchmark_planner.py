"""Benchmarks the STOMP planner on the paper's experiments, with Drake's KinematicTrajectoryOptimization as a peer.

  closure_off / closure_on: paper Table I. Both hands hold the can at its grasp; both arms
      lift it 0.15 m, without / with the kinematic-chain closure constraint (the table is the
      only obstacle, the held object moves with the hands; self-collision counts). 10 s limit.
  bar_lift: the same lift keeping, besides the closure, both hands' world orientation
      (a bar lying on both wrists must not roll off).
  reach: from arms under the table top (the straight line collides) to the pre-grasp
      poses of a test can or drill at a random yaw.
  reach_kto: the same reaching problems solved by Drake's KinematicTrajectoryOptimization.

Every returned trajectory is checked densely with Drake's own geometry queries.

python scripts/benchmark_planner.py --runs 50 --json planner.json
"""

import argparse
import logging
import time
from pathlib import Path

import numpy as np
from json_report import write_json
from pydrake.math import RigidTransform
from pydrake.multibody.inverse_kinematics import MinimumDistanceLowerBoundConstraint
from pydrake.planning import KinematicTrajectoryOptimization
from pydrake.solvers import Solve
from pydrake.trajectories import BsplineTrajectory

from diagrams.objects.library import resolve_object
from diagrams.planning_scene import grasp_configuration, make_dual_arm_ik, true_grasp_poses
from diagrams.scenario import load_scenario, replace_object
from diagrams.station import object_pose_on_table
from systems.planning.closure import ClosureConstraint, OrientationConstraint, deviations, orientation_deviations
from systems.planning.ik import DualArmIk
from systems.planning.stomp import interpolate_segments

BELOW_TABLE = np.array([0, 0.15, 0, -0.1, 0, 0, 0, 0, -0.15, 0, -0.1, 0, 0, 0.0])
TIME_LIMIT_S = 10.0
DENSE_STEPS = 20  # states checked per segment between keyframes


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
    successes = [r for r in rows if r["success"]]
    if "max_translation_dev_m" in rows[0]:
        # Over the successful runs: a failed plan is never executed.
        result["max_translation_dev_m"] = max((r["max_translation_dev_m"] for r in successes), default=np.nan)
        result["max_orientation_dev_rad"] = max((r["max_orientation_dev_rad"] for r in successes), default=np.nan)
    return result


def closure_experiment(runs: int, closure: bool, fixed_orientation: bool = False) -> list[dict]:
    scenario = load_scenario()
    model = resolve_object(scenario.object)
    X_WO = object_pose_on_table(scenario, model)
    q_grasp = grasp_configuration(scenario, make_dual_arm_ik(scenario, obstacle=model, X_WO=X_WO))
    ik = make_dual_arm_ik(scenario)  # the held object moves with the hands: robot and table only
    X = ik.grasp_frame_poses(q_grasp)  # the lift's goal: both hands 0.15 m up, holding the object as at q_grasp
    lift = ik.solve_held(RigidTransform([0, 0, 0.15]) @ X["left"], X["left"].InvertAndCompose(X["right"]), q_grasp,
                         0.001, 0.15)  # fmt: skip
    q_lift = lift.q
    stomp = ik.stomp
    stomp.config.time_limit_s = TIME_LIMIT_S
    constraint = ClosureConstraint()
    X_desired = stomp.end_effectors.relative(q_grasp[None])[0]
    orientation = OrientationConstraint() if fixed_orientation else None
    R_desired = [X[0, :3, :3] for X in stomp.end_effectors.poses(q_grasp[None])] if fixed_orientation else None
    goal = stomp.project(q_lift, X_desired, R_desired, steps=15)[0]
    rows = []
    for run in range(runs):
        stomp.config.seed = run
        result = stomp.plan(q_grasp, goal, ik.planning_obstacles, constraint if closure else None, orientation)
        states = interpolate_segments(result.trajectory, DENSE_STEPS)
        t_dev, o_dev = deviations(stomp.end_effectors, states, X_desired)
        if fixed_orientation:
            o_dev = np.maximum(o_dev, orientation_deviations(stomp.end_effectors, states, R_desired))
        clearance = min(ik.clearance(q) for q in states[:: max(1, len(states) // 200)])
        rows.append(
            {
                "success": bool(result.success and clearance > 0),
                "runtime_s": result.seconds,
                "iterations": result.iterations,
                "min_clearance_m": clearance,
                "max_translation_dev_m": float(t_dev.max()),
                "max_orientation_dev_rad": float(o_dev.max()),
            }
        )
    return rows


def reach_problems(runs: int, seed: int):
    """(ik, q_start, q_goal) per run: a test can or drill at a random yaw, seeded."""
    rng = np.random.default_rng(seed)
    base = load_scenario()
    problems = []
    for run in range(runs):
        category = ("watering_can", "drill")[run % 2]
        scenario = replace_object(
            base, category=category, instance=f"test_{rng.integers(3)}", yaw=float(rng.uniform(-0.45, 0.45))
        )
        model = resolve_object(scenario.object)
        X_WO = object_pose_on_table(scenario, model)
        ik = make_dual_arm_ik(scenario, obstacle=model, X_WO=X_WO)
        poses = true_grasp_poses(scenario)
        pregrasps = {side: poses[f"{side}_pregrasp"] for side in ("left", "right")}
        goal = ik.solve(pregrasps, np.array(scenario.initial_arm_positions))
        if goal.success:
            problems.append((ik, BELOW_TABLE, goal.q))
    return problems


def check_dense(ik: DualArmIk, trajectory: np.ndarray) -> float:
    states = interpolate_segments(trajectory, DENSE_STEPS)
    return min(ik.clearance(q) for q in states)


def reach_stomp(problems) -> list[dict]:
    rows = []
    for ik, q_start, q_goal in problems:
        ik.stomp.config.time_limit_s = TIME_LIMIT_S
        result = ik.stomp.plan(q_start, q_goal, ik.planning_obstacles)
        clearance = check_dense(ik, result.trajectory)
        success = bool(result.success and clearance > 0)
        rows.append({"success": success, "runtime_s": result.seconds, "min_clearance_m": clearance})
    return rows


def reach_kto(problems, control_points: int = 10, samples: int = 25) -> list[dict]:
    """Drake's KinematicTrajectoryOptimization: B-spline, collision as minimum-distance constraints at samples."""
    rows = []
    for ik, q_start, q_goal in problems:
        plant, context = ik.plant, ik.plant_context
        start = time.perf_counter()
        trajopt = KinematicTrajectoryOptimization(plant.num_positions(), control_points)
        prog = trajopt.get_mutable_prog()
        full_start, full_goal = ik.full_positions(q_start), ik.full_positions(q_goal)
        lower, upper = full_start.copy(), full_start.copy()  # fingers stay as they are
        lower[ik.arm_indices], upper[ik.arm_indices] = ik.lower, ik.upper
        trajopt.AddPositionBounds(lower, upper)
        velocity = np.zeros(plant.num_positions())
        velocity[ik.arm_indices] = ik.velocity_limits
        trajopt.AddVelocityBounds(-velocity, velocity)
        trajopt.AddDurationConstraint(0.5, 10.0)
        trajopt.AddDurationCost(1.0)
        trajopt.AddPathLengthCost(1.0)
        trajopt.AddPathPositionConstraint(full_start, full_start, 0)
        trajopt.AddPathPositionConstraint(full_goal, full_goal, 1)
        guess = np.linspace(full_start, full_goal, control_points).T
        trajopt.SetInitialGuess(BsplineTrajectory(trajopt.basis(), guess))
        collision = MinimumDistanceLowerBoundConstraint(plant, 0.005, context)
        for s in np.linspace(0, 1, samples):
            trajopt.AddPathPositionConstraint(collision, s)
        result = Solve(prog)
        seconds = time.perf_counter() - start
        path = trajopt.ReconstructTrajectory(result)
        times = np.linspace(path.start_time(), path.end_time(), 16)
        keyframes = np.array([path.value(t).ravel()[ik.arm_indices] for t in times])
        clearance = check_dense(ik, keyframes)
        success = bool(result.is_success() and clearance > 0)
        rows.append({"success": success, "runtime_s": seconds, "min_clearance_m": clearance})
    return rows


def main():
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--reach-runs", type=int, default=20)
    parser.add_argument("--kto-runs", type=int, default=5, help="KTO is slow: fewer runs")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    results = {}
    results["closure_off"] = summary(closure_experiment(args.runs, closure=False))
    results["closure_on"] = summary(closure_experiment(args.runs, closure=True))
    results["bar_lift"] = summary(closure_experiment(args.runs, closure=True, fixed_orientation=True))
    problems = reach_problems(args.reach_runs, args.seed)
    results["reach"] = summary(reach_stomp(problems))
    results["reach_kto"] = summary(reach_kto(problems[: args.kto_runs]))
    header = ("runs", "success", "median s", "mean s", "std s", "min clear m", "max dev m / rad")
    print(f"\n{'experiment':12s} " + " ".join(f"{h:>12s}" for h in header))
    for name, r in results.items():
        dev = (
            f"{r['max_translation_dev_m']:.4f} / {r['max_orientation_dev_rad']:.3f}"
            if "max_translation_dev_m" in r
            else ""
        )
        print(
            f"{name:12s} {r['runs']:12d} {r['success_rate']:12.2f} {r['runtime_s_median']:12.3f} "
            f"{r['runtime_s_mean']:12.3f} {r['runtime_s_std']:12.3f} {r['min_clearance_m']:12.4f} {dev:>12s}"
        )
    if args.json:
        write_json(args.json, results)


if __name__ == "__main__":
    main()
