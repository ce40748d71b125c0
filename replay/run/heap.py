"""The C heap during a long replay (an hour of mission or more): glibc's mmap threshold kept at its starting 128 KiB.

glibc raises the size above which a block gets its own mapping each time
such a block is freed (up to 32 MiB). A replay frees a block's columns
(hundreds of KiB) thousands of times, so after the first few they come
from the main heap, which long-lived small objects then pin: the resident
size climbs with the mission. A fixed threshold returns each large block
to the system when it is freed (docs/benchmarks.md, "the end of a long
replay, one method at a time": 24 h peak RSS 253 MB instead of 266-276).
It costs a fresh mapping, and its page faults, per large allocation: the
1700 s sample trial took 17x the page faults and some 30 % more CPU with
it, so only replays of an hour of mission or more set it (for the rest of
the process: mallopt has no undo that restores the dynamic threshold).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

M_MMAP_THRESHOLD = -3          # mallopt's parameter number (glibc malloc.h)
MMAP_THRESHOLD_BYTES = 128 * 1024   # glibc's own starting value: fixing it stops the dynamic raise
LONG_MISSION_S = 3600.0        # from this span of mission on, the replay fixes the threshold

_done = False


def fix_mmap_threshold(mission_s: float = LONG_MISSION_S) -> bool:
    """Keep glibc's mmap threshold at 128 KiB for this process (once) when `mission_s` spans at least an hour;
    False when it is not set (a shorter mission, or no glibc mallopt)."""
    global _done
    if mission_s < LONG_MISSION_S:
        return _done
    if _done:
        return True
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False     # musl and others: no mallopt, their own heap policy
    _done = bool(mallopt(ctypes.c_int(M_MMAP_THRESHOLD), ctypes.c_int(MMAP_THRESHOLD_BYTES)))
    return _done
