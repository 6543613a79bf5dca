"""The paper's simulated experiment (§V-B, Tables II and III): autonomous picks of unseen objects.

Each object at yaw +0.25, 0 and -0.25 rad, K seeded trials each, with a yaw offset
uniform in +-0.2 rad on the pose handed to the shape registration. Prints the success
table (Table II form) and the per-component runtime table (Table III form), writes JSON
and a PNG figure.

python scripts/evaluate.py --trials 3                          # the 3 test cans, 27 picks
python scripts/evaluate.py --trials 3 --category drill --json drills.json
python scripts/evaluate.py --trials 2 --category watering_can --object-files my_cans/*.sdf
python scripts/evaluate.py --trials 3 --jobs 2                 # two picks at a time (timings then share the CPU)
python scripts/evaluate.py --trials 3 --ray --jobs 2           # as Ray tasks on a local Ray with 2 CPUs
python scripts/evaluate.py --trials 20 --ray auto --json big.json   # on the Ray cluster this machine is part of
python scripts/evaluate.py --trials 20 --ray auto --json big.json --resume  # go on where it was stopped
python scripts/evaluate.py --summarize big.jsonl --json big.json   # tables and figure from a records file
python scripts/evaluate.py --placement random --trials 40 --jobs 2 --json map.json   # 40 random placements
    (unseen extra_1000.., x +-10 cm, y +-20 cm, yaw +-0.6 rad), each also picked with ground truth; a map

Every finished pick is appended to a JSON-lines records file (--records, by default --json's name with
.jsonl) as soon as it ends, so a stopped campaign keeps what it finished and --resume runs only the rest.
"""

import argparse
import dataclasses
import logging
import math
import platform
import sys
from pathlib import Path

from campaign import read_records, run_campaign
from json_report import write_json
from scenario_options import add_sensor_option, with_sensor

from diagrams.evaluation import (
    COMPONENTS,
    OTHERS_MOVED_LIMIT_M,
    PAPER_YAW_NOISE,
    PAPER_YAWS,
    TIMED_STAGES,
    clutter_trials,
    file_objects,
    generated_objects,
    make_trials,
    random_placements,
    summarize,
)
from diagrams.scenario import DEFAULT_SCENARIO, load_scenario, overlay_scenario, place_over_box_scenario

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


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=3, help="picks per object and yaw (K)")
    parser.add_argument(
        "--category", default="watering_can", help="watering_can, drill, or a taught one (scripts/add_category.py)"
    )
    parser.add_argument(
        "--object-files", dest="object_files", type=Path, nargs="+", help="your own models instead of the test set"
    )
    parser.add_argument("--instances", nargs="+", help="generated instances instead of the test set (e.g. test_1)")
    parser.add_argument("--yaws", type=float, nargs="+", help=f"object yaws, rad (default {list(PAPER_YAWS)})")
    parser.add_argument(
        "--placement",
        choices=("paper", "random"),
        default="paper",
        help="paper: each object at each yaw (--trials per yaw); random: --trials random placements over the table "
        "region with unseen instances, each also picked with ground truth (--yaws does not apply)",
    )
    parser.add_argument(
        "--scene",
        choices=("single", "clutter"),
        default="single",
        help="single: one object on the table; clutter: --scenes seeded cluttered tables, an unseen --category "
        "object among 1-4 others, named to the pick (diagrams/generation/clutter_scenes.py)",
    )
    parser.add_argument("--scenes", type=int, default=30, help="cluttered tables (--scene clutter)")
    parser.add_argument(
        "--ground-truth",
        dest="ground_truth",
        action="store_true",
        help="each pick also run with ground truth in place of perception (the true grasps: what the robot can do "
        "there at all), tabled beside the autonomous one (--placement random always does)",
    )
    parser.add_argument(
        "--scene-split",
        dest="scene_split",
        choices=("report", "tune"),
        default="report",
        help="which cluttered tables: report (unseen instances; never tuned on) or tune (training instances)",
    )
    parser.add_argument(
        "--yaw-noise", dest="yaw_noise", type=float, default=PAPER_YAW_NOISE, help="registration yaw noise, +-rad"
    )
    parser.add_argument(
        "--task", choices=("lift", "place"), default="lift", help="lift and hold (the paper), or carry and place"
    )
    parser.add_argument(
        "--obstacle",
        action="store_true",
        help="with --task place: the category's place_over_box layout (diagrams/place_over_box_<category>.yaml): "
        "object, target and a box on the table between them",
    )
    parser.add_argument(
        "--jobs", type=int, default=1, help="picks run at a time (separate processes; CPUs of a local Ray)"
    )
    parser.add_argument(
        "--ray",
        nargs="?",
        const="",
        metavar="ADDRESS",
        help="run each pick as a Ray task: on the cluster at ADDRESS ('auto': the one this machine joined), "
        "or without an address on a local Ray with --jobs CPUs (pip install -e '.[cluster]')",
    )
    parser.add_argument("--records", type=Path, help="JSON-lines file of every finished pick (default: --json, .jsonl)")
    parser.add_argument("--resume", action="store_true", help="keep the picks already in --records, run the rest")
    parser.add_argument("--summarize", type=Path, metavar="RECORDS", help="no picks: tables from a records file")
    parser.add_argument("--seed", type=int, help="seed of the first trial (trial n gets seed + n)")
    parser.add_argument("--scenario", type=Path, default=DEFAULT_SCENARIO, help="scenario YAML file")
    parser.add_argument("--scenario_text", default="", help="YAML overlaid on the scenario file")
    add_sensor_option(parser)
    parser.add_argument("--json", type=Path, help="write the summary and every trial as JSON")
    parser.add_argument("--figure", type=Path, help="PNG figure (default: --json's name, .png)")
    args = parser.parse_args(argv)
    if args.jobs < 1:
        parser.error("--jobs must be >= 1")
    if args.placement == "random" and (args.yaws or args.instances or args.object_files):
        parser.error("--placement random draws its own yaws and unseen instances: no --yaws, --instances or files")
    if args.scene == "clutter" and (args.yaws or args.instances or args.object_files or args.placement != "paper"):
        parser.error("--scene clutter draws its own objects and places: no --yaws, --instances, files or --placement")
    if args.ground_truth and args.scene == "clutter":
        parser.error("--ground-truth is for one object on the table (the paper's or random placements)")
    args.yaws = args.yaws or list(PAPER_YAWS)
    if args.records is None and args.json is not None:
        args.records = args.json.with_suffix(".jsonl")
    if args.resume and args.records is None:
        parser.error("--resume needs --records or --json (the records file to go on from)")
    return args


