"""The planner benchmark (scripts/benchmark_planner.py): STOMP on seeded families of planning problems, beside OMPL
and Drake's KinematicTrajectoryOptimization.

Families (diagrams/generation/planning_problems.py; problem k of a family and split is made from its seed alone):
  lift, carry, turn, set_down: held moves of an object both hands hold (closure and hand orientation kept, the
      object kept clear), with 0-3 boxes standing or hanging where the object's straight path goes;
  reach: both hands to their pre-grasps from under the table or the ready pose, past boxes;
  aim: a held drill aimed at a board's target (the hands' tilt kept); pour: a held can tilted over a container
      until it pours (the closure kept, the hands' orientation free).
Splits: `tune` (training objects; parameters are chosen here) and `report` (unseen objects; never tuned on).
`--problems N` takes the first N kept problems of the split; the problems dropped on the way (no IK at start or
goal, or either less than 2 cm clear) are counted in `dropped_share`.

Planners (every path judged by the same dense checker: Drake's exact clearance of robot, held object, table
and boxes, the joint limits, and in held moves the closure and hand orientation (where kept), at states 0.01 rad
apart):
  stomp: the pick's STOMP (systems/planning/stomp.py) from the straight joint-space line;
  stomp_no_detours, stomp_no_projection, stomp_first_trajectory: ablations (held moves; the last also reaches);
  ompl: OMPL's RRTConnect (held: in a ProjectedStateSpace with the hand constraints) then simplification;
  kto: Drake's KinematicTrajectoryOptimization.
A planner that fails counts at the time limit in the time statistics. The slow planners (ompl, kto, and the
ablations) run on the first --peer-problems problems; ratios are taken on the problems both planners ran.
"""

import dataclasses
from pathlib import Path

import numpy as np
from tqdm import tqdm

from diagrams.benchmarks.planner_peers import KtoConfig, OmplConfig, PeerResult, kto_plan, ompl_plan
from diagrams.generation.planning_problems import (
    HELD_FAMILIES,
    PlanningProblem,
    check_path,
    make_problem,
    projected_straight_line,
)
from systems.planning.closure import ClosureConstraint
from systems.planning.pick_motions import PickMotions
from systems.planning.stomp import Stomp
from systems.planning.stomp_config import StompConfig

TIME_LIMIT_S = 10.0  # every planner's, per problem
# Without any projection, the tangent-space noise must be small (docs/history/planning_parameters.md).
NO_PROJECTION_NOISE = 0.15
STOMP_PLANNERS = ("stomp", "stomp_no_detours", "stomp_no_projection", "stomp_first_trajectory")
PLANNERS = (*STOMP_PLANNERS, "ompl", "kto")
REACH_PLANNERS = ("stomp", "stomp_first_trajectory", "ompl", "kto")


def stomp_config(planner: str, seed: int) -> StompConfig:
    """The STOMP configuration of a planner (the pick's, or an ablation of it) for the problem's seed."""
    config = StompConfig(seed=seed, time_limit_s=TIME_LIMIT_S)
    no_detours = dataclasses.replace(config.detours, heights=())
    if planner == "stomp_no_detours":
        return dataclasses.replace(config, detours=no_detours)
    if planner == "stomp_no_projection":  # no detours either: they are projected
        sampling = dataclasses.replace(
            config.sampling, projection_steps=0, rollout_projection_steps=0, constrained_noise_std=NO_PROJECTION_NOISE
        )
        return dataclasses.replace(config, sampling=sampling, detours=no_detours)
    if planner == "stomp_first_trajectory":
        return dataclasses.replace(config, max_iterations=0)
    return config


def run_stomp(problem: PlanningProblem, motions: PickMotions, planner: str) -> dict:
    stomp = Stomp(motions.world, stomp_config(planner, problem.index))
    if problem.held:
        result = stomp.plan(
            problem.q_start,
            problem.q_goal,
            problem.obstacles,
            ClosureConstraint(),
            problem.orientation,
            payload=motions.payload(problem.q_start),
        )
    else:
        result = stomp.plan(problem.q_start, problem.q_goal, problem.obstacles)
    return judged(
        problem, PeerResult(result.success, result.trajectory, result.seconds, result.message), result.iterations
    )


