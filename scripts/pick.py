"""Runs one simulated pick of the scenario's object and reports the outcome.

python scripts/pick.py                               # autonomous pick, default scenario
python scripts/pick.py --oracle                      # ground-truth pick (true pose and grasps)
python scripts/pick.py --oracle --object drill --instance test_1 --yaw 0.25 --json r.json
python scripts/pick.py --oracle --object-file my_can.sdf --object watering_can
python scripts/pick.py --oracle --meshcat --record pick.html
"""

import argparse
import dataclasses
import json
import logging
import sys
from pathlib import Path

from pydrake.geometry import Meshcat, MeshcatParams

from diagrams.autonomous_pick import run_pick
from diagrams.oracle_pick import PlanningError
from diagrams.pick_simulation import run_oracle_pick
from diagrams.scenario import DEFAULT_SCENARIO, load_scenario, replace_object


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", type=Path, default=DEFAULT_SCENARIO, help="scenario YAML file")
    parser.add_argument("--scenario_text", default="", help="YAML overlaid on the scenario file")
    parser.add_argument("--object", help="object category (watering_can, drill)")
    parser.add_argument("--instance", help="generated instance: train_<i>, test_<i>, extra_<seed>")
    parser.add_argument("--object-file", dest="object_file", help="your own model: .sdf, .urdf, .obj/.ply/.stl")
    parser.add_argument("--yaw", type=float, help="object yaw relative to the category's presentation, rad")
    parser.add_argument("--seed", type=int, help="random seed of the run")
    parser.add_argument("--oracle", action="store_true", help="pick from the simulator's ground truth")
    parser.add_argument("--meshcat", action="store_true", help="serve a live meshcat view on localhost")
    parser.add_argument("--record", type=Path, help="write a self-contained meshcat replay (.html)")
    parser.add_argument("--json", type=Path, help="write the outcome as JSON")
    return parser.parse_args(argv)


def scenario_from_args(args):
    scenario = load_scenario(args.scenario, args.scenario_text)
    changes = {}
    if args.object:
        changes["category"] = args.object
    if args.instance:
        changes["instance"] = args.instance
    if args.object_file:
        changes["file"] = args.object_file
    if args.yaw is not None:
        changes["yaw"] = args.yaw
    scenario = replace_object(scenario, **changes)
    if args.seed is not None:
        scenario = dataclasses.replace(scenario, random_seed=args.seed)
    return scenario


def main(argv=None) -> int:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    args = parse_args(argv)
    try:
        scenario = scenario_from_args(args)
        meshcat = Meshcat(MeshcatParams(host="localhost")) if (args.meshcat or args.record) else None
        if meshcat is not None and args.meshcat:
            print(f"meshcat: {meshcat.web_url()}")
        obj = scenario.object
        print(f"object: {obj.category}/{obj.file or obj.instance}, yaw {obj.yaw:+.3f} rad")

        if args.oracle:
            outcome = run_oracle_pick(scenario, meshcat, args.record)
        else:
            outcome = run_pick(scenario, meshcat, args.record)
    except (PlanningError, ValueError, FileNotFoundError) as error:
        print(f"error: {error}", file=sys.stderr)
        outcome = None
        report = {"success": False, "error": str(error)}
    if outcome is not None:
        if outcome.stages:
            print("stage wall times: " + ", ".join(f"{name} {s:.3f} s" for name, s in outcome.stages.items()))
        print(
            f"{'SUCCESS' if outcome.success else 'FAILURE'}: {outcome.message}; lift {outcome.lift_height_m:.3f} m, "
            f"simulated {outcome.sim_time_s:.1f} s in {outcome.wall_time_s:.1f} s"
        )
        report = {
            "success": outcome.success,
            "lift_height_m": outcome.lift_height_m,
            "min_hold_height_m": outcome.min_hold_height_m,
            "hands_in_contact": outcome.hands_in_contact,
            "object": obj.category,
            "instance": obj.file or obj.instance,
            "yaw": obj.yaw,
            "seed": scenario.random_seed,
            "mode": "oracle" if args.oracle else "autonomous",
            "planning_s": outcome.planning_s,
            "stages": outcome.stages,
            "failed_stage": outcome.failed_stage,
            "sim_wall_s": outcome.wall_time_s,
            "message": outcome.message,
        }
    if args.json:
        args.json.write_text(json.dumps(report, indent=2))
    return 0 if report["success"] else 1


if __name__ == "__main__":
    sys.exit(main())
