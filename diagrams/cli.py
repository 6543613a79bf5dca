"""What the scripts share on the command line: the options that choose a scenario and its object (pick.py,
robot_driver.py, draw_clutter_scene.py), the --sensor option, and results written as strict JSON."""

import argparse
import dataclasses
import json
import math
from pathlib import Path

from diagrams.generation.clear_scenes import clear_scene
from diagrams.generation.clutter_scenes import clutter_scene
from diagrams.scenario import DEFAULT_SCENARIO, TASKS, Scenario, load_scenario, replace_object
from systems.perception.rgbd_noise import PRESETS
from systems.shape_space.units import MESH_UNITS, MESH_UP_AXES


def add_scenario_options(parser: argparse.ArgumentParser) -> None:
    """--scenario, --scenario_text, the object options (--object, --instance, --object-file, --yaw), --seed, --scene
    with --clutter-index, and --sensor."""
    parser.add_argument("--scenario", type=Path, default=DEFAULT_SCENARIO, help="scenario YAML file")
    parser.add_argument("--scenario_text", default="", help="YAML overlaid on the scenario file")
    parser.add_argument("--object", help="object category: watering_can, drill, or one taught by add_category.py")
    parser.add_argument(
        "--instance", help="generated instance: train_<i>, test_<i>, extra_<seed>, wide_<seed> (the wider family)"
    )
    parser.add_argument(
        "--object-file", dest="object_file", help="your own model: .sdf, .urdf, or a mesh (.obj/.ply/.stl/.glb)"
    )
    add_mesh_options(parser)
    parser.add_argument("--yaw", type=float, help="object yaw relative to the category's presentation, rad")
    parser.add_argument(
        "--task",
        choices=TASKS,
        help="lift (the paper's), place (scenario place:), aim (a drill at the scenario aim: board; docs/use.md), "
        "pour (a can into the scenario pour: container; docs/use.md) or "
        "clear (every familiar object into the scenario clear: drop zone, with --scene clutter; docs/clear.md); "
        "default: the scenario's",
    )
    parser.add_argument("--seed", type=int, help="random seed of the run")
    parser.add_argument(
        "--scene",
        choices=("single", "clutter"),
        default="single",
        help="single: the scenario's object alone; clutter: a seeded cluttered table with an unseen --object "
        "(default watering_can) among 1-4 others (diagrams/generation/clutter_scenes.py); with --task clear, a "
        "table of 2-3 unseen familiar objects among 1-2 distractors (diagrams/generation/clear_scenes.py)",
    )
    parser.add_argument(
        "--clutter-index", dest="clutter_index", type=int, default=0, help="which cluttered table (--scene clutter)"
    )
    add_sensor_option(parser)


def add_mesh_options(parser: argparse.ArgumentParser) -> None:
    """--mesh-units and --mesh-up: how to read a user's mesh file (default: detected, and said)."""
    parser.add_argument(
        "--mesh-units", dest="mesh_units", choices=MESH_UNITS, help="a mesh file's units (default auto: from its size)"
    )
    parser.add_argument(
        "--mesh-up", dest="mesh_up", choices=MESH_UP_AXES, help="a mesh file's up axis (default auto: how it stands)"
    )


def add_sensor_option(parser: argparse.ArgumentParser, default: str | None = None) -> None:
    """--sensor PRESET (the RGB-D sensor model) and --no-noise (--sensor perfect)."""
    presets = ", ".join(PRESETS)
    fallback = default or "the scenario's camera_noise, kinect_v2"
    parser.add_argument(
        "--sensor",
        choices=tuple(PRESETS),
        default=default,
        help=f"the RGB-D sensor model ({presets}; default: {fallback})",
    )
    parser.add_argument(
        "--no-noise",
        dest="sensor",
        action="store_const",
        const="perfect",
        help="the renderer's perfect images (--sensor perfect)",
    )


def with_sensor(scenario: Scenario, sensor: str | None) -> Scenario:
    """The scenario with its camera_noise preset replaced (None: as it is)."""
    if sensor is None:
        return scenario
    return dataclasses.replace(scenario, camera_noise=dataclasses.replace(scenario.camera_noise, preset=sensor))


def scenario_from_args(args: argparse.Namespace) -> Scenario:
    """The scenario file, the --scenario_text overlay, then the object options. --object names the category to
    perception too (requested_category): the user's word for what stands there wins over the network's class.
    With --scene clutter, the cluttered table --clutter-index with an --object to pick among others.

    Raises:
        ValueError: --scene clutter with an option that places the object itself.
    """
    scenario = load_scenario(args.scenario, args.scenario_text)
    if getattr(args, "task", None) is not None:
        scenario = dataclasses.replace(scenario, task=args.task)
    if getattr(args, "scene", "single") == "clutter":
        given = [f"--{n.replace('_', '-')}" for n in ("instance", "object_file", "yaw") if getattr(args, n) is not None]
        if given:
            raise ValueError(f"--scene clutter draws the object and its place: no {', '.join(given)}")
        if scenario.task == "clear":
            scenario = clear_scene(scenario, args.clutter_index)
        else:
            scenario = clutter_scene(scenario, args.object or "watering_can", args.clutter_index)
        if args.seed is not None:
            scenario = dataclasses.replace(scenario, random_seed=args.seed)
        return with_sensor(scenario, args.sensor)
    changes = {"category": args.object, "instance": args.instance, "file": args.object_file, "yaw": args.yaw}
    changes |= {"units": args.mesh_units, "up": args.mesh_up}
    scenario = replace_object(scenario, **{k: v for k, v in changes.items() if v is not None})
    if args.object is not None:
        scenario = dataclasses.replace(scenario, requested_category=args.object)
    if args.seed is not None:
        scenario = dataclasses.replace(scenario, random_seed=args.seed)
    return with_sensor(scenario, args.sensor)


def scenario_arguments(args: argparse.Namespace) -> list[str]:
    """These options as given, to start another script on the same scenario."""
    forwarded = ["--scenario", str(args.scenario), "--scenario_text", args.scenario_text]
    names = ("object", "instance", "object_file", "mesh_units", "mesh_up", "yaw", "seed", "sensor", "scene", "task")
    for name in (*names, "clutter_index"):
        value = getattr(args, name)
        if value is not None:
            forwarded += [f"--{name.replace('_', '-')}", str(value)]
    return forwarded


def _finite_or_none(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _finite_or_none(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_or_none(item) for item in value]
    return value


def write_json(path: Path, results: dict) -> None:
    """Writes a script's results as strict JSON: NaN and infinities (a figure that does not exist) become null."""
    path.write_text(json.dumps(_finite_or_none(results), indent=2, allow_nan=False))
    print(f"wrote {path}")
