"""Repeatable timings of a technique's own passes (docs/metrics.md#timing-and-cost).

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

#: The metrics columns a timing fills (:meth:`Timing.columns`); with every ``*_ms`` figure they are
#: what a study's timing phase measures alone on the host and what accuracy comparisons leave out.
TIMING_COLUMNS = ("time_ms_median", "time_ms_iqr", "time_ms_q25", "time_ms_q75", "time_repeats",
                  "gpu_time_ms_median")


def is_time_column(name: str) -> bool:
    """Whether a metrics column is a time: the frame times and every ``*_ms`` cost figure
    (``preprocess_ms``, ``pass_<name>_ms``). Studies measure those apart from accuracy, and
    comparisons of two runs' accuracy skip them."""
    return name in TIMING_COLUMNS or name.endswith("_ms")


WALL_CLOCK = "wall clock around ctx.finish() (perf_counter), median and IQR over repeats after warm-up"


@dataclass
class Timing:
    """Median and IQR (ms) of the timed runs, and the raw samples (ms); ``q25_ms``/``q75_ms``: the
    quartiles whose difference is the IQR (the repeat interval two configurations' times are
    compared by, docs/metrics.md#verdicts-and-significance; None where unknown)."""

    median_ms: float
    iqr_ms: float
    samples_ms: list[float]
    gpu_median_ms: float | None = None
    q25_ms: float | None = None
    q75_ms: float | None = None

    def columns(self) -> dict:
        """The metrics.csv columns of this timing."""
        out = {"time_ms_median": self.median_ms, "time_ms_iqr": self.iqr_ms, "time_repeats": len(self.samples_ms)}
        if self.q25_ms is not None and self.q75_ms is not None:
            out["time_ms_q25"], out["time_ms_q75"] = self.q25_ms, self.q75_ms
        if self.gpu_median_ms is not None:
            out["gpu_time_ms_median"] = self.gpu_median_ms
        return out


def method_description() -> str:
    """How this process times GPU work, for run.json."""
    return method_for(gl.renderer())


def method_for(renderer: str) -> str:
    """How GPU work is timed on the renderer named ``renderer`` (GL_RENDERER), for run records."""
    if gl.is_software_name(renderer):
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
        query = gl.query("time_passes", time=True) if use_query else None
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
    return Timing(float(med), float(q3 - q1), samples, float(np.median(gpu_samples)) if gpu_samples else None,
                  float(q1), float(q3))


def pass_timing_method() -> str:
    """How this process times the passes of a render (for run.json)."""
    return pass_timing_method_for(gl.renderer())


def pass_timing_method_for(renderer: str) -> str:
    """How the passes of a render are timed on the renderer named ``renderer``."""
    if gl.is_software_name(renderer):
        return "wall clock with ctx.finish() between passes (software rasteriser)"
    return "GL_TIME_ELAPSED query per pass"


class PassTimer:
    """Per-pass times of a technique's render, the way engine profilers show them: each named
    pass (:meth:`shadowlab.techniques.Technique.timed_pass`) is timed with a GL_TIME_ELAPSED
    query on real GPUs, or with the wall clock between ``ctx.finish()`` calls on software
    renderers (whose timer queries do not measure rasterisation) and for CPU passes. The
    finishes perturb the total, so the pipeline times passes in runs of their own, after the
    runs that give ``time_ms_median``.
    """

    def __init__(self):
        self.use_queries = not gl.is_software_renderer()
        self.ctx = gl.context()
        self.samples: dict[str, list[float]] = {}
        self._run: dict[str, float] = {}
        self._queries: list = []  # (pass name, query) of the current run, read at its end

    def measure(self, name: str, cpu: bool = False):
        """Context manager timing one occurrence of pass ``name`` (several add up in a run)."""
        import contextlib

        @contextlib.contextmanager
        def timed():
            if self.use_queries and not cpu:
                # one pooled query per occurrence of the pass within a run (planar: per receiver)
                query = gl.query(("pass", name, sum(n == name for n, _ in self._queries)), time=True)
                with query:
                    yield
                self._queries.append((name, query))
                return
            if not cpu:
                self.ctx.finish()
            t0 = time.perf_counter()
            yield
            if not cpu:
                self.ctx.finish()
            self._run[name] = self._run.get(name, 0.0) + (time.perf_counter() - t0) * 1e3

        return timed()

    def end_run(self) -> None:
        """Close one render run: its per-pass sums become one sample each."""
        self.ctx.finish()
        for name, query in self._queries:
            self._run[name] = self._run.get(name, 0.0) + query.elapsed / 1e6
        for name, ms in self._run.items():
            self.samples.setdefault(name, []).append(ms)
        self._run, self._queries = {}, []

    def columns(self) -> dict:
        """``pass_<name>_ms``: the median over runs of each pass's time per run."""
        return {f"pass_{name}_ms": float(np.median(v)) for name, v in self.samples.items()}
