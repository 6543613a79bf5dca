"""How regularly the arm command stream sends on this machine, with nothing else of the pick running.

The pick's arm commands go out from a process of their own (systems/robot_io/command_stream.py: real-time
priority where the OS allows, no garbage collector). Its largest gap between two sends during a pick
is bounded below by how late the OS wakes such a process at all. This runs the same CommandStream on an
in-memory LCM bus (memq://, no network), idle and then beside busy processes (one per core, each
running Python and large numpy arrays: the load of a pick that perceives and plans), and reports the
gaps and the CPU time the hypervisor took (steal, from /proc/stat, on a VM).

python scripts/benchmark_command_stream.py --seconds 60 --json stream.json
"""

import argparse
import multiprocessing
import os
import platform
import time
from pathlib import Path

import numpy as np
from json_report import write_json

from systems.robot_io.command_stream import CommandStream

PERIOD_S = 0.005  # the scenario's hardware.control_period_s
JOINTS = 15  # the arms and the torso


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=30.0, help="length of each run, s")
    parser.add_argument("--load", type=int, default=os.cpu_count(), help="busy processes in the loaded run")
    parser.add_argument("--json", type=Path, help="write the results here")
    return parser.parse_args(argv)


def _spin(stop):
    """What a perceiving and planning pick does to a core: Python, and large numpy arrays made and multiplied."""
    rng = np.random.default_rng(0)
    while not stop.is_set():
        sum(i * i for i in range(10_000))
        a = rng.standard_normal((600, 600))
        (a @ a).sum()
        np.sort(rng.standard_normal(2_000_000))


def _steal_s() -> float:
    """CPU time the hypervisor took from this machine so far, s (0 where /proc/stat has no steal column)."""
    try:
        fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()
    except OSError:
        return 0.0
    return int(fields[8]) / os.sysconf("SC_CLK_TCK") if len(fields) > 8 else 0.0


def run(seconds: float, load: int) -> dict:
    """One run of the stream for `seconds` beside `load` busy processes: its send figures."""
    stop = multiprocessing.Event()
    spinners = [multiprocessing.Process(target=_spin, args=(stop,), daemon=True) for _ in range(load)]
    for spinner in spinners:
        spinner.start()
    stream = CommandStream("memq://", "BENCHMARK_COMMAND", JOINTS, PERIOD_S)
    steal = _steal_s()
    try:
        stream.set(0, np.zeros(JOINTS))
        stream.start()
        time.sleep(seconds)
    finally:
        stream.stop()
        stop.set()
        for spinner in spinners:
            spinner.join(timeout=5)
    return {
        "busy_processes": load,
        "seconds": seconds,
        "sent": stream.sends,
        "late": stream.late_sends,
        "max_gap_s": stream.max_gap_s,
        "steal_s": _steal_s() - steal,
    }


def main(argv=None) -> int:
    args = parse_args(argv)
    rows = []
    for load in (0, args.load):
        print(f"streaming every {1000 * PERIOD_S:.0f} ms for {args.seconds:.0f} s beside {load} busy process(es) ...")
        rows.append(run(args.seconds, load))
    print(f"\n{'busy processes':>15} {'sent':>7} {'late (> 2 periods)':>19} {'largest gap [ms]':>17} {'steal [s]':>10}")
    for row in rows:
        print(f"{row['busy_processes']:>15} {row['sent']:>7} {row['late']:>19} {1000 * row['max_gap_s']:>17.1f} "
              f"{row['steal_s']:>10.2f}")  # fmt: skip
    if args.json:
        machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
        write_json(args.json, {"period_s": PERIOD_S, "machine": machine, "runs": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
