"""How regularly the arm command stream sends on this machine, with nothing else of the pick running
(scripts/benchmark_command_stream.py).

The pick's arm commands go out from a process of their own (systems/robot_io/command_stream.py: real-time
priority where the OS allows, no garbage collector). Its largest gap between two sends during a pick
is bounded below by how late the OS wakes such a process at all. This runs the same CommandStream on an
in-memory LCM bus (memq://, no network), idle and then beside busy processes (one per core, each
running Python and large numpy arrays: the load of a pick that perceives and plans), and reports the
gaps and the CPU time the hypervisor took (steal, from /proc/stat, on a VM).
"""

import multiprocessing
import os
import platform
import time
from pathlib import Path

import numpy as np

from systems.robot_io.command_stream import CommandStream

PERIOD_S = 0.005  # the scenario's hardware.control_period_s
JOINTS = 15  # the arms and the torso


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


def benchmark(seconds: float, load: int) -> dict:
    """A run idle and one beside `load` busy processes, each `seconds` long, printed as a table; the report."""
    rows = []
    for busy in (0, load):
        print(f"streaming every {1000 * PERIOD_S:.0f} ms for {seconds:.0f} s beside {busy} busy process(es) ...")
        rows.append(run(seconds, busy))
    print(f"\n{'busy processes':>15} {'sent':>7} {'late (> 2 periods)':>19} {'largest gap [ms]':>17} {'steal [s]':>10}")
    for row in rows:
        print(f"{row['busy_processes']:>15} {row['sent']:>7} {row['late']:>19} {1000 * row['max_gap_s']:>17.1f} "
              f"{row['steal_s']:>10.2f}")  # fmt: skip
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    return {"period_s": PERIOD_S, "machine": machine, "runs": rows}