def judged(problem: PlanningProblem, result: PeerResult, iterations: int | None = None) -> dict:
    """A planner's record: its own verdict, the dense checker's, the time (a failure counts at the limit)."""
    check = check_path(problem, result.path)
    success = bool(result.solved and check["valid"])
    return {
        "index": problem.index,
        "success": success,
        "solved": result.solved,
        "runtime_s": result.seconds if success else max(result.seconds, TIME_LIMIT_S),
        "planner_s": result.seconds,
        "iterations": iterations,
        "message": result.message,
        **check,
    }


def straight_line_collides(problem: PlanningProblem, motions: PickMotions) -> bool:
    """Whether the projected straight line (STOMP's first trajectory before any detour) fails the dense clearance
    check: what makes a problem more than a straight move."""
    return check_path(problem, projected_straight_line(problem, motions.stomp))["min_clearance_m"] <= 0


def percentile(values, q: float) -> float:
    values = [v for v in values if v is not None]
    return float(np.percentile(values, q)) if values else float("nan")


def summary(rows: list[dict]) -> dict:
    """A planner's figures over its problems."""
    successes = [r for r in rows if r["success"]]
    iterations = [r["iterations"] for r in rows if r["iterations"] is not None]
    result = {
        "problems": len(rows),
        "success_rate": float(np.mean([r["success"] for r in rows])) if rows else float("nan"),
        "runtime_s_median": percentile([r["runtime_s"] for r in rows], 50),
        "runtime_s_p95": percentile([r["runtime_s"] for r in rows], 95),
        "iterations_median": percentile(iterations, 50),
        "iterations_p95": percentile(iterations, 95),
        "zero_iteration_share": float(np.mean([r["success"] and r["iterations"] == 0 for r in rows]))
        if iterations
        else float("nan"),
        "min_clearance_m": min((r["min_clearance_m"] for r in successes), default=float("nan")),
    }
    if rows and "closure_translation_dev_m" in rows[0]:  # held moves: over the successes (a failure never runs)
        for key in ("closure_translation_dev_m", "closure_orientation_dev_rad", "hand_orientation_dev_rad"):
            result[f"{key}_max"] = max((r[key] for r in successes), default=float("nan"))
    return result


def generate(motions: PickMotions, family: str, split: str, count: int) -> tuple[list[PlanningProblem], list]:
    """The first `count` kept problems of the family's split, and those dropped on the way."""
    problems, dropped, index = [], [], 0
    with tqdm(total=count, desc=f"{family}: problems", unit="problem") as bar:
        while len(problems) < count:
            problem = make_problem(motions, family, split, index)
            index += 1
            if isinstance(problem, PlanningProblem):
                problems.append(problem)
                bar.update()
            else:
                dropped.append(problem)
    return problems, dropped


def run_family(args, motions: PickMotions, family: str) -> dict:
    """The family's problems of args.split run by args.planners (scripts/benchmark_planner.py's options: split,
    problems, planners, peer_problems and the ompl_* ones): the figures of each planner and every record."""
    problems, dropped = generate(motions, family, args.split, args.problems)
    planners = [p for p in (PLANNERS if family in HELD_FAMILIES else REACH_PLANNERS) if p in args.planners]
    ompl_config = OmplConfig(
        space=args.ompl_space,
        range=args.ompl_range,
        delta=args.ompl_delta,
        tolerance=args.ompl_tolerance,
        bounds_margin=args.ompl_bounds_margin,
    )
    rows = {planner: [] for planner in planners}
    # Problem by problem, every planner that runs it in turn: a machine that slows down for a while slows all alike.
    for k, problem in enumerate(tqdm(problems, desc=f"{family}: {', '.join(planners)}", unit="problem")):
        for planner in planners:
            if planner != "stomp" and k >= args.peer_problems:
                continue
            if planner in STOMP_PLANNERS:
                rows[planner].append(run_stomp(problem, motions, planner))
            elif planner == "ompl":
                rows[planner].append(judged(problem, ompl_plan(problem, motions.stomp, TIME_LIMIT_S, ompl_config)))
            else:
                rows[planner].append(judged(problem, kto_plan(problem, motions.stomp, TIME_LIMIT_S, KtoConfig())))
    collides = [straight_line_collides(p, motions) for p in problems]
    result = {
        "split": args.split,
        "problems": len(problems),
        "dropped_share": len(dropped) / (len(dropped) + len(problems)),
        "dropped_reasons": _reasons(dropped),
        "straight_line_collides_share": float(np.mean(collides)),
        "first_index": problems[0].index if problems else None,
        "last_index": problems[-1].index if problems else None,
        "planners": {planner: summary(records) for planner, records in rows.items()},
        "records": rows,
    }
    if "stomp" in rows and "ompl" in rows:
        result["speedup_vs_ompl"] = _speedup(rows["stomp"], rows["ompl"])
    if "stomp" in rows and "kto" in rows:
        result["speedup_vs_kto"] = _speedup(rows["stomp"], rows["kto"])
    return result


