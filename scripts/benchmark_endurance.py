"""Endurance: one process clears tables back to back for a stated time (issue 81), sensor on.

Per task it prints the wall time, the process's resident memory, the objects cleared and (over LCM) the arm command
stream's largest gap; at the end the memory's growth from the 5th task to the last, and the slope of the tasks' wall
times with its standard error (diagrams/benchmarks/endurance.py).

python scripts/benchmark_endurance.py --minutes 60 --json endurance.json
python scripts/benchmark_endurance.py --minutes 10 --backend lcm-memq    # the hardware diagram against the emulator
"""

import argparse
import logging
from pathlib import Path

from diagrams.autonomous_pick import run_pick
from diagrams.benchmarks.endurance import run_endurance
from diagrams.cli import add_sensor_option, with_sensor, write_json
from diagrams.scenario import load_scenario


def main(argv=None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--minutes", type=float, default=60.0, help="wall time to run for (the last task ends it)")
    parser.add_argument("--tables", type=int, default=20, help="tables of the split, taken in turn")
    parser.add_argument("--split", choices=("report", "tune"), default="report")
    parser.add_argument("--max-tasks", dest="max_tasks", type=int, help="stop after this many tasks")
    parser.add_argument("--backend", choices=("sim", "lcm-memq"), default="sim")
    add_sensor_option(parser)
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    base = with_sensor(load_scenario(), args.sensor)
    report = run_endurance(
        base, args.minutes, lambda s: run_pick(s, backend=args.backend), args.tables, args.split, args.max_tasks
    )
    print(f"\n{'task':>4s} {'table':>5s} {'wall s':>7s} {'sim s':>6s} {'RSS MB':>7s} {'cleared':>8s} {'gap ms':>7s}")
    for t in report["tasks"]:
        gap = "-" if t["command_gap_ms"] is None else f"{t['command_gap_ms']:.1f}"
        cleared = f"{t['objects_cleared']}/{t['familiar_objects']}"
        print(f"{t['task']:4d} {t['table']:5d} {t['wall_s']:7.1f} {t['sim_s']:6.1f} {t['memory_mb']:7.0f} "
              f"{cleared:>8s} {gap:>7s}")  # fmt: skip
    print(
        f"memory growth from task 5 to the last: {100 * report['memory_growth_share']:+.1f} %; task time slope "
        f"{report['task_time_slope_s_per_task']:+.2f} +- {report['task_time_slope_standard_error']:.2f} s per task; "
        f"{report['failures']} tasks not fully cleared ({args.backend}, {base.camera_noise.preset} sensor)"
    )
    if args.json:
        write_json(args.json, {**report, "backend": args.backend, "sensor": base.camera_noise.preset})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
