"""Endurance (scripts/benchmark_endurance.py): clear tasks back to back in one process for a stated time.

Each task clears one seeded table (diagrams/generation/clear_scenes.py, table k of a split, k = 0, 1, ... wrapping
round after `tables`), simulated with the sensor model on, judged on ground truth. After each one: its wall time, the
process's resident memory (VmRSS), the objects cleared and, against the LCM backend, the arm command stream's
largest gap. The figures the issue asks for: the memory's growth from the 5th task to the last (a share of the 5th's;
the first tasks load the networks and the shape spaces), and the slope of a line fitted to the tasks' wall times
(s per task), with its standard error (the noise it is judged against).
"""

import dataclasses
import logging
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from diagrams.generation.clear_scenes import clear_scene
from diagrams.scenario import Scenario

WARM_TASKS = 5  # the memory's growth is measured from this task on (the first load what every later one uses)


def resident_memory_mb() -> float:
    """This process's resident memory (VmRSS), MB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return float(line.split()[1]) / 1024.0
    raise RuntimeError("no VmRSS in /proc/self/status")


def task_time_slope(times_s: list[float]) -> tuple[float, float]:
    """The slope of a least-squares line through the tasks' wall times (s per task) and its standard error (NaN
    with fewer than 3 tasks)."""
    n = len(times_s)
    if n < 3:
        return float("nan"), float("nan")
    x = np.arange(n, dtype=float)
    slope, intercept = np.polyfit(x, times_s, 1)
    residuals = np.asarray(times_s) - (slope * x + intercept)
    standard_error = np.sqrt(residuals @ residuals / (n - 2) / np.sum((x - x.mean()) ** 2))
    return float(slope), float(standard_error)


def run_endurance(
    base: Scenario,
    minutes: float,
    run_task: Callable[[Scenario], object],
    tables: int = 20,
    split: str = "report",
    max_tasks: int | None = None,
) -> dict:
    """Clear tables back to back until `minutes` of wall time have passed (or max_tasks); run_task(scenario) runs one
    and returns its PickOutcome. Returns {"tasks": [per task], "memory_growth_share", "task_time_slope_s_per_task",
    "task_time_slope_standard_error", "command_gap_ms_max", "failures", ...}."""
    tasks, start = [], time.perf_counter()
    while time.perf_counter() - start < 60.0 * minutes and (max_tasks is None or len(tasks) < max_tasks):
        k = len(tasks) % tables
        scenario = dataclasses.replace(clear_scene(base, k, split), random_seed=base.random_seed + k)
        began = time.perf_counter()
        outcome = run_task(scenario)
        wall = time.perf_counter() - began
        clear = outcome.clear or {}
        gap = outcome.commands.get("max_gap_s") if outcome.commands else None
        task = {
            "task": len(tasks), "table": k, "wall_s": wall, "sim_s": outcome.sim_time_s,
            "memory_mb": resident_memory_mb(), "success": outcome.success,
            "objects_cleared": clear.get("objects_cleared"), "familiar_objects": clear.get("familiar_objects"),
            "command_gap_ms": None if gap is None else 1000.0 * gap, "message": outcome.message,
        }  # fmt: skip
        tasks.append(task)
        logging.warning(
            "task %d (table %d): %.0f s wall, %.0f MB, %s/%s cleared", task["task"], k, wall, task["memory_mb"],
            task["objects_cleared"], task["familiar_objects"],
        )  # fmt: skip
    memory = [t["memory_mb"] for t in tasks]
    warm = WARM_TASKS - 1
    growth = (memory[-1] - memory[warm]) / memory[warm] if len(memory) > warm else float("nan")
    slope, error = task_time_slope([t["wall_s"] for t in tasks])
    gaps = [t["command_gap_ms"] for t in tasks if t["command_gap_ms"] is not None]
    return {
        "minutes": minutes, "split": split, "tasks": tasks, "memory_growth_share": growth,
        "task_time_slope_s_per_task": slope, "task_time_slope_standard_error": error,
        "command_gap_ms_max": max(gaps) if gaps else None,
        "failures": sum(not t["success"] for t in tasks),
    }  # fmt: skip
