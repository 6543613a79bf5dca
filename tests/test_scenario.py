"""Scenario loading: defaults, overlays, and clear errors for bad input."""

import json
import subprocess
import sys

import numpy as np
import pytest

from diagrams.evaluation import PAPER_YAWS
from diagrams.generation.objects.library import resolve_object
from diagrams.paths import REPO_ROOT
from diagrams.planning_scene import object_surface_W
from diagrams.scenario import load_scenario, place_over_box_scenario, replace_object
from diagrams.station import TABLE_HEIGHT, object_pose_on_table, place_target


def test_default_scenario_loads():
    scenario = load_scenario()
    assert scenario.object.category == "watering_can"
    assert scenario.plant_config.discrete_contact_approximation == "sap"
    assert scenario.lcm.lcm_url == "memq://null"


def test_overlay_changes_only_what_it_names():
    scenario = load_scenario(scenario_text="{object: {yaw: 0.25}, random_seed: 7}")
    assert scenario.object.yaw == 0.25 and scenario.random_seed == 7
    assert scenario.object.instance == "test_1"


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="scenario file not found"):
        load_scenario(tmp_path / "nope.yaml")


def test_unknown_field(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("object: {colour: red}\n")
    with pytest.raises(ValueError, match=r"invalid scenario in .*bad.yaml"):
        load_scenario(path)


def test_wrong_type():
    with pytest.raises(ValueError, match="--scenario_text"):
        load_scenario(scenario_text="random_seed: [1, 2]")


def test_wrong_length():
    with pytest.raises(ValueError, match="initial_arm_positions must have 14"):
        load_scenario(scenario_text="initial_arm_positions: [0, 0]")


@pytest.mark.parametrize(
    ("text", "named"),
    [
        ("{object: {yaw: .nan}}", "object.yaw must be finite"),
        ("{object: {xy: [.inf, 0]}}", r"object.xy\[0\] must be finite"),
        ("{object: {mass: -1}}", "object.mass must lie in"),
        ("{object: {yaw: 40}}", "object.yaw must lie in"),
        ("{object: {xy: [3.0, 0]}}", "object.xy must lie within"),
        ("{place: {xy: [0, .nan]}}", r"place.xy\[1\] must be finite"),
        ("{place: {yaw: 9}}", "place.yaw must lie in"),
        ("{task: juggle}", "task must be one of"),
        ("{planning: {latency_s: -1}}", "planning.latency_s must lie in"),
        ("{initial_arm_positions: [.nan, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]}", "initial_arm_positions"),
        ("{camera_noise: {preset: kinect}}", "camera_noise: unknown rgbd noise preset 'kinect'"),
        ("{camera_noise: {preset: kinect_v2, overrides: {dropout_share: .nan}}}", "dropout_share must be finite"),
        ("{camera_noise: {preset: kinect_v2, overrides: {axial_sigma_m: 0.5}}}", "metres are expected"),
    ],
)
def test_bad_numbers_are_refused_before_anything_is_built(text, named):
    """(A NaN yaw used to abort inside Drake: AllFinite(q_v) in SetPositionsAndVelocities.)"""
    with pytest.raises(ValueError, match=named):
        load_scenario(scenario_text=text)


@pytest.mark.slow
def test_pick_script_names_a_bad_field(tmp_path):
    report = tmp_path / "r.json"
    done = subprocess.run(
        [sys.executable, str(REPO_ROOT / "scripts" / "pick.py"), "--scenario_text", "{object: {yaw: .nan}}",
         "--json", str(report)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 1 and "object.yaw must be finite" in done.stderr
    assert json.loads(report.read_text())["error"] == "object.yaw must be finite, got nan"


@pytest.mark.slow
@pytest.mark.parametrize("category", ["watering_can", "drill"])
def test_place_over_box_layouts_keep_the_box_clear_of_the_object_at_both_ends(category):
    """The box lies between where each test instance rests and its target, touching neither (1 cm to spare),
    at every evaluated yaw."""
    base = load_scenario(place_over_box_scenario(category))
    box = base.obstacle
    assert base.task == "place" and box.present
    p_WB = np.array(base.table_xyz) + [*box.xy, TABLE_HEIGHT]  # the box's base centre
    half = np.array(box.size) / 2 + 0.01
    for name in ("test_0", "test_1", "test_2"):
        for yaw in PAPER_YAWS:
            scenario = replace_object(base, category=category, instance=name, yaw=float(yaw))
            model = resolve_object(scenario.object)
            for X_WO in (object_pose_on_table(scenario, model), place_target(scenario)):
                points_B = object_surface_W(model, X_WO, 4000)[0] - p_WB
                inside = np.all(np.abs(points_B[:, :2]) < half[:2], axis=1) & (points_B[:, 2] < box.size[2] + 0.01)
                assert not inside.any(), f"{name} at yaw {yaw} touches the box"
    start, target = np.array(base.object.xy), np.array(base.place.xy)
    assert np.sign(box.xy[1] - start[1]) != np.sign(box.xy[1] - target[1])  # between them along y
