"""The report of a campaign of picks (scripts/evaluate.py): the success table (Table II form) and the per-component
runtime table (Table III form) of the paper's placements, the tables of random placements and cluttered tables, the
JSON with every record, and a PNG figure (or, for random placements, a map of the table region).
"""

import dataclasses
import math
import platform
from dataclasses import dataclass, field
from pathlib import Path

from diagrams.cli import write_json
from diagrams.evaluation import (
    COMPONENTS,
    OTHERS_MOVED_LIMIT_M,
    PAPER_YAW_NOISE,
    PAPER_YAWS,
    TIMED_STAGES,
    summarize,
)

# The paper's figures (Table II: the three test cans; Table III: the real robot's pipeline, s).
PAPER_CAN_SUCCESS = {"test_0": 0.75, "test_1": 1.00, "test_2": 0.60}
PAPER_RUNTIME_S = {"segmentation": 0.74, "pose": 0.12, "registration": 4.51, "planning": 0.96,
                   "image_to_trajectory": 6.27}  # fmt: skip
# What the project must reach (SPEC): success on every object.
TARGET_SUCCESS = {"watering_can": 0.95, "drill": 0.90}
STAGE_LABELS = {
    "segmentation": "semantic segmentation",
    "pose": "pose estimation",
    "registration": "grasp generation (registration)",
    "planning": "trajectory optimization (the reach)",
    "grasp": "grasp (both hands hold something)",
    "image_to_trajectory": "complete pipeline (image to trajectory; pick)",
    "execution": "execution (lifted and held by both hands)",
}


@dataclass
class CampaignSettings:
    """What a campaign was, as its report states it (evaluate.py's options)."""

    category: str = "watering_can"
    task: str = "lift"  # or "place"
    obstacle: bool = False  # the category's place_over_box layout
    trials: int = 3  # per object and yaw
    yaws: list[float] = field(default_factory=lambda: list(PAPER_YAWS))  # rad
    yaw_noise: float = PAPER_YAW_NOISE  # the registration's yaw noise, +-rad
    sensor: str | None = None  # the RGB-D sensor model's preset
    jobs: int = 1  # picks at a time
    ray: str | None = None  # the Ray cluster's address ("": a local Ray); None: worker processes


def recorded_campaign(records: list[dict], given: CampaignSettings) -> CampaignSettings:
    """The campaign a records file says it was: what its records share (older records may lack some: `given`'s
    stand), its yaws and its trials per object and yaw."""
    first = records[0]
    return dataclasses.replace(
        given,
        category=first.get("category", given.category),
        task=first.get("task", given.task),
        obstacle=first.get("obstacle", given.obstacle),
        yaw_noise=first.get("yaw_noise_rad", given.yaw_noise),
        sensor=first.get("sensor", "perfect"),  # (records from before the sensor model: the renderer's images)
        yaws=list(dict.fromkeys(r["yaw"] for r in records)),
        trials=1 + max(r["trial"] for r in records),
    )


def describe(record: dict) -> str:
    """A pick's line above the progress bar: where it was, and its outcome."""
    offset = record["registration_yaw_offset_rad"]
    head = f"{record['name']} yaw {record['yaw']:+.2f} #{record['trial']} (offset {offset:+.3f})"
    if "oracle" in record:
        truth = record["oracle"]
        head += " [ground truth: " + ("lifted" if truth["success"] else f"FAILED at {truth['failed_stage']}") + "]"
    if record["success"] and record.get("place"):
        place = record["place"]
        off = f"{100 * place['error_m']:.1f} cm and {math.degrees(place['yaw_error_rad']):.1f} deg"
        return f"{head}: SUCCESS, placed {off} off"
    if record["success"]:
        return f"{head}: SUCCESS, lift {record['lift_height_m']:.3f} m, image to trajectory " + (
            f"{record['stages']['image_to_trajectory']:.2f} s"
        )
    return f"{head}: FAILED at {record['failed_stage']}: {record['message']}"


def _rate_cell(rate: float, attempts: int) -> str:
    return f"{100 * rate:.0f} % ({attempts})"


