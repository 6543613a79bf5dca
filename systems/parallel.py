"""Independent pieces of one stage's work on the computer's cores, with the same results on any number of them.

A pick runs one stage at a time, and the numerics inside each stage run on one thread (campaign.SINGLE_THREADED:
threaded reductions round differently from run to run). Where a stage holds pieces that do not depend on each
other (the segmenter's image and its mirror image, the registration's yaw hypotheses, the reach's sphere-model
scene and its first IK goal), those pieces run on THREADS threads at once, each piece computed alone and
single-threaded as before and collected in order: the answer is the same as one after the other, whatever the
machine's load. Only code that releases Python's global lock gains (torch, numpy's larger operations, scipy's
qhull and k-d tree queries); open3d's calls hold it.
"""

import threading
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor

THREADS = 2  # the project's machines have two cores
_NAME = "parallel_map"

_executor: ThreadPoolExecutor | None = None


def parallel_map(function: Callable, items: Iterable) -> list:
    """[function(item) for item in items], the calls on up to THREADS threads, the results in the items' order.

    Called from within a piece, the calls run one after another in that piece's thread (the pool's threads must not
    wait on each other).
    """
    global _executor
    items = list(items)
    if len(items) < 2 or threading.current_thread().name.startswith(_NAME):
        return [function(item) for item in items]
    if _executor is None:
        _executor = ThreadPoolExecutor(THREADS, thread_name_prefix=_NAME)
    return list(_executor.map(function, items))


def parallel_calls(*functions: Callable) -> list:
    """[f() for f in functions], on up to THREADS threads as parallel_map's items (e.g. two pieces of different
    kinds), the results in the functions' order."""
    return parallel_map(lambda function: function(), functions)
