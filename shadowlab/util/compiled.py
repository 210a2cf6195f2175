"""Compiled-kernel plumbing shared by every numba module of the lab: :func:`njit` with the lab's
settings (on-disk cache where one can be written, the GIL released, numpy's error model so x/0
gives ±inf as numpy does) and the two-core split of per-pixel passes (:func:`split`,
:func:`in_parts`: row bands, one per core, each writing its own slice of the outputs)."""
from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

from numba import njit as _numba_njit

#: The lab's numba settings for kernels that must give numpy's bits (no fastmath: no contraction
#: of ``a*b + c`` into fused multiply-adds).
JIT = dict(cache=True, nogil=True, error_model="numpy")

def njit(*args, **kwargs):
    """numba's ``njit``, compiled into numba's on-disk cache where one can be written, and
    without it where none can (a read-only install with no writable ``NUMBA_CACHE_DIR``: numba
    refuses ``cache=True`` there when the function is decorated)."""
    def decorate(fn):
        try:
            return _numba_njit(**kwargs)(fn)
        except RuntimeError as exc:  # "cannot cache function ...: no locator available"
            if not kwargs.get("cache") or "cannot cache" not in str(exc):
                raise
            return _numba_njit(**{**kwargs, "cache": False})(fn)
    return decorate(args[0]) if args and callable(args[0]) else decorate


def cores() -> int:
    """The CPUs this process may run on (its affinity; cgroup-limited containers included)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # not Linux
        return max(1, os.cpu_count() or 1)


#: Work items below this size run in the calling thread alone (handing work to a helper thread
#: costs more than such an item's arithmetic).
MIN_PART = 1 << 15
#: Helper threads for :func:`in_parts`, made on first use in each process (pid: a forked child
#: has no threads of its parent's pool and makes its own).
_POOL: tuple[int, ThreadPoolExecutor] | None = None
_POOL_LOCK = threading.Lock()


def in_parts(fn, bounds: list[tuple[int, int]]) -> list:
    """``[fn(a, b) for a, b in bounds]``, the first part in the calling thread and the others
    on helper threads at the same time (the kernels release the GIL): the per-frame passes over
    every pixel use both cores. Each part writes its own slice of the outputs, so the bits do
    not depend on the split."""
    global _POOL
    if len(bounds) == 1:
        return [fn(*bounds[0])]
    with _POOL_LOCK:
        if _POOL is None or _POOL[0] != os.getpid():
            _POOL = (os.getpid(), ThreadPoolExecutor(max(1, cores() - 1),
                                                     thread_name_prefix="compiled_truth"))
        pool = _POOL[1]
    rest = [pool.submit(fn, a, b) for a, b in bounds[1:]]
    first = fn(*bounds[0])
    return [first] + [f.result() for f in rest]


def split(total: int, work: int | None = None) -> list[tuple[int, int]]:
    """``total`` items (rows, points) cut into one contiguous range per core, fewer when the
    ``work`` (items of output, default ``total``) is under :data:`MIN_PART` per range."""
    work = total if work is None else work
    parts = max(1, min(cores(), work // MIN_PART, total))
    edges = [total * k // parts for k in range(parts + 1)]
    return [(edges[k], edges[k + 1]) for k in range(parts)]
