"""Soft shadows from hard techniques: the average of N hard renders from points of an area light.

Heckbert & Herf, "Simulating soft shadows with graphics hardware" (CMU-CS-97-104, 1997): the
visibility of an area light is approximated by rendering a hard shadow from each of N sample
points on the light and averaging them. Here it lives in the shared machinery, not in each
technique: a technique class opts in with ``LIGHT_SAMPLED = True`` (which gives it the
parameter ``light_samples``, :mod:`shadowlab.techniques.base`), and :func:`shadowlab.pipeline.measure`
hands an opted-in technique on an area light to :func:`measure_sampled`, which

1. takes the light's fixed pattern of N points (:meth:`shadowlab.scene.area_lights.AreaLight.pattern`:
   centres of N equal-area strata, N = 1 the centre; a sphere's spread by area over its cap
   seen from the mean of the evaluated points, N = 1 the cap's apex), the same points for every pixel — so a small N shows N overlapping hard
   shadows (banding), not noise;
2. measures the technique once per point on a point light there (same colour and ambient),
   standing in for the area light under its index (:meth:`shadowlab.frame.Frame.lit_by`), each
   one set up, rendered and released before the next (one sample's resources at a time);
3. combines them with the definition the sampled truth uses (DESIGN §7, §9): over the area
   light's evaluated pixels,

       V(P) = [P on the emitting side] · (1/N) Σ_i vis_i(P) · [point i above P's tangent plane]

   (camera-facing geometric normal; below the plane, P's own surface hides the point; a
   one-sided light's back side sees none of it), 1 on the other pixels.

The frame's cost is N renders: time, setup and pass times are the samples' sums, peak memory
their maximum (:func:`combined_timing`, :func:`combined_stats`). Time grows linearly with N and
the error of the average falls towards the pattern's discretisation error.
"""
from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from . import timing
from .scene.area_lights import AreaLight, above_horizon
from .scene.lights import Light, PointLight

#: Stats that are a peak or a size held while one sample is set up: combined by maximum.
_MAX_STATS = frozenset({"stencil_peak_count"})
#: Stats that describe the configuration or one view rather than work per render: the first
#: sample's value is kept.
_FIRST_STATS = frozenset({"depth_range", "texel_world", "planar_receivers", "dropped_faces"})


def is_sampled(technique, light: Light) -> bool:
    """True when ``technique`` opted in to light sampling and ``light`` is an area light."""
    return bool(getattr(technique, "LIGHT_SAMPLED", False)) and isinstance(light, AreaLight)


def ignored_note(technique, light_index: int, light: Light) -> str | None:
    """The run's note when an opted-in technique asks for ``light_samples`` > 1 on a light that
    is not an area light (rendered once, as a hard light), else None."""
    n = technique.params().get("light_samples", 1)
    if getattr(technique, "LIGHT_SAMPLED", False) and n > 1 and not isinstance(light, AreaLight):
        return f"light_samples={n} ignored: light {light_index} is a {light.type_name} light"
    return None


def evaluated_centre(frame, light_index: int) -> np.ndarray | None:
    """Mean (3,) of the exact points of the light's evaluated pixels (None if there are none):
    where a sphere light's pattern looks from."""
    ev = frame.compact_evaluated(light_index)
    return frame.compact_position[ev].mean(axis=0) if ev.any() else None


def sample_lights(light: AreaLight, n: int, towards: np.ndarray | None = None) -> list[PointLight]:
    """Point lights (same colour and ambient) at the ``n`` points of ``light``'s pattern."""
    if not isinstance(light, AreaLight):
        raise TypeError(f"light sampling needs an area light, got a {light.type_name} light")
    return [PointLight(color=np.array(light.color, np.float64), ambient=float(light.ambient),
                       position=np.array(p, np.float64)) for p in light.pattern(n, towards=towards)]


class VisibilityAverage:
    """Accumulates the per-sample hard visibilities into the area light's visibility (the
    formula in the module docstring), one (height, width) image at a time, in O(pixels) memory.

    ``frame``'s evaluated mask for ``light_index`` must be the area light's when this is made."""

    def __init__(self, frame, light_index: int, light: AreaLight):
        self.frame, self.n = frame, 0
        self.evaluated = frame.compact_evaluated(light_index).copy()  # (M,) bool, the area light's
        self.points = frame.compact_position[self.evaluated]  # (E, 3) float64
        self.normals = frame.compact_normal[self.evaluated]  # (E, 3) float64, towards the camera
        self.emits = light.emits_towards(self.points)  # (E,) bool
        self.sum = np.zeros(len(self.points), np.float64)

    def add(self, sample_point: np.ndarray, visibility: np.ndarray) -> None:
        """Add one hard visibility image, float32 (height, width), row 0 = top, rendered from the
        point light at ``sample_point`` (3,)."""
        f = self.frame
        if visibility.shape != (f.height, f.width):
            raise ValueError(f"visibility of shape {visibility.shape} for a {f.width}x{f.height} frame")
        compact = visibility.reshape(-1)[f.pixel_index][self.evaluated].astype(np.float64)
        sample = np.broadcast_to(np.asarray(sample_point, np.float64), (len(self.points), 1, 3))
        compact *= above_horizon(sample, self.points, self.normals)[:, 0]
        self.sum += compact
        self.n += 1

    def result(self) -> np.ndarray:
        """V float32 (height, width), row 0 = top: the average on evaluated pixels, 1 elsewhere."""
        if self.n == 0:
            raise ValueError("no light sample was added")
        out = np.ones(len(self.evaluated), np.float32)
        out[self.evaluated] = np.where(self.emits, self.sum / self.n, 0.0)
        return self.frame.to_image(out, fill=1.0)


