"""The yaw-noise system, the evaluation's trials and statistics, and scripts/evaluate.py end to end."""

import dataclasses
import json
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw

from diagrams.autonomous_pick import MakePickDiagram
from diagrams.evaluation import (
    COMPONENTS,
    PLACEMENT_HALF_SIZE_M,
    PLACEMENT_MAX_YAW,
    Trial,
    clutter_trials,
    file_objects,
    generated_objects,
    make_trials,
    random_placements,
    run_trial,
    summarize,
)
from diagrams.evaluation_report import CampaignSettings, describe, report
from systems.messages import ObjectEstimate
from systems.perception.pose_noise import PoseYawOffset, draw_yaw_offset
from systems.robot_io.gravity_compensation import SimulationDiverged

REPO = Path(__file__).resolve().parents[1]


def evaluate(*arguments: str) -> subprocess.CompletedProcess:
    """scripts/evaluate.py as a user runs it."""
    command = [sys.executable, "scripts/evaluate.py", *arguments]
    return subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=600)


def test_yaw_offset_is_seeded_uniform_and_bounded():
    draws = np.array([draw_yaw_offset(0.2, seed) for seed in range(400)])
    assert np.all(np.abs(draws) <= 0.2)
    assert draws.min() < -0.18 and draws.max() > 0.18 and abs(draws.mean()) < 0.02  # spread over the range
    assert draw_yaw_offset(0.2, 7) == draw_yaw_offset(0.2, 7) != draw_yaw_offset(0.2, 8)
    assert draw_yaw_offset(0.0, 7) == 0.0
    with pytest.raises(ValueError, match="amplitude"):
        draw_yaw_offset(float("nan"), 0)


def test_pose_yaw_offset_turns_the_estimate_about_the_object_origin():
    dut = PoseYawOffset(0.15)
    context = dut.CreateDefaultContext()
    X_WO = RigidTransform(RollPitchYaw(0.0, 0.0, 0.4), [0.7, -0.1, 0.76])
    points = np.random.default_rng(0).normal(size=(50, 3))
    dut.get_input_port().FixValue(context, AbstractValue.Make(ObjectEstimate(True, "drill", X_WO, points)))
    out = dut.get_output_port().Eval(context)
    np.testing.assert_allclose(out.X_WO.translation(), X_WO.translation())
    np.testing.assert_allclose(RollPitchYaw(out.X_WO.rotation()).vector(), [0.0, 0.0, 0.55], atol=1e-12)
    np.testing.assert_array_equal(out.points_W, points)
    assert out.category == "drill"

    dut.get_input_port().FixValue(context, AbstractValue.Make(ObjectEstimate(False, message="nothing")))
    assert not dut.get_output_port().Eval(context).found


@pytest.mark.slow
def test_pick_diagram_inserts_the_noise_only_when_asked(scenario):
    assert not MakePickDiagram(scenario).GetSubsystemByName("perception").HasSubsystemNamed("registration_yaw_noise")
    noisy = MakePickDiagram(dataclasses.replace(scenario, registration_yaw_noise=0.2, random_seed=3))
    offset = noisy.GetSubsystemByName("perception").GetSubsystemByName("registration_yaw_noise").yaw_offset_rad
    assert offset == draw_yaw_offset(0.2, 3)


def test_trials_cover_objects_yaws_and_have_their_own_seeds(scenario):
    trials = make_trials(scenario, "watering_can", generated_objects("watering_can"), trials=2)
    assert len(trials) == 3 * 3 * 2
    assert {t.name for t in trials} == {"test_0", "test_1", "test_2"}
    assert {t.yaw for t in trials} == {0.25, 0.0, -0.25}
    seeds = [t.scenario.random_seed for t in trials]
    assert len(set(seeds)) == len(seeds) and seeds[0] == scenario.random_seed
    assert all(t.scenario.registration_yaw_noise == 0.2 for t in trials)
    assert trials[-1].scenario.object.instance == "test_2" and trials[-1].scenario.object.yaw == -0.25
    copy = pickle.loads(pickle.dumps(trials[5]))  # the worker processes get them pickled
    assert isinstance(copy, Trial) and copy.scenario.random_seed == trials[5].scenario.random_seed
    assert copy.scenario.object == trials[5].scenario.object

    with pytest.raises(ValueError, match="trials"):
        make_trials(scenario, "watering_can", generated_objects("watering_can"), trials=0)
    with pytest.raises(FileNotFoundError, match="nope.sdf"):
        file_objects([Path("nope.sdf")])


