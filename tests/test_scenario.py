"""Scenario loading: defaults, overlays, and clear errors for bad input."""

import json
import subprocess
import sys

import pytest

from diagrams.paths import REPO_ROOT
from diagrams.scenario import load_scenario


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
    ],
)
def test_bad_numbers_are_refused_before_anything_is_built(text, named):
    """(A NaN yaw used to abort inside Drake: AllFinite(q_v) in SetPositionsAndVelocities.)"""
    with pytest.raises(ValueError, match=named):
        load_scenario(scenario_text=text)


def test_pick_script_names_a_bad_field(tmp_path):
    report = tmp_path / "r.json"
    done = subprocess.run(
        [sys.executable, str(REPO_ROOT / "scripts" / "pick.py"), "--scenario_text", "{object: {yaw: .nan}}",
         "--json", str(report)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 1 and "object.yaw must be finite" in done.stderr
    assert json.loads(report.read_text())["error"] == "object.yaw must be finite, got nan"