def _per_yaw_header(title: str, width: int, per_instance: dict) -> str:
    yaws = next(iter(per_instance.values()))["per_yaw"].keys()
    return f"{'object':<{width}}{title:>20}" + "".join(f"{'yaw ' + y:>12}" for y in yaws)


def _per_yaw_row(name: str, row: dict, width: int) -> str:
    """One object's line of a Table II form table: its rate (attempts), then its rate at each yaw."""
    cells = "".join(f"{100 * rate:>11.0f}%" for rate in row["per_yaw"].values())
    return f"{name:<{width}}{_rate_cell(row['success_rate'], row['attempts']):>20}{cells}"


def _always(always: list[str], objects: int) -> str:
    return f"objects with every pick a success: {len(always)}/{objects}" + (f" ({', '.join(always)})" if always else "")


def print_tables(summary: dict, category: str, trials: int, yaw_noise: float):
    """The paper's placements: the success table (Table II form) and the runtime table (Table III form)."""
    print(f"\nSuccess rate ({category}, {trials} trial(s) per yaw, yaw noise +-{yaw_noise:.2f} rad), Table II form")
    width = max(16, 2 + max(len(name) for name in summary["per_instance"]))
    print(_per_yaw_header("success (attempts)", width, summary["per_instance"]) + f"{'paper':>8}")
    for name, row in summary["per_instance"].items():
        paper = PAPER_CAN_SUCCESS.get(name) if category == "watering_can" else None
        paper_cell = f"{100 * paper:>7.0f}%" if paper is not None else f"{'-':>8}"
        print(_per_yaw_row(name, row, width) + paper_cell)
    low, high = summary["success_rate_ci95"]
    print(f"{'all':<{width}}{_rate_cell(summary['success_rate'], summary['trials']):>20}   95 % Wilson interval "
          f"{100 * low:.0f}-{100 * high:.0f} %")  # fmt: skip
    print(_always(summary["always_succeeded"], len(summary["per_instance"])))
    if "ground_truth_per_instance" in summary:
        print_ground_truth(summary, width)

    print("\nRuntime and success per component; paper Table III form (paper: real robot)")
    print(f"{'component':<46}{'runtime [s]':>18}{'median':>9}{'success':>10}{'paper [s]':>11}")
    stages = summary["stages"]
    for component in COMPONENTS + ("image_to_trajectory",):
        if component in TIMED_STAGES:
            mean, std = stages[f"{component}_s_mean"], stages[f"{component}_s_std"]
            runtime, median = f"{mean:.3f} +- {std:.3f}", f"{stages[f'{component}_s_median']:.3f}"
        else:
            runtime = median = "-"
        if component == "image_to_trajectory":
            rate = summary["success_rate"]  # the complete pipeline's success is the pick's
        else:
            rate = summary["components"][component]["success_rate"]
        paper = PAPER_RUNTIME_S.get(component)
        print(
            f"{STAGE_LABELS[component]:<46}{runtime:>18}{median:>9}{100 * rate:>8.0f} %"
            + (f"{paper:>11.2f}" if paper else f"{'-':>11}")
        )


def print_ground_truth(summary: dict, width: int):
    """--ground-truth: the same scenes picked with the true grasps, in the same form, then the autonomous pick's share
    of what ground truth lifted."""
    truth = summary["ground_truth_per_instance"]
    print("\nThe same scenes with ground truth in place of perception (what the robot can do there at all)")
    print(_per_yaw_header("lifted (attempts)", width, truth))
    for name, row in truth.items():
        print(_per_yaw_row(name, row, width))
    always = _always(summary["ground_truth_always_succeeded"], len(truth))
    print(f"ground truth: {100 * summary['oracle_success_rate']:.0f} % lifted; {always}")
    print(f"the autonomous pick lifted {100 * summary['success_rate_given_oracle']:.0f} % of what ground truth lifted")