def _record(name, yaw, success, failed_stage="", seconds=1.0):
    stages = {} if failed_stage == "segmentation" else {"segmentation": 0.1, "pose": 0.05}
    if success or failed_stage == "execution":
        stages |= {"registration": 0.2, "planning": seconds - 0.35, "image_to_trajectory": seconds}
    return {"name": name, "yaw": yaw, "success": success, "failed_stage": failed_stage, "stages": stages}


def test_summary_counts_success_per_object_yaw_and_component():
    records = [
        _record("a", 0.25, True, seconds=1.0),
        _record("a", 0.0, True, seconds=2.0),
        _record("a", 0.0, False, "execution", seconds=3.0),
        _record("b", 0.25, False, "segmentation"),
        _record("b", 0.0, False, "registration"),
        _record("b", 0.0, True, seconds=4.0),
    ]
    summary = summarize(records)
    assert summary["success_rate"] == pytest.approx(0.5) and summary["trials"] == 6
    assert summary["per_instance"]["a"]["success_rate"] == pytest.approx(2 / 3)
    assert summary["per_instance"]["a"]["per_yaw"] == {"+0.25": 1.0, "+0.00": 0.5}
    assert summary["per_instance"]["b"]["attempts"] == 3 and summary["per_instance"]["b"]["successes"] == 1
    assert summary["always_succeeded"] == [] and summarize(records[:2] + records[5:])["always_succeeded"] == ["a", "b"]
    components = summary["components"]
    assert list(components) == list(COMPONENTS)
    assert components["segmentation"] == {"success_rate": pytest.approx(5 / 6), "reached": 6}
    assert components["pose"] == {"success_rate": 1.0, "reached": 5}
    assert components["registration"] == {"success_rate": pytest.approx(4 / 5), "reached": 5}
    assert components["execution"] == {"success_rate": pytest.approx(3 / 4), "reached": 4}
    stages = summary["stages"]
    assert stages["image_to_trajectory_s_median"] == pytest.approx(2.5)  # of 1, 2, 3, 4
    assert stages["image_to_trajectory_s_mean"] == pytest.approx(2.5)
    assert stages["image_to_trajectory_s_std"] == pytest.approx(np.std([1, 2, 3, 4]))
    assert stages["segmentation_s_mean"] == pytest.approx(0.1)
    assert "tool_frames_judged" not in summary  # no pick perceived a tool frame


def test_summary_gives_the_perceived_tool_frames_errors_where_they_were_judged():
    records = [_record("a", 0.0, True), _record("a", 0.25, True), _record("b", 0.0, False, "segmentation")]
    for record, tip, axis in zip(records[:2], (0.004, 0.012), (0.01, 0.03), strict=True):
        record["perception"] = {"tool_errors": {"tip_m": tip, "axis_rad": axis}}
    summary = summarize(records)
    assert summary["tool_frames_judged"] == 2
    assert summary["tool_tip_error_m_median"] == pytest.approx(0.008)
    assert summary["tool_axis_error_rad_median"] == pytest.approx(0.02)


