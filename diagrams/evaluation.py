"""The paper's simulated pick experiment (§V-B) as trials, and its statistics.

Each object is placed at yaw +0.25, 0 and -0.25 rad and picked K times; every trial
has its own seed, from which the +-0.2 rad yaw offset of the pose handed to the
registration (Scenario.registration_yaw_noise) and every other random draw come.
A trial runs the whole autonomous pick (diagrams/autonomous_pick.py) and is judged
on the simulator's ground truth.
"""

import dataclasses
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.stats import binomtest

from diagrams.generation.objects import catalog
from diagrams.scenario import Scenario, clutter_name, replace_object

# The paper's two categories: what the benchmarks and the planning problems draw from (a category added to the
# catalog changes none of them).
PAPER_CATEGORIES = ("watering_can", "drill")
PAPER_YAWS = (0.25, 0.0, -0.25)  # rad
PAPER_YAW_NOISE = 0.2  # rad
# Random placements over the table region around the default spot (object.xy, table_top frame; the planning
# problems' objects stand there too): x within
# +-PLACEMENT_HALF_SIZE_M[0], y within +-[1], yaw within +-PLACEMENT_MAX_YAW (m, m, rad), placement k with the
# unseen generated instance extra_<PLACEMENT_FIRST_INSTANCE + k> (a range nobody tunes on).
PLACEMENT_HALF_SIZE_M = (0.10, 0.20)
PLACEMENT_MAX_YAW = 0.6
PLACEMENT_FIRST_INSTANCE = 1000
PLACEMENT_SEED = 34
# Cluttered tables: another object moved more than this was touched, m (the judge measures every move).
OTHERS_MOVED_LIMIT_M = 0.02
# The pipeline's stages in order, then the motion itself ("execution": the plan was played but
# the object was not lifted and held by both hands).
COMPONENTS = ("segmentation", "pose", "registration", "planning", "grasp", "execution")
TIMED_STAGES = ("segmentation", "pose", "registration", "planning", "image_to_trajectory")


@dataclass
class Trial:
    """One pick of the experiment."""

    name: str  # the object's name in the report: the generated instance, or the model file's stem
    yaw: float  # rad
    index: int  # 0..K-1 at this object and yaw
    scenario: Scenario  # pickles (as its YAML) for worker processes and Ray
    # Also run the ground-truth pick on the same scenario (whether the robot can do it at all), recorded as
    # the record's "oracle".
    with_oracle: bool = False
    placement: str = "paper"  # "paper" (each object at each yaw) or "random" (random_placements)


def generated_objects(category: str, split: str = "test") -> dict[str, dict]:
    """{name: ObjectConfig changes} of a category's generated instances of one split (e.g. the 3 test cans)."""
    return {n: {"instance": n, "file": ""} for n in catalog.instance_names(category) if n.startswith(f"{split}_")}


def file_objects(paths: list[Path], units: str = "auto", up: str = "auto") -> dict[str, dict]:
    """{name: ObjectConfig changes} of a user's model files, named by their stems (made unique); a mesh file's
    `units` and `up` as ObjectConfig's."""
    objects = {}
    for path in paths:
        if not path.is_file():
            raise FileNotFoundError(f"object file not found: {path}")
        name, n = path.stem, 1
        while name in objects:
            n += 1
            name = f"{path.stem}_{n}"
        objects[name] = {"file": str(path), "units": units, "up": up}
    return objects


def make_trials(
    base: Scenario,
    category: str,
    objects: dict[str, dict],
    trials: int,
    yaws=PAPER_YAWS,
    yaw_noise: float = PAPER_YAW_NOISE,
    with_ground_truth: bool = False,
) -> list[Trial]:
    """Every object at every yaw, `trials` times; trial n of the list gets the seed base.random_seed + n. A user's
    model file (changes["file"]) is of the category the user gave: perception registers it so and reports what the
    network made of it (requested_category), as `pick.py --object C --object-file F` does. with_ground_truth: each
    trial also runs the ground-truth pick on its scenario (what the robot can do there with the true grasps)."""
    if trials < 1:
        raise ValueError(f"trials must be >= 1, got {trials}")
    catalog.presentation_yaw(category)  # a clear error for an unknown category
    out = []
    for name, changes in objects.items():
        for yaw in yaws:
            for index in range(trials):
                scenario = replace_object(base, category=category, yaw=float(yaw), **changes)
                scenario = dataclasses.replace(
                    scenario,
                    random_seed=base.random_seed + len(out),
                    registration_yaw_noise=yaw_noise,
                    requested_category=category if changes.get("file") else base.requested_category,
                )
                out.append(Trial(name, float(yaw), index, scenario, with_oracle=with_ground_truth))
    return out