def draw_figure(path: Path, summary: dict, records: list[dict], category: str):
    """Success per object and yaw (bars) beside the stage times (box plots, the paper's means as crosses)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    figure, (left, right) = plt.subplots(1, 2, figsize=(12, 4.5))
    names = list(summary["per_instance"])
    yaws = list(summary["per_instance"][names[0]]["per_yaw"])
    width = 0.8 / len(yaws)
    for k, yaw in enumerate(yaws):
        rates = [100 * summary["per_instance"][n]["per_yaw"][yaw] for n in names]
        left.bar(np.arange(len(names)) + (k - (len(yaws) - 1) / 2) * width, rates, width, label=f"yaw {yaw} rad")
    if category in TARGET_SUCCESS:
        left.axhline(100 * TARGET_SUCCESS[category], color="k", linestyle="--", linewidth=1, label="target")
    if category == "watering_can":
        paper = [100 * PAPER_CAN_SUCCESS[n] if n in PAPER_CAN_SUCCESS else np.nan for n in names]
        left.plot(np.arange(len(names)), paper, "rx", markersize=10, label="paper (per can)")
    left.set_xticks(np.arange(len(names)), names, rotation=20)
    left.set_ylim(0, 130)  # room for the legend above the bars
    left.set_yticks(range(0, 101, 20))
    left.set_ylabel("success rate [%]")
    left.set_title(f"{category}: {summary['trials']} picks, {100 * summary['success_rate']:.0f} % lifted")
    left.legend(fontsize=8, loc="upper center", ncol=3)

    data = [[r["stages"][s] for r in records if s in r["stages"]] for s in TIMED_STAGES]
    shown = [k for k, d in enumerate(data) if d]
    if shown:
        right.boxplot([data[k] for k in shown], positions=shown)
        right.plot(range(len(TIMED_STAGES)), [PAPER_RUNTIME_S[s] for s in TIMED_STAGES], "rx", markersize=10,
                   label="paper (real robot)")  # fmt: skip
    right.set_xticks(range(len(TIMED_STAGES)), ["segment.", "pose", "registr.", "planning", "image to traj."])
    right.set_yscale("log")
    right.set_ylabel("wall time [s]")
    right.set_title("stage runtimes")
    right.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    print(f"wrote {path}")


def _short_reason(record: dict) -> str:
    """A failure's stage and the message's gist, for tables and the map."""
    message = record["message"].split(": ", 1)[-1]
    return f"{record['failed_stage']}: {message[:70]}"


def print_clutter(summary: dict, records: list[dict], category: str):
    """The cluttered tables: each one's other objects, the outcome and the largest move of another object (a clear's
    tables: of a distractor, the familiar objects being moved on purpose)."""
    clears = "objects_cleared_share" in summary
    done = "cleared" if clears else "lifted"
    named = "every familiar object to clear" if clears else f"{category} named"
    print(f"\nCluttered tables ({named}): the other objects; the outcome; the largest move of one of them")
    for record in records:
        moved = record["clear"]["others_moved_m_max"] if clears else max(record.get("others_moved_m") or [0.0])
        outcome = done if record["success"] else _short_reason(record)
        print(f"{record['name']:<20}{', '.join(record['clutter']):<60.60} {outcome:<40.40} {100 * moved:5.1f} cm")
    low, high = summary["success_rate_ci95"]
    successes = sum(r["success"] for r in records)
    print(f"{done} {successes}/{len(records)} (95 % Wilson interval {100 * low:.0f}-{100 * high:.0f} %)")


def print_placements(summary: dict, records: list[dict], category: str):
    """The random placements: where each was, whether ground truth and the autonomous pick did it."""
    print(f"\nRandom placements ({category}): table_top frame x, y (m), yaw (rad); ground truth, then autonomous")
    print(f"{'instance':<12}{'x':>7}{'y':>7}{'yaw':>7}  {'ground truth':<14}{'autonomous':<12}attempts  failure")
    for r in records:
        oracle = r["oracle"]
        failure = _short_reason(r) if not r["success"] else ""
        if not oracle["success"]:
            failure = "ground truth " + _short_reason(oracle)
        print(f"{r['name']:<12}{r['xy'][0]:>7.3f}{r['xy'][1]:>7.3f}{r['yaw']:>7.2f}  "
              f"{'lifted' if oracle['success'] else 'FAILED':<14}{'lifted' if r['success'] else 'FAILED':<12}"
              f"{r.get('attempts_made', 1):>8}  {failure}")  # fmt: skip
    doable = sum(r["oracle"]["success"] for r in records)
    print(f"ground truth lifted {doable} of {len(records)} ({100 * summary['oracle_success_rate']:.0f} %); "
          f"the autonomous pick lifted {100 * summary['success_rate_given_oracle']:.0f} % of those, "
          f"{100 * summary['success_rate']:.0f} % of all")  # fmt: skip


def draw_map(path: Path, records: list[dict], category: str):
    """The table region seen from above: each placement's object origin and heading, coloured by outcome."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    figure, axes = plt.subplots(figsize=(9, 5.5))
    styles = {  # by (ground truth lifted, autonomous lifted)
        "lifted (ground truth and autonomous)": ("tab:green", "o", lambda truth, auto: truth and auto),
        "ground truth lifted, autonomous failed": ("tab:orange", "s", lambda truth, auto: truth and not auto),
        "ground truth failed": ("tab:red", "X", lambda truth, auto: not truth),
    }
    for label, (colour, marker, belongs) in styles.items():
        chosen = [r for r in records if belongs(r["oracle"]["success"], r["success"])]
        if not chosen:
            continue
        x, y = np.array([r["xy"][0] for r in chosen]), np.array([r["xy"][1] for r in chosen])
        yaw = np.array([r["yaw"] for r in chosen])
        # The robot looks along +x of the table_top frame: drawn upwards, its left to the left.
        axes.scatter(-y, x, c=colour, marker=marker, s=70, label=f"{label} ({len(chosen)})", zorder=3)
        axes.quiver(-y, x, -np.sin(yaw), np.cos(yaw), color=colour, scale=25, width=0.004, zorder=2)
        for r in chosen:
            failed = r["oracle"] if not r["oracle"]["success"] else (r if not r["success"] else None)
            if failed is not None:  # a planning failure by its phase (reach, approach, lift), else by its stage
                parts = failed["message"].split(": ")
                label = parts[1] if failed["failed_stage"] == "planning" and len(parts) > 1 else failed["failed_stage"]
                axes.annotate(label, (-r["xy"][1], r["xy"][0]), fontsize=6, xytext=(4, -8), textcoords="offset points")
    axes.set_xlabel("-y of the table top (m): the robot's left is to the left")
    axes.set_ylabel("x of the table top (m): away from the robot")
    axes.set_aspect("equal")
    axes.grid(alpha=0.3)
    axes.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=3)
    axes.set_title(f"{category}: {len(records)} random placements (arrows: the object's heading)")
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    print(f"wrote {path}")


