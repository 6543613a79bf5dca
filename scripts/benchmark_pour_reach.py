"""How far the arms tilt a held watering can to pour, with the paper's grasps (issue 80's pour).

For each can, placement yaw and turn of its spout about the vertical (before the pour), the tilts about the grasps'
midpoint (the spout down, across its vertical plane) whose goal the arms reach holding the can: IK under the closure
from the held start (the can lifted 10 cm), as the planner benchmark draws its problems. Printed per row: the outflow's
elevation before the tilt, the largest tilt reached (every smaller one reached too), and where the outflow then
points (negative: below the horizontal; a pour needs -40 deg by default). The true grasps and tool frame place the
can: this measures the arms' reach, not perception.

python scripts/benchmark_pour_reach.py --json pour_reach.json
python scripts/benchmark_pour_reach.py --instances test_0 --turns -45 0 45 --tilts 15 30 45 60 75 90
"""

import argparse
import logging
import time
from pathlib import Path

from diagrams.benchmarks.pour_reach import pour_reach_rows
from diagrams.cli import write_json
from diagrams.generation.planning_problems import DRAWN_WITH
from diagrams.planning_scene import make_pick_motions
from diagrams.scenario import load_scenario


def main():
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--instances", nargs="+", default=["test_0", "test_1", "test_2"], help="watering cans")
    parser.add_argument("--yaws", type=float, nargs="+", default=[-0.25, 0.0, 0.25], help="placement yaws, rad")
    parser.add_argument("--turns", type=float, nargs="+", default=[-45.0, 0.0, 45.0], help="spout turns, deg")
    parser.add_argument("--tilts", type=float, nargs="+", default=[15.0, 30.0, 45.0, 60.0, 75.0, 90.0], help="deg")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    start = time.perf_counter()
    rows = pour_reach_rows(make_pick_motions(load_scenario(), DRAWN_WITH), args.instances, args.yaws, args.turns,
                           args.tilts)  # fmt: skip
    print(f"\n{'can':8s} {'yaw':>6s} {'turn':>5s} {'outflow':>8s} {'largest tilt':>13s} {'outflow then':>13s}")
    for row in rows:
        largest, then = row["largest_tilt_deg"], row["outflow_at_largest_deg"]
        print(
            f"{row['instance']:8s} {row['yaw_rad']:+6.2f} {row['turn_deg']:+5.0f} {row['elevation_deg']:+7.0f}° "
            f"{'none' if largest is None else f'{largest:.0f}°':>13s} {'-' if then is None else f'{then:+.0f}°':>13s}"
        )
    pours = sum(1 for row in rows if row["outflow_at_largest_deg"] is not None and row["outflow_at_largest_deg"] <= -40)
    print(f"rows whose reached tilt points the outflow 40° below the horizontal: {pours} of {len(rows)} "
          f"({time.perf_counter() - start:.0f} s)")  # fmt: skip
    if args.json:
        write_json(args.json, {"instances": args.instances, "yaws": args.yaws, "turns_deg": args.turns,
                               "tilts_deg": args.tilts, "pour_rows": pours, "rows": rows})  # fmt: skip


if __name__ == "__main__":
    main()
