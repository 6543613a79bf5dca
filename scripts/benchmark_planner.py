"""Benchmarks STOMP on seeded families of planning problems, beside OMPL and Drake's KinematicTrajectoryOptimization.

Families (diagrams/generation/planning_problems.py; problem k of a family and split is made from its seed alone):
  lift, carry, turn, set_down: held moves of an object both hands hold (closure and hand orientation kept, the
      object kept clear), with 0-3 boxes standing or hanging where the object's straight path goes;
  reach: both hands to their pre-grasps from under the table or the ready pose, past boxes;
  aim: a held drill turned and moved until its bit points at a board's target, 5 mm off it (the board a box);
  pour: a held can turned, carried over a bowl or pot and tilted until it pours, its spout's tip over the opening
      (the container a box; the closure kept, the hands' orientation free).
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
ablations) run on the first --peer-problems problems; ratios are taken on the problems both planners ran
(diagrams/benchmarks/planner.py, planner_peers.py).

python scripts/benchmark_planner.py --family carry --problems 200 --split report --json carry.json
"""

import argparse
import logging
import time
from pathlib import Path

from diagrams.benchmarks.planner import PLANNERS, TIME_LIMIT_S, draw, print_family, run_family
from diagrams.benchmarks.planner_peers import OmplConfig
from diagrams.cli import write_json
from diagrams.generation.planning_problems import DRAWN_WITH, FAMILIES, SPLITS
from diagrams.planning_scene import make_pick_motions
from diagrams.scenario import load_scenario


def main():
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--family", nargs="+", choices=FAMILIES, default=list(FAMILIES))
    parser.add_argument("--problems", type=int, default=200, help="the first N kept problems of the split")
    parser.add_argument("--split", choices=SPLITS, default="report")
    parser.add_argument("--planners", nargs="+", choices=PLANNERS, default=list(PLANNERS))
    parser.add_argument("--peer-problems", type=int, default=40, help="the slow planners run on the first N")
    defaults = OmplConfig()
    parser.add_argument("--ompl-space", choices=("projected", "atlas"), default=defaults.space)
    parser.add_argument("--ompl-range", type=float, default=defaults.range, help="RRTConnect's range (0: default)")
    parser.add_argument("--ompl-delta", type=float, default=defaults.delta, help="step along the manifold")
    parser.add_argument("--ompl-tolerance", type=float, default=defaults.tolerance)
    parser.add_argument("--ompl-bounds-margin", type=float, default=defaults.bounds_margin)
    parser.add_argument("--figure-dir", type=Path, help="writes <family>.png there")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    motions = make_pick_motions(load_scenario(), DRAWN_WITH)
    print(f"threads: this process, one problem at a time; time limit {TIME_LIMIT_S:.0f} s per planner and problem")
    results = {}
    for family in args.family:
        start = time.perf_counter()
        results[family] = run_family(args, motions, family)
        print_family(family, results[family])
        print(f"({time.perf_counter() - start:.0f} s)")
        if args.figure_dir:
            args.figure_dir.mkdir(parents=True, exist_ok=True)
            draw(family, results[family], args.figure_dir / f"planner_{family}.png")
    if args.json:
        write_json(args.json, results)


if __name__ == "__main__":
    main()