def describe(record: dict) -> str:
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


def main(argv=None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    args = parse_args(argv)
    if args.summarize:
        return summarize_records(args)
    try:
        base = load_scenario(args.scenario)
        if args.obstacle and args.task != "place":
            raise ValueError("--obstacle needs --task place (the box lies between the object and the place target)")
        if args.obstacle:  # the category's layout: where the object rests, the target and the box between
            layout = place_over_box_scenario(args.category)
            base = overlay_scenario(base, layout.read_text(), str(layout))
        base = overlay_scenario(base, args.scenario_text, "--scenario_text")
        base = dataclasses.replace(with_sensor(base, args.sensor), task=args.task)
        args.sensor = base.camera_noise.preset
        if args.seed is not None:
            base = dataclasses.replace(base, random_seed=args.seed)
        if args.object_files:
            objects = file_objects(args.object_files)
        elif args.instances:
            objects = {n: {"instance": n, "file": ""} for n in args.instances}
        else:
            objects = generated_objects(args.category)
        if args.scene == "clutter":
            trials = clutter_trials(base, args.category, args.scenes, args.scene_split, args.yaw_noise)
            objects = {trial.name: {} for trial in trials}
        elif args.placement == "random":
            trials = random_placements(base, args.category, args.trials, args.yaw_noise)
            objects = {trial.name: {} for trial in trials}
        else:
            trials = make_trials(
                base,
                args.category,
                objects,
                args.trials,
                args.yaws,
                args.yaw_noise,
                with_ground_truth=args.ground_truth,
            )
    except (ValueError, FileNotFoundError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    what = args.task + (", a box in the way" if args.obstacle else "")
    where = f"{args.jobs} at a time"
    if args.ray is not None:
        where = f"as Ray tasks ({'at ' + args.ray if args.ray else f'a local Ray with {args.jobs} CPUs'})"
    if args.scene == "clutter":
        shape = f"{len(trials)} cluttered tables ({args.scene_split} range), the {args.category} named to the pick"
    elif args.placement == "random":
        shape = f"{len(trials)} random placements of unseen {args.category} instances, each also with ground truth"
    else:
        shape = f"{len(objects)} {args.category} object(s) x {len(args.yaws)} yaw(s) x {args.trials} trial(s)"
    print(
        f"{len(trials)} autonomous picks ({what}): {shape}, registration yaw noise +-{args.yaw_noise:.2f} rad, "
        f"sensor {args.sensor}, {where}"
    )
    try:
        records = run_campaign(trials, args.jobs, args.ray, args.records, args.resume, describe)
    except (RuntimeError, FileExistsError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    report(args, records, base.random_seed)
    return 0


def summarize_records(args) -> int:
    """--summarize: the tables, JSON and figure of a records file (a finished or a stopped campaign)."""
    records = read_records(args.summarize)
    if not records:
        print(f"error: no records in {args.summarize}", file=sys.stderr)
        return 2
    first = records[0]  # a campaign's records share these (older records may lack some: the flags stand)
    args.category, args.task = first.get("category", args.category), first.get("task", args.task)
    args.obstacle, args.yaw_noise = first.get("obstacle", args.obstacle), first.get("yaw_noise_rad", args.yaw_noise)
    args.sensor = first.get("sensor", "perfect")  # (records from before the sensor model: the renderer's images)
    args.yaws = list(dict.fromkeys(r["yaw"] for r in records))
    args.trials = 1 + max(r["trial"] for r in records)
    print(f"{len(records)} picks from {args.summarize}")
    report(args, records, min(r["seed"] for r in records))
    return 0


def _short_reason(record: dict) -> str:
    """A failure's stage and the message's gist, for tables and the map."""
    message = record["message"].split(": ", 1)[-1]
    return f"{record['failed_stage']}: {message[:70]}"


def print_clutter(summary: dict, records: list[dict], category: str):
    """The cluttered tables: each one's other objects, the outcome and the largest move of another object."""
    print(f"\nCluttered tables ({category} named): the other objects; the outcome; the largest move of one of them")
    for record in records:
        moved = max(record.get("others_moved_m") or [0.0])
        outcome = "lifted" if record["success"] else _short_reason(record)
        print(f"{record['name']:<20}{', '.join(record['clutter']):<60.60} {outcome:<40.40} {100 * moved:5.1f} cm")
    low, high = summary["success_rate_ci95"]
    successes = sum(r["success"] for r in records)
    print(f"lifted {successes}/{len(records)} (95 % Wilson interval {100 * low:.0f}-{100 * high:.0f} %)")


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


def report(args, records: list[dict], first_seed: int):
    """Prints the tables; writes the JSON (with every record) and the figure."""
    summary = summarize(records)
    # (Records from before a record said its placement: random placements were those with a ground-truth pick.)
    placements = all(r.get("placement", "random" if "oracle" in r else "paper") == "random" for r in records)
    if placements:
        print_placements(summary, records, args.category)
    elif any(r.get("clutter") for r in records):
        print_clutter(summary, records, args.category)
    else:
        print_tables(summary, args.category, args.trials, args.yaw_noise)
    if "others_moved_m_max" in summary:
        print(
            f"\ncluttered tables: other objects moved at most {100 * summary['others_moved_m_max']:.1f} cm "
            f"({summary['picks_moving_others']} of {len(records)} picks moved one more than "
            f"{100 * OTHERS_MOVED_LIMIT_M:.0f} cm); perception took the named category in "
            f"{100 * summary['requested_category_share']:.0f} % of the picks that perceived"
        )
    t_dev, o_dev = summary["closure_translation_dev_m_max"], summary["closure_orientation_dev_rad_max"]
    print(f"\nclosure along the played held moves (picks that lifted): largest {1000 * t_dev:.1f} mm, {o_dev:.4f} rad")
    if args.task == "place":
        error = summary["place_error_m_median"]
        print(f"place error, median over the picks that set the object down: {100 * error:.1f} cm")
        turn, most = summary["release_turn_rad_median"], summary["release_turn_rad_max"]
        turned = f"median {math.degrees(turn):.1f} deg, largest {math.degrees(most):.1f} deg"
        print(f"turned by letting go and backing off: {turned}")
    report = {
        "category": args.category,
        "task": args.task,
        "obstacle": args.obstacle,
        "placement": "random" if placements else "paper",
        "scene": "clutter" if any(r.get("clutter") for r in records) else "single",
        "trials_per_yaw": args.trials,
        "yaws": args.yaws,
        "yaw_noise_rad": args.yaw_noise,
        "sensor": args.sensor,
        "first_seed": first_seed,
        "jobs": args.jobs,
        "ray": args.ray,
        "machine": f"{platform.processor() or platform.machine()}, {platform.system()}",
        **summary,
        "records": records,
    }
    if args.json:
        write_json(args.json, report)
    figure = args.figure or (args.json.with_suffix(".png") if args.json else Path(f"evaluation_{args.category}.png"))
    if placements:
        draw_map(figure, records, args.category)
    elif report["scene"] == "clutter":  # one table each, no yaws: the tables and the JSON say it all
        print("(no figure for cluttered tables: draw one with scripts/draw_clutter_scene.py)")
    else:
        draw_figure(figure, summary, records, args.category)


if __name__ == "__main__":
    sys.exit(main())