def _speedup(stomp: list[dict], peer: list[dict]) -> float:
    """The peer's median time over STOMP's, on the problems both ran."""
    ran = {r["index"] for r in peer}
    ours = [r["runtime_s"] for r in stomp if r["index"] in ran]
    return float(np.median([r["runtime_s"] for r in peer]) / np.median(ours))


def _reasons(dropped: list) -> dict:
    """How many problems were dropped for each kind of reason."""
    counts: dict[str, int] = {}
    for problem in dropped:
        if problem.reason.startswith("no IK"):
            kind = problem.reason.split(":")[0]
        elif "joint limits" in problem.reason:
            kind = "start or goal outside the joint limits"
        elif "sphere model" in problem.reason:
            kind = "start or goal not clear in the sphere model"
        else:
            kind = "start or goal too near (exact)"
        counts[kind] = counts.get(kind, 0) + 1
    return counts


def print_family(family: str, result: dict) -> None:
    print(
        f"\n{family} ({result['split']} range, indices {result['first_index']}-{result['last_index']}): "
        f"{result['problems']} problems, {100 * result['dropped_share']:.0f} % dropped {result['dropped_reasons']}, "
        f"straight line collides in {100 * result['straight_line_collides_share']:.0f} %"
    )
    header = ("problems", "success", "median s", "p95 s", "iter med", "iter p95", "0-iter", "closure mm/rad")
    print(f"{'planner':24s} " + " ".join(f"{h:>10s}" for h in header))
    for planner, r in result["planners"].items():
        closure = (
            f"{1000 * r['closure_translation_dev_m_max']:.1f}/{r['closure_orientation_dev_rad_max']:.3f}"
            if "closure_translation_dev_m_max" in r
            else ""
        )
        print(
            f"{planner:24s} {r['problems']:10d} {r['success_rate']:10.3f} {r['runtime_s_median']:10.3f} "
            f"{r['runtime_s_p95']:10.3f} {r['iterations_median']:10.1f} {r['iterations_p95']:10.1f} "
            f"{r['zero_iteration_share']:10.2f} {closure:>14s}"
        )
    for peer in ("ompl", "kto"):
        if f"speedup_vs_{peer}" in result:
            print(
                f"speedup vs {peer} (its median time over STOMP's, same problems): {result[f'speedup_vs_{peer}']:.1f}"
            )


def draw(family: str, result: dict, path: Path) -> None:
    """Success per planner, and each planner's time distribution (failures at the limit)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    planners = list(result["planners"])
    figure, (bars, times) = plt.subplots(1, 2, figsize=(11, 4))
    rates = [result["planners"][p]["success_rate"] for p in planners]
    bars.barh(planners, rates, color=["tab:blue" if p.startswith("stomp") else "tab:gray" for p in planners])
    for y, (planner, rate) in enumerate(zip(planners, rates, strict=True)):
        label = f"{100 * rate:.0f} % of {result['planners'][planner]['problems']}"
        bars.text(0.02, y, label, va="center", color="white" if rate > 0.3 else "black")
    bars.set_xlim(0, 1)
    bars.invert_yaxis()
    bars.set_xlabel("success (dense check)")
    for planner in planners:
        records = result["records"][planner]
        seconds = np.sort([r["runtime_s"] for r in records if r["success"]])
        share = np.arange(len(seconds) + 1) / len(records)
        times.step(np.concatenate([[1e-3], seconds]), share, where="post", label=planner)
    times.axvline(TIME_LIMIT_S, color="k", linestyle=":", linewidth=1)
    times.set_xscale("log")
    times.set_xlim(1e-3, 2 * TIME_LIMIT_S)
    times.set_ylim(0, 1.02)
    times.set_xlabel(f"time, s (limit {TIME_LIMIT_S:.0f} s, dotted)")
    times.set_ylabel("share of its problems solved within")
    times.legend(fontsize=8)
    figure.suptitle(f"{family}: {result['problems']} problems of the {result['split']} range")
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