def combined_timing(timings: list[timing.Timing]) -> timing.Timing:
    """One frame's timing of N renders: median and IQR are the sums of the samples' (the IQRs
    added: a conservative spread), ``samples_ms`` run by run sums (run j of every sample), the
    GL-query median the sum when every sample has one."""
    if not timings:
        raise ValueError("no timing to combine")
    runs = min(len(t.samples_ms) for t in timings)
    gpu = [t.gpu_median_ms for t in timings]
    return timing.Timing(float(sum(t.median_ms for t in timings)), float(sum(t.iqr_ms for t in timings)),
                         [float(sum(t.samples_ms[j] for t in timings)) for j in range(runs)],
                         float(sum(gpu)) if all(g is not None for g in gpu) else None)


def combined_stats(stats: list[dict]) -> dict:
    """The samples' cost figures as one frame's: work counts and times (numbers) summed — the
    frame makes every sample's passes —, peaks and sizes (``*_bytes``, ``stencil_peak_count``)
    the maximum, since one sample is set up at a time, and descriptive values (non-numbers,
    ``depth_range``, ``texel_world``, ``planar_receivers``, ``dropped_faces``) the first
    sample's. Keys keep the first sample's order."""
    out: dict = {}
    for key in dict.fromkeys(k for s in stats for k in s):
        values = [s[key] for s in stats if key in s]
        numeric = all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))
                      for v in values)
        if not numeric or key in _FIRST_STATS:
            out[key] = values[0]
        elif key in _MAX_STATS or key.endswith("_bytes"):
            out[key] = max(values)
        else:
            out[key] = sum(values)
    return out


def _every_nth(on_step: Callable[[], None] | None, n: int) -> Callable[[], None] | None:
    """``on_step`` called once every ``n`` calls: the N samples' renders count as one frame's."""
    if on_step is None or n == 1:
        return on_step
    count = [0]

    def step():
        count[0] += 1
        if count[0] % n == 0:
            on_step()

    return step


def measure_sampled(tech, frame, light_index: int, measure_one: Callable, repeat: int = 5, warmup: int = 1,
                    on_step: Callable[[], None] | None = None, release: bool = True, pass_timing: bool = False):
    """Measure the opted-in technique ``tech`` on area light ``light_index`` of ``frame`` as the
    average of ``tech.light_samples`` hard measurements (``measure_one``: the pipeline's hard
    measurement, same arguments), one per pattern point; returns one Measurement (same class)
    with the combined visibility, timing, stats (plus ``light_samples``: the renders made),
    pass times (summed), setup time (summed), peak memory (maximum) and deduplicated notes.

    ``release=False`` keeps the last sample's technique set up (its visibility() is that
    sample's hard image, not the average)."""
    light = frame.scene.lights[light_index]
    if not is_sampled(tech, light):
        raise TypeError(f"{tech.name} on light {light_index}: not a light-sampled technique on an area light")
    n = int(tech.light_samples)
    before = len(tech.notes)
    average = VisibilityAverage(frame, light_index, light)
    samples = sample_lights(light, n, evaluated_centre(frame, light_index))
    step = _every_nth(on_step, n)
    ms = []
    for i, point_light in enumerate(samples):
        try:
            with frame.lit_by(light_index, point_light):
                m = measure_one(tech, frame, light_index, repeat, warmup, step,
                                release=release or i < n - 1, pass_timing=pass_timing)
        except Exception as exc:
            exc.add_note(f"{tech.name}: light sample {i + 1} of {n} at {point_light.position.tolist()} "
                         f"of light {light_index}")
            raise
        average.add(point_light.position, m.visibility)
        ms.append(dataclasses.replace(m, visibility=None))  # one image at a time
    notes = list(dict.fromkeys(tech.notes[before:]))
    tech.notes[before:] = notes
    pass_times: dict = {}
    for m in ms:
        for k, v in m.pass_times.items():
            pass_times[k] = pass_times.get(k, 0.0) + v
    stats = {**combined_stats([m.stats for m in ms]), "light_samples": n}
    return dataclasses.replace(ms[0], visibility=average.result(), timing=combined_timing([m.timing for m in ms]),
                               stats=stats, notes=notes, pass_times=pass_times,
                               setup_ms=float(sum(m.setup_ms for m in ms)),
                               peak_rss_bytes=max(m.peak_rss_bytes for m in ms))