def test_random_placements_are_seeded_unseen_and_within_the_region(scenario):
    trials = random_placements(scenario, "drill", 200)
    assert [t.name for t in trials[:2]] == ["extra_1000", "extra_1001"] and all(t.with_oracle for t in trials)
    offsets = np.array([np.subtract(t.scenario.object.xy, scenario.object.xy) for t in trials])
    assert np.all(np.abs(offsets) <= PLACEMENT_HALF_SIZE_M) and np.all(
        np.abs(offsets).max(axis=0) > 0.9 * np.array(PLACEMENT_HALF_SIZE_M)
    )
    yaws = np.array([t.scenario.object.yaw for t in trials])
    assert np.all(np.abs(yaws) <= PLACEMENT_MAX_YAW) and np.abs(yaws).max() > 0.9 * PLACEMENT_MAX_YAW
    assert len({t.scenario.random_seed for t in trials}) == 200 and all(
        t.scenario.object.category == "drill" for t in trials
    )
    # Placement k comes from its own seed alone: a shorter campaign is the longer one's beginning.
    first = random_placements(scenario, "drill", 3)
    assert [t.scenario.object.xy for t in first] == [t.scenario.object.xy for t in trials[:3]]
    with pytest.raises(ValueError, match="taught category|unknown"):
        random_placements(scenario, "teapot", 3)


def test_summary_of_random_placements_says_what_ground_truth_could_do():
    records = [_record("a", 0.1, True), _record("b", 0.2, False, "grasp"), _record("c", 0.3, False, "planning")]
    for record, oracle in zip(records, (True, True, False), strict=True):
        record["oracle"] = {"success": oracle, "failed_stage": "" if oracle else "planning", "message": ""}
    summary = summarize(records)
    assert summary["oracle_success_rate"] == pytest.approx(2 / 3)
    assert summary["success_rate_given_oracle"] == pytest.approx(1 / 2)
    assert "oracle_success_rate" not in summarize([_record("a", 0.1, True)])  # the paper's placements


def test_the_paper_placements_with_ground_truth_table_what_the_true_grasps_lift_beside_the_pick(
    scenario, tmp_path, capsys
):
    """--ground-truth: every trial also runs the ground-truth pick; the summary and the tables give its lifts per
    object and yaw, and the autonomous pick's share of them; the report stays the paper's form, not the map's."""
    trials = make_trials(scenario, "drill", generated_objects("drill"), trials=1, with_ground_truth=True)
    assert all(t.with_oracle and t.placement == "paper" for t in trials)
    assert not any(t.with_oracle for t in make_trials(scenario, "drill", generated_objects("drill"), trials=1))
    records = [
        _record("a", 0.25, True),
        _record("a", 0.0, False, "registration"),
        _record("b", 0.25, False, "grasp"),
        _record("b", 0.0, True),
    ]
    for record, truth in zip(records, (True, True, False, True), strict=True):
        record |= {"placement": "paper", "trial": 0, "seed": 0, "registration_yaw_offset_rad": 0.0, "message": "m"}
        record["oracle"] = {"success": truth, "failed_stage": "" if truth else "grasp", "message": ""}
    summary = summarize(records)
    assert summary["ground_truth_per_instance"]["b"]["per_yaw"] == {"+0.25": 0.0, "+0.00": 1.0}
    assert summary["ground_truth_always_succeeded"] == ["a"] and summary["always_succeeded"] == []
    assert summary["success_rate_given_oracle"] == pytest.approx(2 / 3)
    assert "[ground truth: FAILED at grasp]" in describe(records[2])
    path = tmp_path / "truth.json"
    report(CampaignSettings(category="drill", trials=1), records, first_seed=0, json_path=path)
    printed = capsys.readouterr().out
    assert "Table II form" in printed and "Random placements" not in printed
    assert "ground truth: 75 % lifted; objects with every pick a success: 1/2 (a)" in printed
    assert "the autonomous pick lifted 67 % of what ground truth lifted" in printed
    assert json.loads(path.read_text())["placement"] == "paper"
    refused = evaluate("--ground-truth", "--scene", "clutter")
    assert refused.returncode == 2 and "--ground-truth is for one object" in refused.stderr


