"""The C heap during a long replay: glibc's mmap threshold kept at its starting 128 KiB.

glibc raises the size above which a block gets its own mapping each time
such a block is freed (up to 32 MiB). A replay frees a block's columns
(hundreds of KiB) thousands of times, so after the first few they come
from the main heap, which long-lived small objects then pin: the resident
size climbs with the mission. A fixed threshold returns each large block
to the system when it is freed (docs/benchmarks.md, "the end of a long
replay, one method at a time": 24 h peak RSS 253 MB instead of 266-276).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

M_MMAP_THRESHOLD = -3          # mallopt's parameter number (glibc malloc.h)
MMAP_THRESHOLD_BYTES = 128 * 1024   # glibc's own starting value: fixing it stops the dynamic raise

_done = False


def fix_mmap_threshold() -> bool:
    """Keep glibc's mmap threshold at 128 KiB for this process (once); False where there is no glibc mallopt."""
    global _done
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
