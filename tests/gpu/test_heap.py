"""shadowlab.gpu.heap: freed per-pixel arrays stay in the process's heap for the next frame."""
from __future__ import annotations

import ctypes
import ctypes.util
import sys

import numpy as np
import pytest

from shadowlab.gpu import heap


class _Mallinfo2(ctypes.Structure):
    """glibc's ``struct mallinfo2`` (≥ 2.33): ``fordblks`` is the free bytes the heap keeps."""

    _fields_ = [(name, ctypes.c_size_t) for name in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                 "keepcost")]


def _mallinfo2():
    libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    try:
        fn = libc.mallinfo2
    except AttributeError:
        pytest.skip("no mallinfo2 (not glibc ≥ 2.33)")
    fn.restype = _Mallinfo2
    return fn


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_a_freed_frame_sized_array_stays_in_the_heap_and_is_reused():
    """After keep_freed_memory, a 40 MB array (above glibc's default 32 MiB mmap ceiling, so
    mapped and unmapped afresh without it) comes from the heap, stays there when freed, and the
    next array of that size is served from that free memory. Counted as differences, so memory
    other code mapped or freed earlier in the process does not matter."""
    mallinfo2 = _mallinfo2()
    assert heap.keep_freed_memory() is True
    assert heap.keep_freed_memory() is True  # once per process; asking again changes nothing
    n = 40 * 2**20
    mapped = mallinfo2().hblkhd  # bytes in blocks of their own mapping (other code's, before)
    a = np.ones(n, np.uint8)
    assert mallinfo2().hblkhd - mapped < n  # not a block of its own mapping
    del a
    free = mallinfo2().fordblks
    assert free >= n  # freed into the heap, not given back to the system
    b = np.ones(n, np.uint8)
    assert mallinfo2().fordblks <= free - n  # taken back from the heap's free memory
    assert mallinfo2().hblkhd - mapped < n
    del b
