"""Whether the arms reach the poses that use a held object, with the paper's grasps (issue 80's pour and aim).

--task pour: for each can, placement yaw and turn of its spout about the vertical (before the pour), the tilts about
the grasps' midpoint (the spout down, across its vertical plane) whose goal the arms reach holding the can. Printed
per row: the outflow's elevation before the tilt, the largest tilt reached (every smaller one reached too), and where
the outflow then points (negative: below the horizontal; the issue's pour needs -40 deg).
--task aim: for each drill, placement yaw, board (at the table's far edge, left or right side) and target on it
(heights above the table, offsets along the board), whether the arms reach the aim (the bit along the board's
normal, its tip 5 mm off the target).
--task clear: for each familiar object of the clear tables (alone where it stands, lifted), the drop zone's spots
(a grid, each turn about the vertical from how it stood) the carry reaches (diagrams/benchmarks/zone_reach.py).
Printed: per object the share of spots reached at each turn; per turn a map of the zone (x down, y across, both in W)
with the number of objects reaching each spot, and the same at any of the turns.

Pour and aim reached: IK under the closure from the held start (the object lifted 10 cm), torso free, as the planner
benchmark draws its problems (diagrams/benchmarks/use_reach.py). The true grasps and tool frame place the object: this
measures the arms' reach, not perception.

python scripts/benchmark_use_reach.py --task pour --json pour_reach.json
python scripts/benchmark_use_reach.py --task aim --json aim_reach.json
python scripts/benchmark_use_reach.py --task clear --tables 4 --scene-split tune --json zone_reach.json
"""

import argparse
import collections
import logging
import time
from pathlib import Path

import numpy as np

from diagrams.benchmarks.use_reach import BOARDS, LIFT_M, PIVOTS, aim_reach_rows, pour_reach_rows
from diagrams.benchmarks.zone_reach import zone_reach_rows
from diagrams.cli import write_json
from diagrams.generation.planning_problems import DRAWN_WITH
from diagrams.planning_scene import make_pick_motions
from diagrams.scenario import load_scenario
from systems.planning.drop_zone import DROP_TURNS_RAD

POUR_BELOW_DEG = 40.0  # the default pour: the outflow this far below the horizontal


def main():
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", choices=("pour", "aim", "clear"), required=True)
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
    parser.add_argument("--tables", type=int, default=4, help="clear: the tables (0..N-1) whose objects are carried")
    parser.add_argument(
        "--scene-split", choices=("tune", "validation", "report"), default="tune", help="clear: the tables' split"
    )
    parser.add_argument("--zone-turns", type=float, nargs="+", default=sorted(DROP_TURNS_RAD), help="clear: rad")
    parser.add_argument("--zone-step", type=float, default=0.06, help="clear: between the zone's spots, m")
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
    elif args.task == "clear":
        turns = args.zone_turns
        print(f"\n{'table':>5s} {'object':22s} {'at (x, y) in W':>15s}  spots reached at each turn (rad)")
        print(f"{'':46s}" + " ".join(f"{turn:+6.2f}" for turn in turns))
        rows = zone_reach_rows(motions, load_scenario(), args.tables, args.scene_split, turns, args.zone_step,
                               lambda row: _print_zone_row(row, turns))  # fmt: skip
        reached, summary = _print_zone_maps(rows, turns)
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


def _print_zone_row(row: dict, turns: list[float]) -> None:
    """Prints one object's share of the zone's spots reached at each turn."""
    name = f"{row['category']}/{row['instance']}"
    where = "({:.2f}, {:+.2f})".format(*row["xy_W"])
    shares = "not lifted" if row["reached"] is None else " ".join(
        f"{np.mean(row['reached'][str(turn)]):6.0%}" for turn in turns
    )  # fmt: skip
    print(f"{row['table']:5d} {name:22s} {where:>15s}  {shares}", flush=True)


def _print_zone_maps(rows: list[dict], turns: list[float]) -> tuple[int, str]:
    """Prints per turn (and at any of them) how many objects are carried to each of the zone's spots; returns the
    spots every object lifted is carried to at one turn or another, and the summary line."""
    lifted = [row for row in rows if row["reached"] is not None]
    if not lifted:
        return 0, "no object lifted"
    xs, ys = lifted[0]["xs_W"], lifted[0]["ys_W"]
    reached = {f"turn {turn:+.2f} rad": [row["reached"][str(turn)] for row in lifted] for turn in turns}
    reached["at any of the turns"] = [np.any([row["reached"][str(turn)] for turn in turns], axis=0) for row in lifted]
    print(f"\nobjects (of {len(lifted)} lifted) carried to each spot; rows x, columns y in W: "
          + " ".join(f"{y:+.2f}" for y in ys))  # fmt: skip
    for label, maps in reached.items():
        count = np.sum(maps, axis=0)
        print(label)
        for i, x in enumerate(xs):
            print(f"  x {x:.2f}  " + " ".join(f"{n:5d}" for n in count[i]))
    anywhere = np.sum(reached["at any of the turns"], axis=0)
    every = int(np.sum(anywhere == len(lifted)))
    summary = f"spots every object lifted is carried to at one turn or another: {every} of {anywhere.size}"
    summary += f" ({len(lifted)} of {len(rows)} objects lifted)"
    return every, summary


if __name__ == "__main__":
    main()