def random_placements(base: Scenario, category: str, count: int, yaw_noise: float = PAPER_YAW_NOISE) -> list[Trial]:
    """`count` placements drawn uniformly over the table region around base's object.xy (PLACEMENT_HALF_SIZE_M,
    PLACEMENT_MAX_YAW), placement k from its own seed [PLACEMENT_SEED, k] alone, with the unseen instance
    extra_<PLACEMENT_FIRST_INSTANCE + k>; each runs the autonomous pick and the ground-truth one."""
    if count < 1:
        raise ValueError(f"placements must be >= 1, got {count}")
    catalog.category_module(category)  # a clear error for a taught or unknown category: it has no extra instances
    out = []
    for k in range(count):
        rng = np.random.default_rng([PLACEMENT_SEED, k])
        dx, dy = rng.uniform(-1.0, 1.0, size=2) * PLACEMENT_HALF_SIZE_M
        yaw = float(rng.uniform(-PLACEMENT_MAX_YAW, PLACEMENT_MAX_YAW))
        xy = [base.object.xy[0] + float(dx), base.object.xy[1] + float(dy)]
        name = f"extra_{PLACEMENT_FIRST_INSTANCE + k}"
        scenario = replace_object(base, category=category, instance=name, file="", xy=xy, yaw=yaw)
        scenario = dataclasses.replace(scenario, random_seed=base.random_seed + k, registration_yaw_noise=yaw_noise)
        out.append(Trial(name, yaw, 0, scenario, with_oracle=True, placement="random"))
    return out


def clutter_trials(
    base: Scenario, category: str, count: int, split: str = "report", yaw_noise: float = PAPER_YAW_NOISE
) -> list[Trial]:
    """`count` cluttered tables (diagrams/generation/clutter_scenes.py), table k of `split` with the seed
    base.random_seed + k; the user names `category`, the pick finds the nearest one among the others. For the clear
    task, tables to clear (diagrams/generation/clear_scenes.py: every familiar object, `category` unused)."""
    from diagrams.generation.clear_scenes import clear_scene
    from diagrams.generation.clutter_scenes import clutter_scene

    if count < 1:
        raise ValueError(f"scenes must be >= 1, got {count}")
    out = []
    for k in range(count):
        table = clear_scene(base, k, split) if base.task == "clear" else clutter_scene(base, category, k, split)
        scenario = dataclasses.replace(table, registration_yaw_noise=yaw_noise)
        out.append(Trial(f"clutter_{split}_{k}", scenario.object.yaw, 0, scenario))
    return out


def trial_key(trial: Trial) -> tuple:
    """What names a trial in a campaign: (object, yaw, index, seed); its record's record_key is the same."""
    return trial.name, trial.yaw, trial.index, trial.scenario.random_seed


def record_key(record: dict) -> tuple:
    return record["name"], record["yaw"], record["trial"], record["seed"]


def run_trial_in_worker(trial: Trial) -> dict:
    """run_trial in a worker process (a pool's or Ray's): one torch thread, warnings only."""
    import torch

    logging.basicConfig(level=logging.WARNING, format="%(message)s", force=True)
    torch.set_num_threads(1)
    return run_trial(trial)


def crashed_record(trial: Trial, why: str) -> dict:
    """The record of a trial whose worker process died before it ended (`why`: how it died)."""
    message = f"the simulation's process died ({why}); nothing of the pick was recorded"
    return _unjudged(_trial_record(trial), trial.scenario, "crash", message)


def _unjudged(record: dict, scenario: Scenario, stage: str, message: str) -> dict:
    """A trial's record (`record`: what it said before it ran) ended with no judgement (its process died, its
    simulation diverged): failed; a clear's familiar objects all counted, none cleared, the distractors' moves
    unknown (NaN)."""
    from diagrams.clear_judge import familiar_objects

    record = record | {"success": False, "failed_stage": stage, "message": message, "stages": {}}
    if scenario.task == "clear":
        record["clear"] = {"objects": [], "familiar_objects": len(familiar_objects(scenario)), "objects_cleared": 0,
                           "taken_on": [], "others_moved_m_max": float("nan")}  # fmt: skip
    return record