@pytest.mark.slow
def test_evaluate_script_end_to_end(tmp_path):
    """One pick of one unseen can at one yaw, with the registration's yaw noise: tables, JSON and figure."""
    report = tmp_path / "evaluation.json"
    run = evaluate("--trials", "1", "--instances", "test_1", "--yaws", "0", "--seed", "5", "--json", str(report))
    assert run.returncode == 0, run.stderr
    results = json.loads(report.read_text())
    assert results["per_instance"]["test_1"]["success_rate"] == 1.0, results["records"]
    assert results["success_rate"] == 1.0
    assert 0.1 < results["stages"]["image_to_trajectory_s_median"] < 30
    (record,) = results["records"]
    assert record["seed"] == 5 and record["registration_yaw_offset_rad"] == pytest.approx(draw_yaw_offset(0.2, 5))
    assert "Table II form" in run.stdout and "complete pipeline" in run.stdout
    png = report.with_suffix(".png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_evaluate_refuses_a_box_without_the_place_task():
    refused = evaluate("--obstacle", "--trials", "1")
    assert refused.returncode == 2 and "--obstacle needs --task place" in refused.stderr


def test_random_placements_refuse_given_yaws():
    refused = evaluate("--placement", "random", "--yaws", "0")
    assert refused.returncode == 2 and "--placement random draws its own yaws" in refused.stderr


def test_summary_of_cluttered_tables_keeps_the_largest_move_of_another_object(scenario):
    trials = clutter_trials(scenario, "drill", 3)
    assert [t.scenario.requested_category for t in trials] == ["drill"] * 3 and trials[0].scenario.clutter
    records = [
        _record("clutter_report_0", 0.0, True) | {"clutter": ["box"], "others_moved_m": [0.001]},
        _record("clutter_report_1", 0.0, False, "planning") | {"clutter": ["bowl", "box"], "others_moved_m": [0, 0.05]},
    ]
    for record in records:
        record |= {"requested_category": "drill", "perception": {"category": "drill"}}
    summary = summarize(records)
    assert summary["others_moved_m_max"] == 0.05 and summary["picks_moving_others"] == 1
    assert summary["requested_category_share"] == 1.0
    assert "others_moved_m_max" not in summarize([_record("test_0", 0.0, True)])


DIVERGED = SimulationDiverged("the simulated plant's state is not finite at t = 41.2 s")
DRAKE_CHECK = SystemExit("Failure at multibody_plant.h: condition 'AllFinite(q_v)' failed.")


@pytest.mark.parametrize("failure", [DIVERGED, DRAKE_CHECK])
def test_a_table_whose_simulation_fails_counts_its_objects_uncleared_and_the_campaign_goes_on(
    scenario, monkeypatch, failure
):
    """pydrake ends the process (SystemExit) where a Drake check fails, as on a plant state blown up to NaN: in a
    worker that ended the whole campaign with nothing reported (report table 7, 2026-12-06). The table is now a
    failed record, its familiar objects all counted and none cleared; the summary's largest distractor move is the
    judged tables'."""
    import diagrams.autonomous_pick

    def failing(*args, **kwargs):
        raise failure

    monkeypatch.setattr(diagrams.autonomous_pick, "run_pick", failing)
    (trial,) = clutter_trials(dataclasses.replace(scenario, task="clear"), "watering_can", 1)
    record = run_trial(trial)
    assert not record["success"] and record["failed_stage"] == "simulation"
    assert record["message"].startswith("the simulation failed: ") and str(failure) in record["message"]
    familiar = 1 + sum(bool(other.instance) for other in trial.scenario.clutter)  # (the object and its neighbours)
    assert familiar >= 2 and record["clear"]["familiar_objects"] == familiar
    assert record["seed"] == trial.scenario.random_seed  # (what the record said before it ran is kept)
    judged = _record("clutter_report_1", 0.0, True) | {"clear": {"objects": [{}], "familiar_objects": 2,
        "objects_cleared": 2, "taken_on": [{"attempts": 1}], "others_moved_m_max": 0.004}}  # fmt: skip
    summary = summarize([record, judged])
    assert summary["familiar_objects"] == familiar + 2 and summary["objects_cleared"] == 2
    assert summary["others_moved_m_max"] == 0.004
