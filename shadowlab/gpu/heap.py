"""Keep freed per-pixel arrays in the process's heap, so the next frame reuses memory that is
already mapped instead of page-faulting fresh memory (glibc only; elsewhere nothing changes).

Why (issue 27, "a faster truth"): a frame's per-pixel arrays (exact points, normals, ray
origins: tens of MB at 800x600 and above) are larger than glibc's mmap threshold (dynamic, at
most 32 MiB by default), so each is mapped fresh and unmapped when freed, and every allocation
pays one page fault per 4 KiB page on first touch — more than the arithmetic that fills it
(the frame's exact points took several times longer into fresh memory than into memory
already mapped, with a wide spread that is the kernel's; with two threads writing each unmap
also costs a TLB shoot-down). Raising glibc's mmap and trim thresholds
(``mallopt(3)``: ``M_MMAP_THRESHOLD``, ``M_TRIM_THRESHOLD``) keeps such blocks in the heap when
freed, where the next allocation of the same size takes them back.

What it costs: freed memory below :data:`RETAINED_LIMIT` stays resident in the process, and a
heap can hold more than separate mappings would (a freed 40 MB block does not serve a 41 MB
request). ``peak_rss_mib`` (docs/cost.md) is the process's resident peak during a measurement, so
it counts that memory as it counts everything else resident (the GL driver, the frame, caches).
Giving it back before each measurement (``malloc_trim``) was tried and dropped: every small
render then faulted its memory in again, and the inner test loop got slower, most of it in
system time.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import sys

#: Blocks up to this size come from (and return to) the heap; free memory up to this size at
#: the heap's top is not given back to the system. 512 MiB: a 4K frame's largest per-pixel
#: array is 8.3 Mpx × 24 bytes = 200 MB.
RETAINED_LIMIT = 512 * 2**20
#: glibc's ``mallopt`` parameter numbers (malloc.h).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3

_applied: bool | None = None


def keep_freed_memory() -> bool:
    """Set glibc's mmap and trim thresholds to :data:`RETAINED_LIMIT` once per process; True when
    they are set (glibc on Linux), False where the platform has no ``mallopt``."""
    global _applied
    if _applied is None:
        _applied = _set_thresholds()
    return _applied


def _set_thresholds() -> bool:
    """The two ``mallopt`` calls; False if the C library is not glibc or refuses."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # musl and others have no mallopt
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, RETAINED_LIMIT)) and bool(mallopt(_M_TRIM_THRESHOLD, RETAINED_LIMIT))
