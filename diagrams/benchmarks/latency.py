"""Image to first trajectory: the pick's latency end to end and each stage's share, one pick at a time
(scripts/benchmark_latency.py).

Each pick is evaluate.py's (diagrams/evaluation.py run_trial in a worker process: torch, BLAS and OpenMP on one
thread, the stages' independent pieces on two threads: systems/parallel.py), run one after another so that no two
share the CPU. Image to first trajectory is the wall time from the camera latch taking the frame to the end of the
first successful plan after it (the supervisor's reads, the simulator's steps between the stages and every failed
plan before it included); a pick that failed counts until the plan or the perception result that failed. It is not
a sum of the stage timers: what the stages' medians leave of it is shown as "between the stages". Nothing is kept
from one pick to the next but what is built before the image (the diagram, its IK seed table), which is not
counted.
"""

import dataclasses
from pathlib import Path

import numpy as np

from diagrams.cli import with_sensor
from diagrams.evaluation import PAPER_CATEGORIES, PAPER_YAW_NOISE, generated_objects, make_trials
from diagrams.scenario import DEFAULT_SCENARIO, load_scenario

STAGES = ("segmentation", "pose", "registration", "planning")
# The unseen instances: extra_<FIRST_UNSEEN + k>, a range no other figure uses.
FIRST_UNSEEN = 401
# Issue 38's targets, s (medians unless named).
TARGETS_S = {"image_to_trajectory": 0.4, "image_to_trajectory_p95": 0.8, "segmentation": 0.04, "pose": 0.015,
             "registration": 0.12, "planning": 0.25}  # fmt: skip
PAPER_IMAGE_TO_TRAJECTORY_S = 6.27  # the paper's Table III, the real robot


def latency_trials(yaws: list[float], unseen: int, sensor: str | None) -> list:
    """Per category: the test instances at each yaw, then `unseen` unseen instances at yaw 0."""
    base = with_sensor(load_scenario(DEFAULT_SCENARIO), sensor)
    trials = []
    for category in PAPER_CATEGORIES:
        trials += make_trials(base, category, generated_objects(category), 1, yaws, PAPER_YAW_NOISE)
        extras = {
            f"extra_{FIRST_UNSEEN + k}": {"instance": f"extra_{FIRST_UNSEEN + k}", "file": ""} for k in range(unseen)
        }
        if extras:
            trials += make_trials(base, category, extras, 1, [0.0], PAPER_YAW_NOISE)
    # One seed per pick across both categories.
    return [
        dataclasses.replace(t, scenario=dataclasses.replace(t.scenario, random_seed=n)) for n, t in enumerate(trials)
    ]


def summarize(records: list[dict]) -> dict:
    """The JSON's top level: medians (and the end to end's 95th percentile) over every pick that timed them."""

    def seconds(stage: str) -> np.ndarray:
        return np.array([r["stages"][stage] for r in records if stage in r["stages"]])

    end_to_end = seconds("image_to_trajectory")
    summary = {
        "picks": len(records),
        "lifted": int(sum(r["success"] for r in records)),
        "image_to_trajectory_s_median": float(np.median(end_to_end)) if len(end_to_end) else float("nan"),
        "image_to_trajectory_s_p95": float(np.percentile(end_to_end, 95)) if len(end_to_end) else float("nan"),
    }
    for stage in STAGES:
        values = seconds(stage)
        summary[f"{stage}_s_median"] = float(np.median(values)) if len(values) else float("nan")
        summary[f"{stage}_s_p95"] = float(np.percentile(values, 95)) if len(values) else float("nan")
    between = [
        r["stages"]["image_to_trajectory"] - sum(r["stages"].get(s, 0.0) for s in STAGES)
        for r in records
        if "image_to_trajectory" in r["stages"]
    ]
    summary["between_stages_s_median"] = float(np.median(between)) if between else float("nan")
    return summary


def print_table(summary: dict, sensor: str):
    """Each stage's median and 95th percentile beside its target and its share of the end to end time."""
    print(f"\nImage to first trajectory, {summary['picks']} picks one at a time (sensor {sensor}; "
          f"lifted {summary['lifted']}); seconds")  # fmt: skip
    print(f"{'stage':<24}{'median':>9}{'p95':>9}{'target':>9}{'share':>8}")
    total = summary["image_to_trajectory_s_median"]
    for stage in STAGES:
        median, p95 = summary[f"{stage}_s_median"], summary[f"{stage}_s_p95"]
        print(f"{stage:<24}{median:>9.3f}{p95:>9.3f}{TARGETS_S[stage]:>9.3f}{100 * median / total:>7.0f}%")
    between = summary["between_stages_s_median"]
    print(f"{'between the stages':<24}{between:>9.3f}{'':>9}{'':>9}{100 * between / total:>7.0f}%")
    print(f"{'image to trajectory':<24}{total:>9.3f}{summary['image_to_trajectory_s_p95']:>9.3f}"
          f"{TARGETS_S['image_to_trajectory']:>9.3f}    (p95 target {TARGETS_S['image_to_trajectory_p95']:.1f} s; "
          f"paper {PAPER_IMAGE_TO_TRAJECTORY_S} s)")  # fmt: skip


def draw_figure(path: Path, records: list[dict]):
    """Each pick's end to end latency as stacked stage times, slowest on top, with the 0.4 s target."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    timed = sorted((r for r in records if "image_to_trajectory" in r["stages"]),
                   key=lambda r: r["stages"]["image_to_trajectory"])  # fmt: skip
    figure, axes = plt.subplots(figsize=(9, 0.25 * len(timed) + 1.5))
    left = np.zeros(len(timed))
    for stage in STAGES:
        widths = np.array([r["stages"].get(stage, 0.0) for r in timed])
        axes.barh(range(len(timed)), widths, left=left, label=stage)
        left += widths
    rest = np.array([r["stages"]["image_to_trajectory"] for r in timed]) - left
    axes.barh(range(len(timed)), rest, left=left, label="between the stages", color="lightgrey")
    axes.axvline(TARGETS_S["image_to_trajectory"], color="k", linestyle="--", linewidth=1, label="target 0.4 s")
    labels = [f"{r['category'][:5]} {r['name']} {r['yaw']:+.2f}" + ("" if r["success"] else " (failed)") for r in timed]
    axes.set_yticks(range(len(timed)), labels, fontsize=7)
    axes.set_xlabel("wall time from the latched image [s]")
    axes.set_title(f"image to first trajectory, {len(timed)} picks one at a time")
    axes.legend(fontsize=8, loc="lower right")
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    print(f"wrote {path}")


def describe(record: dict) -> str:
    """A pick's line above the progress bar."""
    outcome = "lifted" if record["success"] else f"FAILED at {record['failed_stage']}"
    latency = record["stages"].get("image_to_trajectory", float("nan"))
    name = f"{record['category']} {record['name']} yaw {record['yaw']:+.2f}"
    return f"{name}: {outcome}, image to trajectory {latency:.3f} s"
