"""The robot driver emulator: the simulated Centauro, hands and camera, speaking only LCM.

python scripts/robot_driver.py --lcm-url udpm://239.255.76.67:7667?ttl=0 --object watering_can --instance test_0
python scripts/robot_driver.py --duration 30 --result driver.json   # stop after 30 s, report the lift
python scripts/robot_driver.py --state driver_state.json --resume    # go on from a killed driver's world

It runs in real time until --duration or SIGINT/SIGTERM, logging its links' health every
few seconds. Nothing of the simulator's ground truth goes on the bus; --result writes the
ground-truth judgement of the lift, or of the clear with --task clear (for tests and scripts/pick.py --spawn-driver).
Use udpm:// only inside a private network namespace (see README, "LCM backend"). --state writes the
driver's world and last commands every STATE_PERIOD_S; --resume starts from that file where it exists (its clock,
its world, its commands, and the judge's references from the scene the first driver settled).
"""

import argparse
import logging
import signal
import sys
from pathlib import Path

from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator

from diagrams.clear_judge import ClearJudge
from diagrams.cli import add_scenario_options, scenario_from_args, write_json
from diagrams.pick_simulation import SAMPLE_S, SETTLED_S, LiftJudge, station_plant
from diagrams.robot_driver import (
    COMMAND_MONITORS,
    MakeRobotDriver,
    driver_state,
    read_driver_state,
    resume_driver,
    world_state,
    write_driver_state,
)
from diagrams.station import drop_zone

HEALTH_LOG_S = 5.0
STATE_PERIOD_S = 0.1  # how often --state is written, of the driver's clock, s


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scenario_options(parser)
    parser.add_argument("--lcm-url", dest="lcm_url", help="LCM bus (default: the scenario's lcm.lcm_url)")
    parser.add_argument("--duration", type=float, default=float("inf"), help="stop after this many seconds")
    parser.add_argument("--realtime", type=float, default=1.0, help="target real-time rate")
    parser.add_argument("--result", type=Path, help="write the ground-truth outcome (JSON) when stopping")
    parser.add_argument("--state", type=Path, help="write the driver's world and commands here as it runs")
    parser.add_argument("--resume", action="store_true", help="start from the --state file's world, if it exists")
    return parser.parse_args(argv)


def main(argv=None) -> int:
    logging.basicConfig(level=logging.INFO, format="driver: %(message)s")
    args = parse_args(argv)
    scenario = scenario_from_args(args)
    lcm = DrakeLcm(args.lcm_url) if args.lcm_url else DrakeLcm(scenario.lcm)
    resumed = read_driver_state(args.state, scenario) if args.resume and args.state and args.state.is_file() else None
    driver = MakeRobotDriver(scenario, lcm, commands=resumed.commands if resumed else None)
    simulator = Simulator(driver)
    simulator.set_target_realtime_rate(args.realtime)
    context = simulator.get_mutable_context()
    plant = station_plant(driver)
    if scenario.task == "clear":
        judge = ClearJudge(plant, context, scenario, drop_zone(scenario))
    else:
        judge = LiftJudge(plant, context)
    settled = None  # the world once the scene has settled (the judge's references), for a driver resumed later
    if resumed:
        resume_driver(driver, context, resumed, judge)
        settled = resumed.settled_state
        logging.info("resuming from %s at t = %.2f s", args.state, resumed.time_s)
    stop = {"requested": False}
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.update(requested=True))
    monitors = [driver.GetSubsystemByName(name) for name in COMMAND_MONITORS]
    logging.info("serving %s on %s", scenario.object.instance, lcm.get_lcm_url())
    simulator.Initialize()
    start, step = context.get_time(), 0
    while not stop["requested"] and (t := start + (step + 1) * SAMPLE_S) <= start + args.duration:
        step += 1
        simulator.AdvanceTo(t)
        judge.sample(t)
        if settled is None and t >= SETTLED_S:
            settled = world_state(driver, context)
        if args.state and step % round(STATE_PERIOD_S / SAMPLE_S) == 0:
            write_driver_state(args.state, driver_state(driver, context, settled))
        if step % round(HEALTH_LOG_S / SAMPLE_S) == 0:
            for monitor in monitors:
                health = monitor.GetOutputPort("health").Eval(monitor.GetMyContextFromRoot(context))
                logging.info(
                    "t = %5.1f s  %s: %d commands, %d rejected%s",
                    t, health.channel, health.received, health.rejected, ", stale" if health.stale else "",
                )  # fmt: skip
    outcome = judge.outcome()
    logging.info("stopped at t = %.2f s: %s (lift %.3f m)", context.get_time(), outcome.message, outcome.lift_height_m)
    if args.result:
        rejected = {
            m.get_name(): m.GetOutputPort("health").Eval(m.GetMyContextFromRoot(context)).rejected for m in monitors
        }
        report = {
            "success": outcome.success,
            "lift_height_m": outcome.lift_height_m,
            "min_hold_height_m": outcome.min_hold_height_m,
            "hands_in_contact": outcome.hands_in_contact,
            "message": outcome.message,
            "sim_time_s": context.get_time(),
            "rejected_commands": rejected,
            "clear": outcome.clear,
        }
        write_json(args.result, report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
