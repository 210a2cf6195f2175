"""Repeatable timings of a technique's own passes (DESIGN §10).

Warm-up runs, then ``repeat`` timed runs; the figure is the median and the interquartile
range, in milliseconds. GPU work is timed with the wall clock around ``ctx.finish()``: on Mesa's
llvmpipe, GL timer queries do not measure the rasterisation work, so they are not used there.
On other renderers the GL_TIME_ELAPSED query time is reported too.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from . import gl

WALL_CLOCK = "wall clock around ctx.finish() (perf_counter), median and IQR over repeats after warm-up"


@dataclass
class Timing:
    """Median and IQR (ms) of the timed runs, and the raw samples (ms)."""

    median_ms: float
    iqr_ms: float
    samples_ms: list[float]
    gpu_median_ms: float | None = None

    def columns(self) -> dict:
        """The metrics.csv columns of this timing."""
        out = {"time_ms_median": self.median_ms, "time_ms_iqr": self.iqr_ms, "time_repeats": len(self.samples_ms)}
        if self.gpu_median_ms is not None:
            out["gpu_time_ms_median"] = self.gpu_median_ms
        return out


def method_description() -> str:
    """How this process times GPU work, for run.json."""
    if gl.is_software_renderer():
        return WALL_CLOCK + "; GL timer queries not used (software rasteriser)"
    return WALL_CLOCK + "; GL_TIME_ELAPSED queries reported as gpu_time_ms_median"


def time_passes(run: Callable[[], None], repeat: int = 5, warmup: int = 1, gpu: bool = True,
                on_step: Callable[[], None] | None = None) -> Timing:
    """Time ``run`` (the technique's passes); ``gpu`` waits for GL to finish inside each run.

    ``on_step`` is called after every run (progress display).
    """
    ctx = gl.context() if gpu else None
    use_query = gpu and not gl.is_software_renderer()
    for _ in range(warmup):
        run()
        if ctx is not None:
            ctx.finish()
        if on_step:
            on_step()
    samples, gpu_samples = [], []
    for _ in range(max(1, repeat)):
        query = ctx.query(time=True) if use_query else None
        t0 = time.perf_counter()
        if query is not None:
            with query:
                run()
        else:
            run()
        if ctx is not None:
            ctx.finish()
        samples.append((time.perf_counter() - t0) * 1e3)
        if query is not None:
            gpu_samples.append(query.elapsed / 1e6)
        if on_step:
            on_step()
    q1, med, q3 = np.percentile(samples, [25, 50, 75])
    return Timing(float(med), float(q3 - q1), samples, float(np.median(gpu_samples)) if gpu_samples else None)