def report(
    campaign: CampaignSettings,
    records: list[dict],
    first_seed: int,
    json_path: Path | None = None,
    figure_path: Path | None = None,
):
    """Prints the tables; writes the JSON (with every record) and the figure (default: the JSON's name,
    .png; without a JSON, evaluation_<category>.png)."""
    summary = summarize(records)
    # (Records from before a record said its placement: random placements were those with a ground-truth pick.)
    placements = all(r.get("placement", "random" if "oracle" in r else "paper") == "random" for r in records)
    if placements:
        print_placements(summary, records, campaign.category)
    elif any(r.get("clutter") for r in records):
        print_clutter(summary, records, campaign.category)
    else:
        print_tables(summary, campaign.category, campaign.trials, campaign.yaw_noise)
    if "others_moved_m_max" in summary and "objects_cleared_share" not in summary:
        print(
            f"\ncluttered tables: other objects moved at most {100 * summary['others_moved_m_max']:.1f} cm "
            f"({summary['picks_moving_others']} of {len(records)} picks moved one more than "
            f"{100 * OTHERS_MOVED_LIMIT_M:.0f} cm); perception took the named category in "
            f"{100 * summary['requested_category_share']:.0f} % of the picks that perceived"
        )
    if "lifts_off_handle" in summary:
        print(
            f"\ngrasps judged on the true handles in {summary['grasps_judged_on_handles']} picks: "
            f"{summary['lifts_off_handle']} lifted with a grasp off its handle (> 2.5 cm from it)"
        )
    if "tool_frames_judged" in summary:
        print(
            f"tool frames perceived in {summary['tool_frames_judged']} picks: tip "
            f"{1000 * summary['tool_tip_error_m_median']:.1f} mm, axis "
            f"{math.degrees(summary['tool_axis_error_rad_median']):.1f} deg off the true one (medians)"
        )
    if "aims_held" in summary:
        print(
            f"aims held in {summary['aims_held']} of {summary['trials']} picks, judged aimed in "
            f"{100 * summary['aimed_share']:.0f} %: bit axis {math.degrees(summary['aim_axis_error_rad_median']):.1f} "
            f"deg off the board's normal, tip {1000 * summary['aim_tip_to_target_m_median']:.1f} mm from the target "
            "(medians of each hold's worst; success also needs the drill set down where it stood)"
        )
    if "pours_held" in summary:
        print(
            f"pours held in {summary['pours_held']} of {summary['trials']} picks, judged poured in "
            f"{100 * summary['poured_share']:.0f} %: spout tip {100 * summary['pour_tip_from_centre_m_median']:.1f} "
            f"cm from the opening's centre, outflow {math.degrees(summary['pour_outflow_below_rad_median']):.0f} deg "
            "down (medians of each hold's worst; success also needs the can set down where it stood)"
        )
    if "objects_cleared_share" in summary:
        print(
            f"tables cleared: {summary['objects_cleared']} of {summary['familiar_objects']} familiar objects "
            f"({100 * summary['objects_cleared_share']:.0f} %) in the drop zone, upright and apart, over "
            f"{summary['tables']} tables ({summary['objects_cleared_per_table_mean']:.1f} per table); "
            f"{summary['attempts_per_object_mean']:.2f} attempts and {summary['sim_s_per_object_mean']:.0f} s "
            f"simulated per object taken on; a distractor moved {100 * summary['others_moved_m_max']:.1f} cm at most"
        )
    t_dev, o_dev = summary["closure_translation_dev_m_max"], summary["closure_orientation_dev_rad_max"]
    print(f"\nclosure along the played held moves (picks that lifted): largest {1000 * t_dev:.1f} mm, {o_dev:.4f} rad")
    if campaign.task == "place":
        error = summary["place_error_m_median"]
        print(f"place error, median over the picks that set the object down: {100 * error:.1f} cm")
        turn, most = summary["release_turn_rad_median"], summary["release_turn_rad_max"]
        turned = f"median {math.degrees(turn):.1f} deg, largest {math.degrees(most):.1f} deg"
        print(f"turned by letting go and backing off: {turned}")
    report = {
        "category": campaign.category,
        "task": campaign.task,
        "obstacle": campaign.obstacle,
        "placement": "random" if placements else "paper",
        "scene": "clutter" if any(r.get("clutter") for r in records) else "single",
        "trials_per_yaw": campaign.trials,
        "yaws": campaign.yaws,
        "yaw_noise_rad": campaign.yaw_noise,
        "sensor": campaign.sensor,
        "first_seed": first_seed,
        "jobs": campaign.jobs,
        "ray": campaign.ray,
        "machine": f"{platform.processor() or platform.machine()}, {platform.system()}",
        **summary,
        "records": records,
    }
    if json_path:
        write_json(json_path, report)
    figure = figure_path or (
        json_path.with_suffix(".png") if json_path else Path(f"evaluation_{campaign.category}.png")
    )
    if placements:
        draw_map(figure, records, campaign.category)
    elif report["scene"] == "clutter":  # one table each, no yaws: the tables and the JSON say it all
        print("(no figure for cluttered tables: draw one with scripts/draw_clutter_scene.py)")
    else:
        draw_figure(figure, summary, records, campaign.category)
