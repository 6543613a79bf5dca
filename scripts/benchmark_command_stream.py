"""How regularly the arm command stream sends on this machine, with nothing else of the pick running.

The pick's arm commands go out from a process of their own (systems/robot_io/command_stream.py: real-time
priority where the OS allows, no garbage collector). Its largest gap between two sends during a pick
is bounded below by how late the OS wakes such a process at all. This runs the same CommandStream on an
in-memory LCM bus (memq://, no network), idle and then beside busy processes (one per core, each
running Python and large numpy arrays: the load of a pick that perceives and plans), and reports the
gaps and the CPU time the hypervisor took (steal, from /proc/stat, on a VM): diagrams/benchmarks/command_stream.py.

python scripts/benchmark_command_stream.py --seconds 60 --json stream.json
"""

import argparse
import os
from pathlib import Path

from diagrams.benchmarks.command_stream import benchmark
from diagrams.cli import write_json


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=30.0, help="length of each run, s")
    parser.add_argument("--load", type=int, default=os.cpu_count(), help="busy processes in the loaded run")
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    report = benchmark(args.seconds, args.load)
    if args.json:
        write_json(args.json, report)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