def _trial_record(trial: Trial) -> dict:
    """What a trial's record says before it runs: its scenario and seed."""
    from systems.perception.pose_noise import draw_yaw_offset

    scenario = trial.scenario
    record = {
        "category": scenario.object.category,
        "task": scenario.task,
        "obstacle": scenario.obstacle.present,
        "yaw_noise_rad": scenario.registration_yaw_noise,
        "sensor": scenario.camera_noise.preset,
        "name": trial.name,
        "placement": trial.placement,
        "yaw": trial.yaw,
        "trial": trial.index,
        "seed": scenario.random_seed,
        "registration_yaw_offset_rad": draw_yaw_offset(scenario.registration_yaw_noise, scenario.random_seed),
    }
    if scenario.clutter:
        record["clutter"] = [clutter_name(other) for other in scenario.clutter]
        record["requested_category"] = scenario.requested_category
    return record


def run_trial(trial: Trial) -> dict:
    """Runs one autonomous pick in simulation; a JSON-ready record of what happened."""
    from diagrams.autonomous_pick import run_pick  # (heavy: torch, the shape spaces)
    from systems.planning.pick_motions import PlanningError
    from systems.robot_io.gravity_compensation import SimulationDiverged

    scenario = trial.scenario
    record = _trial_record(trial)
    if trial.with_oracle:
        record["xy"] = list(scenario.object.xy)
        record["oracle"] = _oracle_record(scenario)
    try:
        outcome = run_pick(scenario)
    except (PlanningError, ValueError, FileNotFoundError) as error:  # e.g. a model that cannot be loaded
        logging.warning("trial %s yaw %+.2f #%d: %s", trial.name, trial.yaw, trial.index, error)
        return record | {"success": False, "failed_stage": "setup", "message": str(error), "stages": {}}
    except (SimulationDiverged, SystemExit) as error:  # (pydrake turns a failed Drake check into SystemExit)
        logging.warning("trial %s yaw %+.2f #%d: the simulation failed: %s", trial.name, trial.yaw, trial.index, error)
        return _unjudged(record, scenario, "simulation", f"the simulation failed: {error}")
    failed_stage = outcome.failed_stage or ("" if outcome.success else "execution")
    return record | {
        "success": bool(outcome.success),
        "lift_height_m": outcome.lift_height_m,
        "hands_in_contact": outcome.hands_in_contact,
        "failed_stage": failed_stage,
        "message": outcome.message,
        "attempts_made": outcome.attempts_made,
        "attempt_failures": outcome.attempt_failures,
        "stages": outcome.stages,
        "closure": outcome.closure,
        "closure_executed": outcome.closure_executed,
        "place": outcome.place,
        "use": outcome.use,
        "clear": outcome.clear,
        "waits": outcome.waits,
        "perception": outcome.perception,
        "others_moved_m": outcome.others_moved_m,
        "sim_wall_s": outcome.wall_time_s,
        "sim_time_s": outcome.sim_time_s,
    }


def _oracle_record(scenario: Scenario) -> dict:
    """Whether the ground-truth pick (the same diagram, perception replaced by the truth) does this scenario."""
    from diagrams.autonomous_pick import run_pick
    from systems.planning.pick_motions import PlanningError
    from systems.robot_io.gravity_compensation import SimulationDiverged

    try:
        outcome = run_pick(scenario, perception="ground_truth")
    except (PlanningError, ValueError, FileNotFoundError) as error:
        return {"success": False, "failed_stage": "setup", "message": str(error)}
    except (SimulationDiverged, SystemExit) as error:
        return {"success": False, "failed_stage": "simulation", "message": f"the simulation failed: {error}"}
    failed_stage = outcome.failed_stage or ("" if outcome.success else "execution")
    return {"success": bool(outcome.success), "failed_stage": failed_stage, "message": outcome.message,
            "attempts_made": outcome.attempts_made}  # fmt: skip


def wilson_interval(successes: int, attempts: int) -> tuple[float, float]:
    """The 95 % Wilson score interval of a success rate (NaN, NaN without attempts)."""
    if attempts == 0:
        return float("nan"), float("nan")
    interval = binomtest(successes, attempts).proportion_ci(confidence_level=0.95, method="wilson")
    return float(interval.low), float(interval.high)


def _rate(successes: int, attempts: int) -> float:
    return successes / attempts if attempts else float("nan")


