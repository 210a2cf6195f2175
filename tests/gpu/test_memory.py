"""Peak resident memory (shadowlab.gpu.memory): the peak follows what the process touched and can be
reset, so that a measurement reports its own peak, not the process's history."""
from __future__ import annotations

import mmap

import numpy as np

from shadowlab.gpu import memory

from helpers import SMALL


def test_peak_rises_with_touched_memory_and_resets():
    memory.reset_peak()
    before = memory.peak_bytes()
    # 64 MiB of fresh pages, every one written: an anonymous mapping, not malloc, which may
    # hand back heap pages that an earlier test left resident (then the peak would not move).
    block = mmap.mmap(-1, 64 * 2**20)
    np.frombuffer(block, np.uint8)[::4096] = 1
    during = memory.peak_bytes()
    block.close()
    assert during - before >= 60 * 2**20
    if memory.reset_peak():  # Linux: the peak restarts at the current (smaller) resident size
        assert memory.peak_bytes() < during - 32 * 2**20


def test_a_measurement_reports_its_setup_and_peak(lab):
    m = lab.measure("box_on_plane", "shadow_polygons", SMALL)
    assert m.setup_ms >= m.stats["preprocess_ms"] > 0  # the preprocessing is part of the set-up
    assert m.peak_rss_bytes >= 50 * 2**20  # at least the interpreter, numpy and the GL driver
