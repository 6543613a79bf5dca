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
import sys
from pathlib import Path

from diagrams.campaign import read_records, run_campaign
from diagrams.cli import add_mesh_options, add_sensor_option, with_sensor
from diagrams.evaluation import (
    PAPER_YAW_NOISE,
    PAPER_YAWS,
    clutter_trials,
    file_objects,
    generated_objects,
    make_trials,
    random_placements,
)
from diagrams.evaluation_report import CampaignSettings, describe, recorded_campaign, report
from diagrams.scenario import DEFAULT_SCENARIO, TASKS, load_scenario, overlay_scenario, place_over_box_scenario


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
        choices=("report", "tune", "validation"),
        default="report",
        help="which cluttered tables: report (unseen instances; never tuned on), tune (training instances) or "
        "validation (other unseen instances, for tuning)",
    )
    parser.add_argument(
        "--yaw-noise", dest="yaw_noise", type=float, default=PAPER_YAW_NOISE, help="registration yaw noise, +-rad"
    )
    parser.add_argument(
        "--task",
        choices=TASKS,
        default="lift",
        help="lift and hold (the paper), carry and place, aim a drill at a board's target (--category drill), or pour "
        "from a can into a container (--category watering_can)",
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
    add_mesh_options(parser)
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


def campaign_of(args) -> CampaignSettings:
    """What the report says the campaign was: the options of the same names."""
    return CampaignSettings(**{field.name: getattr(args, field.name) for field in dataclasses.fields(CampaignSettings)})


def base_scenario(args):
    """The scenario file, the category's place_over_box layout (--obstacle), --scenario_text, the sensor, the task
    and the first seed."""
    base = load_scenario(args.scenario)
    if args.obstacle and args.task != "place":
        raise ValueError("--obstacle needs --task place (the box lies between the object and the place target)")
    if args.obstacle:  # the category's layout: where the object rests, the target and the box between
        layout = place_over_box_scenario(args.category)
        base = overlay_scenario(base, layout.read_text(), str(layout))
    base = overlay_scenario(base, args.scenario_text, "--scenario_text")
    base = dataclasses.replace(with_sensor(base, args.sensor), task=args.task)
    if args.seed is not None:
        base = dataclasses.replace(base, random_seed=args.seed)
    return base


def campaign_trials(args, base) -> tuple[list, dict]:
    """The trials (the paper's placements, random placements or cluttered tables) and the objects they pick."""
    if args.object_files:
        objects = file_objects(args.object_files, args.mesh_units or "auto", args.mesh_up or "auto")
    elif args.instances:
        objects = {n: {"instance": n, "file": ""} for n in args.instances}
    else:
        objects = generated_objects(args.category)
    if args.scene == "clutter":
        trials = clutter_trials(base, args.category, args.scenes, args.scene_split, args.yaw_noise)
        return trials, {trial.name: {} for trial in trials}
    if args.placement == "random":
        trials = random_placements(base, args.category, args.trials, args.yaw_noise)
        return trials, {trial.name: {} for trial in trials}
    trials = make_trials(
        base, args.category, objects, args.trials, args.yaws, args.yaw_noise, with_ground_truth=args.ground_truth
    )
    return trials, objects


def heading(args, trials: list, objects: dict) -> str:
    what = args.task + (", a box in the way" if args.obstacle else "")
    where = f"{args.jobs} at a time"
    if args.ray is not None:
        where = f"as Ray tasks ({'at ' + args.ray if args.ray else f'a local Ray with {args.jobs} CPUs'})"
    if args.scene == "clutter" and args.task == "clear":
        shape = f"{len(trials)} tables to clear ({args.scene_split} range), every familiar object into the drop zone"
    elif args.scene == "clutter":
        shape = f"{len(trials)} cluttered tables ({args.scene_split} range), the {args.category} named to the pick"
    elif args.placement == "random":
        shape = f"{len(trials)} random placements of unseen {args.category} instances, each also with ground truth"
    else:
        shape = f"{len(objects)} {args.category} object(s) x {len(args.yaws)} yaw(s) x {args.trials} trial(s)"
    return (
        f"{len(trials)} autonomous picks ({what}): {shape}, registration yaw noise +-{args.yaw_noise:.2f} rad, "
        f"sensor {args.sensor}, {where}"
    )


def main(argv=None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    args = parse_args(argv)
    if args.summarize:
        return summarize_records(args)
    try:
        base = base_scenario(args)
        args.sensor = base.camera_noise.preset
        trials, objects = campaign_trials(args, base)
    except (ValueError, FileNotFoundError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(heading(args, trials, objects))
    try:
        records = run_campaign(trials, args.jobs, args.ray, args.records, args.resume, describe)
    except (RuntimeError, FileExistsError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    report(campaign_of(args), records, base.random_seed, args.json, args.figure)
    return 0


def summarize_records(args) -> int:
    """--summarize: the tables, JSON and figure of a records file (a finished or a stopped campaign)."""
    records = read_records(args.summarize)
    if not records:
        print(f"error: no records in {args.summarize}", file=sys.stderr)
        return 2
    campaign = recorded_campaign(records, campaign_of(args))
    print(f"{len(records)} picks from {args.summarize}")
    report(campaign, records, min(r["seed"] for r in records), args.json, args.figure)
    return 0


if __name__ == "__main__":
    sys.exit(main())