def summarize(records: list[dict]) -> dict:
    """Success per object (and per yaw), per pipeline component, and the stage times' statistics.

    Returns a dict with success_rate, per_instance[name] = {success_rate, successes, attempts,
    per_yaw}, always_succeeded (the objects every pick of which succeeded); where every record also holds the
    ground-truth pick's outcome ("oracle"), the same two of those as ground_truth_per_instance and
    ground_truth_always_succeeded; components[c] =
    {success_rate, reached} (of the trials that reached c, the share that passed it), and
    stages[f"{stage}_s_{mean|std|median}"] over the trials that timed it.
    """
    per_instance = _per_instance(records, lambda r: r["success"])
    components = {}
    reached = [r for r in records if r["failed_stage"] != "setup"]
    for component in COMPONENTS:
        failed = sum(r["failed_stage"] == component for r in reached)
        components[component] = {"success_rate": _rate(len(reached) - failed, len(reached)), "reached": len(reached)}
        reached = [r for r in reached if r["failed_stage"] != component]
    stages = {}
    for stage in TIMED_STAGES:
        seconds = np.array([r["stages"][stage] for r in records if stage in r["stages"]])
        for statistic, value in (("mean", np.mean), ("std", np.std), ("median", np.median)):
            stages[f"{stage}_s_{statistic}"] = float(value(seconds)) if len(seconds) else float("nan")
    closure = [r["closure"] for r in records if r.get("closure") and np.isfinite(r["closure"]["max_translation_dev_m"])]
    placed = [r["place"]["error_m"] for r in records if r.get("place")]
    released = [r["place"]["release_turn_rad"] for r in records if "release_turn_rad" in (r.get("place") or {})]
    successes = sum(r["success"] for r in records)
    oracle = [r for r in records if "oracle" in r]
    cluttered = [r for r in records if r.get("clutter")]
    moved = [m for r in cluttered for m in r.get("others_moved_m", [])]
    moving = sum(max(r.get("others_moved_m") or [0.0]) > OTHERS_MOVED_LIMIT_M for r in cluttered)
    doable = [r for r in oracle if r["oracle"]["success"]]
    truth = _per_instance(records, lambda r: r["oracle"]["success"]) if oracle and len(oracle) == len(records) else None
    return {
        # Random placements (records with an "oracle"): the share the ground-truth pick does, and the share of
        # those the autonomous pick does.
        **(
            {
                "oracle_success_rate": _rate(len(doable), len(oracle)),
                "success_rate_given_oracle": _rate(sum(r["success"] for r in doable), len(doable)),
            }
            if oracle
            else {}
        ),
        # Cluttered tables: the largest move of any other object over all picks (failed ones too), m; how many picks
        # moved one more than OTHERS_MOVED_LIMIT_M; the share where perception took the category the user named.
        **(
            {
                "others_moved_m_max": max(moved, default=0.0),
                "picks_moving_others": moving,
                "requested_category_share": _rate(
                    sum(r.get("perception", {}).get("category") == r["requested_category"] for r in cluttered),
                    sum("category" in r.get("perception", {}) for r in cluttered),
                ),
            }
            if cluttered
            else {}
        ),
        **_grasps_on_handles(records),
        **_tool_errors(records),
        **_clears(records),
        **_aims(records),
        **_pours(records),
        "success_rate": _rate(successes, len(records)),
        "success_rate_ci95": wilson_interval(successes, len(records)),
        # Over the picks that lifted (a held move was played), m and rad.
        "closure_translation_dev_m_max": max((c["max_translation_dev_m"] for c in closure), default=float("nan")),
        "closure_orientation_dev_rad_max": max((c["max_orientation_dev_rad"] for c in closure), default=float("nan")),
        # The place task: the object's distance from the target at the end, over the picks that got that far.
        "place_error_m_median": float(np.median(placed)) if placed else float("nan"),
        # How far letting go and backing off turned the set-down object about the vertical, rad (median, max).
        "release_turn_rad_median": float(np.median(released)) if released else float("nan"),
        "release_turn_rad_max": max(released, default=float("nan")),
        "trials": len(records),
        "per_instance": per_instance,
        "always_succeeded": _always_succeeded(per_instance),
        **(
            {"ground_truth_per_instance": truth, "ground_truth_always_succeeded": _always_succeeded(truth)}
            if truth is not None
            else {}
        ),
        "components": components,
        "stages": stages,
    }


def _grasps_on_handles(records: list[dict]) -> dict:
    """Where the objects' true parts are known: {"grasps_judged_on_handles": picks whose grasps were judged on them,
    "lifts_off_handle": picks that lifted with a grasp off its own handle}; {} where none was judged."""
    judged = [r for r in records if "grasps_on_handles" in r.get("perception", {})]
    if not judged:
        return {}
    off = [r for r in judged if r["success"] and not all(r["perception"]["grasps_on_handles"].values())]
    return {"grasps_judged_on_handles": len(judged), "lifts_off_handle": len(off)}


