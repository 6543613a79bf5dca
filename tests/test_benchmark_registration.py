"""benchmark_registration.py's views of the picks' own first frames (--pick-frames):
diagrams/benchmarks/pick_frames.py."""

import dataclasses

import numpy as np
import pytest

from diagrams.benchmarks import pick_frames
from diagrams.benchmarks.pick_frames import first_pick_frame, pick_frame_trials
from diagrams.benchmarks.registration import true_grasps
from diagrams.evaluation import make_trials
from diagrams.generation.objects.library import resolve_object
from diagrams.scenario import load_scenario
from diagrams.station import object_pose_on_table
from systems.messages import ObjectEstimate
from systems.perception.pose_noise import draw_yaw_offset
from systems.perception.shape_registrar import registrar_of, shape_space_file, wider_shape_space_file


def yaw(X) -> float:
    R = X.rotation().matrix()
    return float(np.arctan2(R[1, 0], R[0, 0]))


@pytest.mark.slow
def test_the_picks_first_frame_is_its_camera_frame_with_the_papers_yaw_noise_and_registers_near_the_truth():
    """evaluate.py's third pick of the test cans (seed 2: test_0 at yaw -0.25): the frame is the same with and
    without the registration noise, and the noise turns the initial pose by the seed's draw, as in the pick."""
    base = load_scenario()
    trial = make_trials(base, "watering_can", {"test_0": {"instance": "test_0", "file": ""}}, 1)[2]
    scenario = trial.scenario
    assert scenario.random_seed == base.random_seed + 2 and scenario.registration_yaw_noise == 0.2
    noisy, X_WO = first_pick_frame(scenario)
    plain, X_WO_plain = first_pick_frame(dataclasses.replace(scenario, registration_yaw_noise=0.0))
    # The truth is the object as it settled, the same either way, and within millimetres of where it was placed.
    assert X_WO.IsExactlyEqualTo(X_WO_plain)
    placed = object_pose_on_table(scenario, resolve_object(scenario.object))
    assert np.linalg.norm(X_WO.translation() - placed.translation()) < 0.005
    assert noisy.found and noisy.category == "watering_can"
    np.testing.assert_array_equal(noisy.points_W, plain.points_W)
    offset = draw_yaw_offset(0.2, scenario.random_seed)
    assert abs(offset) > 0.01 and abs(yaw(noisy.X_WO) - yaw(plain.X_WO) - offset) < 1e-9
    category = "watering_can"
    result = registrar_of(category, shape_space_file(category), wider_shape_space_file(category)).register(
        noisy.points_W, noisy.X_WO, noisy.viewpoint_W, noisy.view
    )
    for name, X_OG in true_grasps(category, "test_0").items():
        assert np.linalg.norm(result.grasp_poses_W[name].translation() - (X_WO @ X_OG).translation()) < 0.015, name


@pytest.mark.slow
def test_pick_frame_trials_judge_every_pick_of_the_campaign():
    rows = pick_frame_trials(load_scenario(), "drill", {"test_1": {"instance": "test_1", "file": ""}}, 1, [0.0])
    (row,) = rows
    assert row["instance"] == "test_1" and row["seed"] == 0 and row["yaw"] == 0.0
    assert not row["poor_fit"] and row["grasp_translation_error_m"] < 0.015 and row["chamfer_m"] < 0.01
    assert row["handed_on"] and not row["handed_on_off"]  # the grasps the pick builds on the seen parts


@pytest.mark.slow
def test_a_frame_in_which_perception_finds_nothing_is_a_row_with_its_reason(monkeypatch):
    nothing = ObjectEstimate(False, message="no")
    monkeypatch.setattr(pick_frames, "first_pick_frame", lambda scenario: (nothing, None))
    rows = pick_frame_trials(load_scenario(), "drill", {"test_1": {"instance": "test_1", "file": ""}}, 1, [0.0, 0.25])
    assert [(row["yaw"], row["found"], row["message"]) for row in rows] == [(0.0, False, "no"), (0.25, False, "no")]


def test_a_kept_first_frame_is_read_again_and_a_new_scenario_or_part_network_simulates_anew(monkeypatch, tmp_path):
    simulated = []

    def simulate(scenario):
        simulated.append(scenario.random_seed)
        return ObjectEstimate(False, message=f"frame of seed {scenario.random_seed}"), None

    monkeypatch.setattr(pick_frames, "first_pick_frame", simulate)
    scenario = load_scenario()
    first = pick_frames.cached_first_frame(scenario, tmp_path)
    again = pick_frames.cached_first_frame(scenario, tmp_path)
    assert simulated == [0] and again[0].message == first[0].message == "frame of seed 0"
    other = pick_frames.cached_first_frame(dataclasses.replace(scenario, random_seed=5), tmp_path)
    assert simulated == [0, 5] and other[0].message == "frame of seed 5"
    weights = tmp_path / "part_segmenter.pt"
    weights.write_bytes(b"another part network")
    monkeypatch.setattr(pick_frames, "DEFAULT_PART_WEIGHTS", weights)
    pick_frames.cached_first_frame(scenario, tmp_path)
    assert simulated == [0, 5, 0]
