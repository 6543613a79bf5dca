"""Whether the arms reach the poses that use a held object, with the paper's grasps (issue 80's pour and aim).

--task pour: for each can, placement yaw and turn of its spout about the vertical (before the pour), the tilts about
the grasps' midpoint (the spout down, across its vertical plane) whose goal the arms reach holding the can. Printed
per row: the outflow's elevation before the tilt, the largest tilt reached (every smaller one reached too), and where
the outflow then points (negative: below the horizontal; the issue's pour needs -40 deg).
--task aim: for each drill, placement yaw, board (at the table's far edge, left or right side) and target on it
(heights above the table, offsets along the board), whether the arms reach the aim (the bit along the board's
normal, its tip 5 mm off the target).

Reached: IK under the closure from the held start (the object lifted 10 cm), torso free, as the planner benchmark
draws its problems (diagrams/benchmarks/use_reach.py). The true grasps and tool frame place the object: this
measures the arms' reach, not perception.

python scripts/benchmark_use_reach.py --task pour --json pour_reach.json
python scripts/benchmark_use_reach.py --task aim --json aim_reach.json
"""

import argparse
import collections
import logging
import time
from pathlib import Path

from diagrams.benchmarks.use_reach import BOARDS, LIFT_M, PIVOTS, aim_reach_rows, pour_reach_rows
from diagrams.cli import write_json
from diagrams.generation.planning_problems import DRAWN_WITH
from diagrams.planning_scene import make_pick_motions
from diagrams.scenario import load_scenario

POUR_BELOW_DEG = 40.0  # the default pour: the outflow this far below the horizontal


def main():
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", choices=("pour", "aim"), required=True)
    parser.add_argument("--instances", nargs="+", default=["test_0", "test_1", "test_2"], help="of the task's category")
    parser.add_argument("--yaws", type=float, nargs="+", default=[-0.25, 0.0, 0.25], help="placement yaws, rad")
    parser.add_argument("--turns", type=float, nargs="+", default=[-45.0, 0.0, 45.0], help="pour: spout turns, deg")
    parser.add_argument("--tilts", type=float, nargs="+", default=[15.0, 30.0, 45.0, 60.0, 75.0, 90.0], help="deg")
    parser.add_argument("--pivot", choices=PIVOTS, default="middle", help="pour: what the can turns about")
    parser.add_argument("--lift", type=float, default=LIFT_M, help="pour: how high the can is held, m")
    parser.add_argument("--heights", type=float, nargs="+", default=[0.15, 0.25], help="aim: targets above the table")
    parser.add_argument("--offsets", type=float, nargs="+", default=[-0.15, 0.0, 0.15], help="aim: along the board")
    parser.add_argument(
        "--inset", type=float, default=0.0, help="aim: the boards stand this far in from the table's edges, m"
    )
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    start = time.perf_counter()
    motions = make_pick_motions(load_scenario(), DRAWN_WITH)
    if args.task == "pour":
        rows = pour_reach_rows(motions, args.instances, args.yaws, args.turns, args.tilts, args.pivot, args.lift)
        print(f"\n{'can':8s} {'yaw':>6s} {'turn':>5s} {'outflow':>8s} {'largest tilt':>13s} {'outflow then':>13s}")
        for row in rows:
            largest, then = row["largest_tilt_deg"], row["outflow_at_largest_deg"]
            print(
                f"{row['instance']:8s} {row['yaw_rad']:+6.2f} {row['turn_deg']:+5.0f} {row['elevation_deg']:+7.0f}° "
                f"{'none' if largest is None else f'{largest:.0f}°':>13s} "
                f"{'-' if then is None else f'{then:+.0f}°':>13s}"
            )
        reached = sum(1 for row in rows if (row["outflow_at_largest_deg"] or 0.0) <= -POUR_BELOW_DEG)
        summary = f"rows whose reached tilt points the outflow {POUR_BELOW_DEG:.0f}° down: {reached} of {len(rows)}"
    else:
        rows = aim_reach_rows(motions, args.instances, args.yaws, args.heights, args.offsets, args.inset)
        drills = len(args.instances) * len(args.yaws)
        print(f"\n{'board':6s} {'height':>7s} {'offset':>7s}  reached (of {drills}: the drills at each yaw)")
        cells = collections.defaultdict(list)
        for row in rows:
            cells[(row["board"], row["height_m"], row["offset_m"])].append(row["answer"] == "reached")
        for (board, height, offset), answers in cells.items():
            print(f"{board:6s} {height:7.2f} {offset:+7.2f}  {sum(answers)}")
        reached = sum(row["answer"] == "reached" for row in rows)
        per_board = {b: sum(r["answer"] == "reached" for r in rows if r["board"] == b) for b in BOARDS}
        summary = f"aims reached: {reached} of {len(rows)} ({', '.join(f'{b} {n}' for b, n in per_board.items())})"
    print(f"{summary} ({time.perf_counter() - start:.0f} s)")
    if args.json:
        write_json(args.json, {"task": args.task, "arguments": vars(args) | {"json": str(args.json)},
                               "reached": reached, "rows": rows})  # fmt: skip


if __name__ == "__main__":
    main()
