"""Runs one simulated pick of the scenario's object and reports the outcome.

python scripts/pick.py --oracle                      # ground-truth pick, default scenario
python scripts/pick.py --oracle --object drill --instance test_1 --yaw 0.25 --json r.json
python scripts/pick.py --oracle --object-file my_can.sdf --object watering_can
python scripts/pick.py --oracle --meshcat --record pick.html
"""

import argparse
import dataclasses
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat, MeshcatParams

from diagrams.hand_ik import DualArmIk
from diagrams.objects.library import resolve_object
from diagrams.oracle_pick import PlanningError, plan_oracle_pick
from diagrams.pick_simulation import MakeOracleDiagram, simulate_pick
from diagrams.scenario import DEFAULT_SCENARIO, load_scenario, replace_object
from diagrams.station import object_pose_on_table


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
    if not args.oracle:
        print(
            "error: the autonomous pipeline (segmentation, registration, STOMP) is not built yet; "
            "run with --oracle for the ground-truth pick",
            file=sys.stderr,
        )
        return 2
    try:
        scenario = scenario_from_args(args)
        meshcat = Meshcat(MeshcatParams(host="localhost")) if (args.meshcat or args.record) else None
        if meshcat is not None and args.meshcat:
            print(f"meshcat: {meshcat.web_url()}")
        obj = scenario.object
        print(f"object: {obj.category}/{obj.file or obj.instance}, yaw {obj.yaw:+.3f} rad")

        model = resolve_object(obj)
        # Ground truth: the pose the station places the object at (before it settles).
        X_WO = object_pose_on_table(scenario, model)
        info = model.info
        if info is None:
            raise PlanningError(f"{obj.file} has no grasp frames (info.yaml beside it): the oracle needs them")
        start = time.perf_counter()
        ik = DualArmIk(scenario)
        plan = plan_oracle_pick(ik, np.array(scenario.initial_arm_positions), X_WO, info)
        planning_s = time.perf_counter() - start
        print(f"planned in {planning_s:.2f} s: {plan.duration:.1f} s of motion")
        diagram = MakeOracleDiagram(scenario, plan, meshcat)
        outcome = simulate_pick(diagram, scenario, plan.duration, meshcat, args.record)
    except (PlanningError, ValueError, FileNotFoundError) as error:
        print(f"error: {error}", file=sys.stderr)
        outcome = None
        report = {"success": False, "error": str(error)}
    if outcome is not None:
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
            "mode": "oracle",
            "planning_s": planning_s,
            "sim_wall_s": outcome.wall_time_s,
            "message": outcome.message,
        }
    if args.json:
        args.json.write_text(json.dumps(report, indent=2))
    return 0 if report["success"] else 1


if __name__ == "__main__":
    sys.exit(main())
