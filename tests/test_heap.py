"""shadowlab.heap: freed per-pixel arrays stay in the process's heap for the next frame."""
from __future__ import annotations

import ctypes
import ctypes.util
import sys

import numpy as np
import pytest

from shadowlab import heap


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
    next array of that size takes the same memory back."""
    mallinfo2 = _mallinfo2()
    assert heap.keep_freed_memory() is True
    assert heap.keep_freed_memory() is True  # once per process; asking again changes nothing
    n = 40 * 2**20
    a = np.ones(n, np.uint8)
    address = a.ctypes.data
    assert mallinfo2().hblkhd < n  # not a block of its own mapping
    del a
    assert mallinfo2().fordblks >= n  # freed into the heap, not given back to the system
    b = np.ones(n, np.uint8)
    assert b.ctypes.data == address
