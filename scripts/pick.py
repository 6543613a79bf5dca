"""Runs one simulated pick of the scenario's object and reports the outcome.

python scripts/pick.py                               # autonomous pick, default scenario
python scripts/pick.py --oracle                      # the same diagram, ground truth in place of perception
python scripts/pick.py --oracle --object drill --instance test_1 --yaw 0.25 --json r.json
python scripts/pick.py --oracle --object-file my_can.sdf --object watering_can
python scripts/pick.py --oracle --meshcat --record pick.html
python scripts/pick.py --object pot --object-file my_pot.obj       # a category taught by add_category.py
python scripts/pick.py --object drill --task aim     # aim the drill's bit at the board's target (docs/use.md)
python scripts/pick.py --task pour                   # pour from the can into a bowl or pot beside it (docs/use.md)
"""

import argparse
import logging
import math
import sys
from pathlib import Path

from pydrake.geometry import Meshcat, MeshcatParams

from diagrams import lcm_pick
from diagrams.autonomous_pick import run_pick
from diagrams.cli import add_scenario_options, scenario_arguments, scenario_from_args, write_json
from diagrams.hardware_station import RobotNotResponding
from diagrams.scenario import clutter_name
from systems.planning.pick_motions import PlanningError
from systems.robot_io.gravity_compensation import SimulationDiverged


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scenario_options(parser)
    parser.add_argument(
        "--oracle",
        action="store_true",
        help="the same pick diagram with the object's true grasp frames and surface in place of perception",
    )
    parser.add_argument("--meshcat", action="store_true", help="serve a live meshcat view on localhost")
    parser.add_argument("--record", type=Path, help="write a self-contained meshcat replay (.html)")
    parser.add_argument("--json", type=Path, help="write the outcome as JSON")
    parser.add_argument(
        "--backend",
        choices=("sim", "lcm"),
        default="sim",
        help="sim: the simulated station; lcm: the hardware station, against a robot over LCM",
    )
    parser.add_argument("--lcm-url", dest="lcm_url", help="LCM bus of --backend lcm (default: the scenario's)")
    parser.add_argument(
        "--spawn-driver",
        dest="spawn_driver",
        action="store_true",
        help="with --backend lcm: start scripts/robot_driver.py as a subprocess, both in a private "
        "loopback-only network namespace (in-process over memq:// where namespaces are unavailable)",
    )
    parser.add_argument("--in-namespace", dest="in_namespace", action="store_true", help=argparse.SUPPRESS)
    return parser.parse_args(argv)


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
        if scenario.clutter:
            print(f"on the table too: {', '.join(clutter_name(other) for other in scenario.clutter)}")

        if args.backend == "sim":
            perception = "ground_truth" if args.oracle else "camera"
            outcome = run_pick(scenario, meshcat, args.record, perception=perception)
        elif args.spawn_driver and not args.in_namespace and lcm_pick.namespaces_available():
            return lcm_pick.rerun_in_private_namespace(sys.argv)
        elif args.spawn_driver and not args.in_namespace:
            logging.warning("no private network namespace here: the driver runs in-process over memq://")
            outcome = run_pick(scenario, meshcat, args.record, backend="lcm-memq")
        elif args.spawn_driver:
            outcome = lcm_pick.run_with_spawned_driver(scenario, scenario_arguments(args))
        else:
            outcome = lcm_pick.run_on_robot(scenario, args.lcm_url, meshcat)
    except (PlanningError, ValueError, FileNotFoundError, RobotNotResponding, SimulationDiverged) as error:
        print(f"error: {error}", file=sys.stderr)
        outcome = None
        report = {"success": False, "error": str(error)}
    if outcome is not None:
        if outcome.stages:
            print("stage wall times: " + ", ".join(f"{name} {s:.3f} s" for name, s in outcome.stages.items()))
        summary = f"{'SUCCESS' if outcome.success else 'FAILURE'}: {outcome.message}"
        if outcome.use.get("axis_error_rad") is not None:
            use = outcome.use
            nearest, farthest = use["tip_off_surface_m"]
            summary += (
                f"; bit {math.degrees(use['axis_error_rad']):.1f} deg off the normal, tip "
                f"{1000 * use['tip_to_target_m']:.1f} mm from the target, {1000 * nearest:.1f}-{1000 * farthest:.1f} "
                "mm off the board"
            )
        if outcome.use.get("outflow_elevation_rad") is not None:
            use = outcome.use
            summary += (
                f"; spout tip {100 * use['tip_from_centre_m']:.1f} cm from the opening's centre, "
                f"{100 * use['tip_above_rim_m']:.1f} cm above its rim, outflow "
                f"{-math.degrees(use['outflow_elevation_rad']):.1f} deg down, the container moved "
                f"{1000 * use['container_moved_m']:.1f} mm"
            )
        if outcome.place:
            place = outcome.place
            summary += (
                f"; {100 * place['error_m']:.1f} cm, {math.degrees(place['yaw_error_rad']):.1f} deg from the target"
            )
        elif outcome.clear:
            summary += f"; {outcome.clear['summary']}"
        elif math.isfinite(outcome.lift_height_m):  # unknown against a real robot
            summary += f"; lift {outcome.lift_height_m:.3f} m"
        if outcome.sim_time_s > 0:
            summary += f", simulated {outcome.sim_time_s:.1f} s in {outcome.wall_time_s:.1f} s"
        print(summary)
        report = {
            "success": outcome.success,
            "lift_height_m": outcome.lift_height_m,  # NaN (null) against a real robot
            "min_hold_height_m": outcome.min_hold_height_m,
            "hands_in_contact": outcome.hands_in_contact,
            "object": obj.category,
            "instance": obj.file or obj.instance,
            "yaw": obj.yaw,
            "seed": scenario.random_seed,
            "mode": "oracle" if args.oracle else "autonomous",
            "backend": args.backend,
            "sensor": scenario.camera_noise.preset,  # the simulated camera's (a real robot's camera is real)
            "planning_s": outcome.planning_s,
            "stages": outcome.stages,
            "closure": outcome.closure,
            "closure_executed": outcome.closure_executed,
            "commands": outcome.commands,
            "task": scenario.task,
            "place": outcome.place,
            "use": outcome.use,
            "clear": outcome.clear,
            "waits": outcome.waits,
            "perception": outcome.perception,
            "others_moved_m": outcome.others_moved_m,  # each other object's largest move (ground truth)
            "failed_stage": outcome.failed_stage,
            "attempts_made": outcome.attempts_made,
            "attempt_failures": outcome.attempt_failures,
            "sim_wall_s": outcome.wall_time_s,
            "message": outcome.message,
        }
    if args.json:
        write_json(args.json, report)
    return 0 if report["success"] else 1


if __name__ == "__main__":
    sys.exit(main())