def _tool_errors(records: list[dict]) -> dict:
    """Where a tool frame was perceived and the true one is known: {"tool_frames_judged": how many picks,
    "tool_tip_error_m_median", "tool_axis_error_rad_median"}; {} where none was."""
    judged = [r["perception"]["tool_errors"] for r in records if "tool_errors" in r.get("perception", {})]
    if not judged:
        return {}
    return {
        "tool_frames_judged": len(judged),
        "tool_tip_error_m_median": float(np.median([e["tip_m"] for e in judged])),
        "tool_axis_error_rad_median": float(np.median([e["axis_rad"] for e in judged])),
    }


def _clears(records: list[dict]) -> dict:
    """The clear task (records judged by diagrams/clear_judge.py): {"tables", "familiar_objects", "objects_cleared",
    "objects_cleared_share": of every familiar object on every table, "objects_cleared_per_table_mean",
    "attempts_per_object_mean": over the objects taken on, "sim_s_per_object_mean": simulated seconds per object taken
    on, "others_moved_m_max": the distractors' largest move}; {} where no record is a clear."""
    clears = [r for r in records if (r.get("clear") or {}).get("objects") is not None]
    if not clears:
        return {}
    familiar = sum(r["clear"]["familiar_objects"] for r in clears)
    cleared = sum(r["clear"]["objects_cleared"] for r in clears)
    taken = [done for r in clears for done in r["clear"].get("taken_on", [])]
    return {
        "tables": len(clears),
        "familiar_objects": familiar,
        "objects_cleared": cleared,
        "objects_cleared_share": _rate(cleared, familiar),
        "objects_cleared_per_table_mean": cleared / len(clears),
        "attempts_per_object_mean": float(np.mean([done["attempts"] for done in taken])) if taken else float("nan"),
        "sim_s_per_object_mean": sum(r.get("sim_time_s", 0.0) for r in clears) / max(len(taken), 1),
        "others_moved_m_max": max(
            (m for r in clears if np.isfinite(m := r["clear"]["others_moved_m_max"])), default=float("nan")
        ),
    }


def _aims(records: list[dict]) -> dict:
    """The aim task (records with a measured hold, diagrams/aim_judge.py): {"aims_held": how many picks held an aim,
    "aimed_share": the share of all picks whose aim the judge passed, "aim_axis_error_rad_median",
    "aim_tip_to_target_m_median"} (worst of each hold); {} where no record is an aim."""
    aims = [r["use"] for r in records if (r.get("use") or {}).get("task") == "aim"]
    if not aims:
        return {}
    held = [use for use in aims if "axis_error_rad" in use]
    return {
        "aims_held": len(held),
        "aimed_share": _rate(sum(use["aimed"] for use in aims), len(records)),
        "aim_axis_error_rad_median": float(np.median([u["axis_error_rad"] for u in held])) if held else float("nan"),
        "aim_tip_to_target_m_median": float(np.median([u["tip_to_target_m"] for u in held])) if held else float("nan"),
    }


def _pours(records: list[dict]) -> dict:
    """The pour task (records with a measured hold, diagrams/pour_judge.py): {"pours_held": how many picks held a
    pour, "poured_share": the share of all picks whose pour the judge passed, "pour_tip_from_centre_m_median",
    "pour_outflow_below_rad_median"} (worst of each hold); {} where no record is a pour."""
    pours = [r["use"] for r in records if (r.get("use") or {}).get("task") == "pour"]
    if not pours:
        return {}
    held = [use for use in pours if "outflow_elevation_rad" in use]
    return {
        "pours_held": len(held),
        "poured_share": _rate(sum(use["poured"] for use in pours), len(records)),
        "pour_tip_from_centre_m_median": float(np.median([u["tip_from_centre_m"] for u in held])) if held else math.nan,
        "pour_outflow_below_rad_median": float(np.median([-u["outflow_elevation_rad"] for u in held])) if held
        else math.nan,
    }  # fmt: skip


def _per_instance(records: list[dict], succeeded) -> dict:
    """{name: {success_rate, successes, attempts, per_yaw}} of the records, succeeded(record) saying which lifted."""
    out = {}
    for name in dict.fromkeys(r["name"] for r in records):
        mine = [r for r in records if r["name"] == name]
        per_yaw = {}
        for yaw in dict.fromkeys(r["yaw"] for r in mine):
            at_yaw = [bool(succeeded(r)) for r in mine if r["yaw"] == yaw]
            per_yaw[f"{yaw:+.2f}"] = _rate(sum(at_yaw), len(at_yaw))
        successes = sum(bool(succeeded(r)) for r in mine)
        out[name] = {
            "success_rate": _rate(successes, len(mine)),
            "successes": successes,
            "attempts": len(mine),
            "per_yaw": per_yaw,
        }
    return out


def _always_succeeded(per_instance: dict) -> list[str]:
    return [name for name, row in per_instance.items() if row["successes"] == row["attempts"]]
