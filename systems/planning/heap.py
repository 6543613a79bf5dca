"""The process's heap kept for numpy's temporaries.

glibc's malloc gives the freed top of its heap back to the system once it exceeds a threshold, and numpy's next
large temporaries fault their pages in again. A STOMP iteration allocates and frees arrays of 16 rollouts x 16
keyframes x hundreds of spheres and sphere pairs many times over; keeping TOP_PAD_BYTES of freed heap
(mallopt's M_TOP_PAD) made the slowest report-range turns 8 % faster (scripts/benchmark_planner.py). Elsewhere than
glibc nothing changes.
"""

import ctypes
import functools

M_TOP_PAD = -2  # glibc's mallopt parameter
TOP_PAD_BYTES = 64 << 20


@functools.cache
def keep_freed_heap() -> bool:
    """Keeps up to TOP_PAD_BYTES of freed heap for reuse, once per process; whether glibc took the setting."""
    try:
        return bool(ctypes.CDLL("libc.so.6").mallopt(M_TOP_PAD, TOP_PAD_BYTES))
    except (OSError, AttributeError):
        return False
