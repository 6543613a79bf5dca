import threading
import time

from systems.parallel import THREADS, parallel_calls, parallel_map


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
