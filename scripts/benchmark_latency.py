"""Image to first trajectory: the pick's latency end to end and each stage's share, one pick at a time.

Each pick is evaluate.py's (diagrams/evaluation.py run_trial in a worker process: torch, BLAS and OpenMP on one
thread, the stages' independent pieces on two threads: systems/parallel.py), run one after another so that no two
share the CPU. Image to first trajectory is the wall time from the camera latch taking the frame to the end of the
first successful plan after it (the supervisor's reads, the simulator's steps between the stages and every failed
plan before it included); a pick that failed counts until the plan or the perception result that failed. It is not
a sum of the stage timers: what the stages' medians leave of it is shown as "between the stages". Nothing is kept
from one pick to the next but what is built before the image (the diagram, its IK seed table), which is not
counted (diagrams/benchmarks/latency.py).

python scripts/benchmark_latency.py --json latency.json          # 30 picks of both categories, about 8 min
python scripts/benchmark_latency.py --unseen 0 --yaws 0          # the test instances at yaw 0 alone
"""

import argparse
import sys
from pathlib import Path

from diagrams.benchmarks import latency
from diagrams.campaign import run_campaign
from diagrams.cli import add_sensor_option, write_json
from diagrams.evaluation import PAPER_YAWS
from systems.parallel import THREADS


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--yaws", type=float, nargs="+", default=list(PAPER_YAWS), help="test instances' yaws, rad")
    parser.add_argument(
        "--unseen", type=int, default=6, help=f"unseen instances per category (extra_{latency.FIRST_UNSEEN}..)"
    )
    parser.add_argument("--json", type=Path, help="write the summary and every pick's record as JSON")
    parser.add_argument("--figure", type=Path, help="PNG figure (default: --json's name, .png)")
    add_sensor_option(parser)
    args = parser.parse_args(argv)
    if args.unseen < 0:
        parser.error("--unseen must be >= 0")
    if args.figure is None and args.json is not None:
        args.figure = args.json.with_suffix(".png")
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        trials = latency.latency_trials(args.yaws, args.unseen, args.sensor)
    except (ValueError, FileNotFoundError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    sensor = trials[0].scenario.camera_noise.preset
    print(f"{len(trials)} picks one at a time (sensor {sensor}), each in a worker process with torch, BLAS and "
          f"OpenMP on one thread and the stages' independent pieces on {THREADS} threads, as evaluate.py runs "
          "them")  # fmt: skip
    records = run_campaign(trials, jobs=1, describe=latency.describe)
    summary = latency.summarize(records)
    latency.print_table(summary, sensor)
    if args.json:
        write_json(args.json, {**summary, "sensor": sensor, "targets_s": latency.TARGETS_S, "records": records})
    if args.figure:
        latency.draw_figure(args.figure, records)
    return 0


if __name__ == "__main__":
    sys.exit(main())
