"""scripts/benchmark_latency.py (diagrams/benchmarks/latency.py) without its picks: which picks it runs and what its
JSON says of their records."""

import pytest

from diagrams.benchmarks import latency as benchmark_latency


def test_the_latency_benchmark_runs_thirty_distinct_picks_of_both_categories():
    trials = benchmark_latency.latency_trials([0.25, 0.0, -0.25], 6, None)
    assert len(trials) == 30
    assert {t.scenario.object.category for t in trials} == {"watering_can", "drill"}
    assert len({t.scenario.random_seed for t in trials}) == 30
    assert {t.name for t in trials} == {"test_0", "test_1", "test_2"} | {f"extra_{401 + k}" for k in range(6)}
    assert all(t.scenario.camera_noise.preset == "kinect_v2" for t in trials)  # the default sensor


def test_the_latency_summary_takes_the_end_to_end_time_not_the_stages_sum():
    def record(end_to_end, planning, success=True):
        stages = {"segmentation": 0.05, "pose": 0.01, "registration": 0.1, "planning": planning}
        return {"success": success, "stages": {**stages, "image_to_trajectory": end_to_end}}

    records = [record(0.5, 0.3), record(0.7, 0.5), record(2.0, 0.2, success=False)]
    summary = benchmark_latency.summarize(records)
    assert summary["picks"] == 3 and summary["lifted"] == 2
    assert summary["image_to_trajectory_s_median"] == pytest.approx(0.7)
    assert summary["planning_s_median"] == pytest.approx(0.3)
    # What the stages leave of each pick's end-to-end time (0.04, 0.04, 1.64 s), its median.
    assert summary["between_stages_s_median"] == pytest.approx(0.04)
    for key in ("image_to_trajectory_s_p95", "segmentation_s_median", "pose_s_median", "registration_s_median"):
        assert key in summary
