import threading
import time

import numpy as np

from diagrams.generation.objects.library import resolve_object
from diagrams.planning_scene import make_pick_motions, object_surface_W, true_grasp_poses
from diagrams.station import object_pose_on_table
from systems.parallel import THREADS, parallel_calls, parallel_map
from systems.planning import pick_motions

# Both hands under the table top, at its front edge, the torso straight (as tests/test_stomp.py's).
BELOW_TABLE = np.array([0, 0.15, 0, -0.1, 0, 0, 0, 0, -0.15, 0, -0.1, 0, 0, 0.0, 0.0])


def test_results_come_in_the_items_order_whichever_finishes_first():
    def slow_first(k):
        time.sleep(0.05 if k == 0 else 0.0)
        return k * k, threading.current_thread().name

    results = parallel_map(slow_first, range(6))
    assert [value for value, _ in results] == [k * k for k in range(6)]
    assert len({name for _, name in results}) <= THREADS


def test_a_nested_call_runs_in_its_pieces_thread():
    def piece(k):
        return parallel_map(lambda j: (k, j, threading.current_thread().name), range(3))

    for k, inner in enumerate(parallel_map(piece, range(4))):
        assert [(a, b) for a, b, _ in inner] == [(k, 0), (k, 1), (k, 2)]
        assert len({name for _, _, name in inner}) == 1  # one after another, in the piece's own thread


def test_parallel_calls_returns_each_functions_result_in_order():
    def slow(value):
        time.sleep(0.05)
        return value

    assert parallel_calls(lambda: slow("first"), lambda: "second", lambda: 3) == ["first", "second", 3]


def test_a_reach_whose_scene_is_built_beside_its_first_ik_goal_is_the_reach_built_one_after_the_other(
    scenario, monkeypatch
):
    """The reach builds the sphere model's scene (the object as seen) beside its first IK goal: the same keyframes,
    to the bit, as with the two one after the other (from under the table: a path STOMP plans)."""
    model = resolve_object(scenario.object)
    points, _ = object_surface_W(model, object_pose_on_table(scenario, model), 2000)
    poses = true_grasp_poses(scenario)
    pregrasps = {side: poses[f"{side}_pregrasp"] for side in ("left", "right")}
    motions = make_pick_motions(scenario)
    beside = motions.reach(BELOW_TABLE, pregrasps, points).keyframes
    monkeypatch.setattr(pick_motions, "parallel_calls", lambda *functions: [f() for f in functions])
    after = motions.reach(BELOW_TABLE, pregrasps, points).keyframes
    assert len(beside) > 2  # (a path STOMP planned, not the straight move alone)
    np.testing.assert_array_equal(beside, after)
