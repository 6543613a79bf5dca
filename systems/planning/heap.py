"""The process's heap kept for numpy's temporaries.

glibc's malloc serves allocations above its mmap threshold (128 KiB at first) by mapping fresh pages and unmaps
them when they are freed, and gives the freed top of its heap back to the system beyond its trim threshold; the
next large temporaries then fault their pages in again. A STOMP iteration allocates and frees arrays of 16 rollouts
x 16 keyframes x hundreds of spheres and sphere pairs many times over. keep_freed_heap() serves allocations up to
MMAP_THRESHOLD_BYTES from the heap and keeps up to TRIM_THRESHOLD_BYTES of it freed for reuse (mallopt): long
plans run faster, most in a process where OMPL and KTO had run (docs/history/planning_parameters.md). Between two
picks, return_freed_heap() gives what is free back (a process that runs many picks keeps its resident memory down:
the heap's free part grew from 246 to 328 MB over three clear tables). Elsewhere than glibc nothing changes.
"""

import ctypes
import functools

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameters
MMAP_THRESHOLD_BYTES = 64 << 20
TRIM_THRESHOLD_BYTES = 256 << 20


@functools.cache
def keep_freed_heap() -> bool:
    """Large temporaries from the heap and freed heap kept for reuse, once per process; whether glibc took it."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        return bool(
            libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
            and libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES)
        )
    except (OSError, AttributeError):
        return False


def return_freed_heap() -> bool:
    """Gives the heap's free pages back to the system (malloc_trim); whether glibc released any."""
    try:
        return bool(ctypes.CDLL("libc.so.6").malloc_trim(0))
    except (OSError, AttributeError):
        return False
