"""Scenario loading: defaults, overlays, and clear errors for bad input."""

import pytest

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
