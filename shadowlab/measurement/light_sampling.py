"""Soft shadows from hard techniques: the pieces of the light-sampling average.

Heckbert & Herf, "Simulating soft shadows with graphics hardware" (CMU-CS-97-104, 1997): the
visibility of an area light is approximated by rendering a hard shadow from each of N sample
points on the light and averaging them. The loop lives in the pipeline
(:func:`shadowlab.measurement.pipeline.measure`), not in each technique: a technique class opts in with
``LIGHT_SAMPLED = True`` (which gives it the parameter ``light_samples``,
:mod:`shadowlab.techniques.base`), and on an area light the pipeline

1. takes the light's fixed pattern of N points (:func:`sample_lights`,
   :meth:`shadowlab.scene.area_lights.AreaLight.pattern`: centres of N equal-area strata, N = 1
   the centre; a sphere's spread by area over its cap seen from the mean of the evaluated
   points, N = 1 the cap's apex), the same points for every pixel — so a small N shows N
   overlapping hard shadows (banding), not noise;
2. measures the technique once per point on a point light there (same colour and ambient), in
   a stand-in :class:`~shadowlab.gpu.frame.LightSlot` under the area light's index
   (:meth:`shadowlab.gpu.frame.Frame.stand_in`; the shared scene is never changed), each one set
   up, rendered and released before the next (one sample's resources at a time);
3. combines them (:class:`VisibilityAverage`) with the definition the sampled truth uses
   (docs/metrics.md, docs/soft-shadows.md): over the area light's evaluated pixels,

       V(P) = [P on the emitting side] · (1/N) Σ_i vis_i(P) · [point i above P's tangent plane]

   (camera-facing geometric normal; below the plane, P's own surface hides the point; a
   one-sided light's back side sees none of it), 1 on the other pixels.

The frame's cost is N renders: time, setup and pass times are the samples' sums
(:func:`combined_timing`), each cost figure combined as its technique declares in ``STATS``
(:func:`combined_stats`: work summed, sizes and peaks the maximum, descriptions the first
sample's), peak memory the maximum. Time grows linearly with N and the error of the average
falls towards the pattern's discretisation error.
"""
from __future__ import annotations

import numpy as np

from ..gpu import timing
from ..scene.area_lights import AreaLight, above_horizon
from ..scene.lights import Light, PointLight
from ..techniques.base import FIRST, MAX, SUM

def is_sampled(technique, light: Light) -> bool:
    """True when ``technique`` opted in to light sampling and ``light`` is an area light."""
    return technique.LIGHT_SAMPLED and isinstance(light, AreaLight)


def ignored_note(technique, slot) -> str | None:
    """The run's note when an opted-in technique asks for ``light_samples`` > 1 on a slot whose
    light is not an area light (rendered once, as a hard light), else None."""
    if not technique.LIGHT_SAMPLED:
        return None
    n = technique.light_samples
    if n > 1 and not isinstance(slot.light, AreaLight):
        return f"light_samples={n} ignored: light {slot.index} is a {slot.light.type_name} light"
    return None


def evaluated_centre(frame, slot) -> np.ndarray | None:
    """Mean (3,) of the exact points of the slot's evaluated pixels (None if there are none):
    where a sphere light's pattern looks from."""
    ev = slot.evaluated
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
    ``slot`` is the area light's slot (its evaluated mask)."""

    def __init__(self, frame, slot):
        light = slot.light
        self.frame, self.n = frame, 0
        self.evaluated = slot.evaluated  # (M,) bool, the area light's
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
    """One frame's timing of N renders: median, IQR and quartiles are the sums of the samples' (the
    IQRs added: a conservative spread), ``samples_ms`` run by run sums (run j of every sample), the
    GL-query median the sum when every sample has one."""
    if not timings:
        raise ValueError("no timing to combine")
    runs = min(len(t.samples_ms) for t in timings)
    gpu = [t.gpu_median_ms for t in timings]
    return timing.Timing(float(sum(t.median_ms for t in timings)), float(sum(t.iqr_ms for t in timings)),
                         [float(sum(t.samples_ms[j] for t in timings)) for j in range(runs)],
                         float(sum(gpu)) if all(g is not None for g in gpu) else None,
                         *_summed_quartiles(timings))


def _summed_quartiles(timings: list[timing.Timing]) -> tuple[float | None, float | None]:
    """The sums of the timings' quartiles, (None, None) when one is unknown."""
    if any(t.q25_ms is None or t.q75_ms is None for t in timings):
        return None, None
    return float(sum(t.q25_ms for t in timings)), float(sum(t.q75_ms for t in timings))


def combined_stats(stats: list[dict], rules: dict[str, str], owner: str = "technique") -> dict:
    """The samples' cost figures as one frame's, each key combined by its rule in ``rules``
    (a technique's ``STATS``): :data:`~shadowlab.techniques.base.SUM` (work: the frame makes
    every sample's passes), :data:`~shadowlab.techniques.base.MAX` (sizes and peaks: one sample
    is set up at a time) or :data:`~shadowlab.techniques.base.FIRST` (descriptions: the first
    sample's). A key without a rule is an error naming ``owner``. Keys keep the first sample's
    order; a key some samples lack combines over those that have it."""
    out: dict = {}
    for key in dict.fromkeys(k for s in stats for k in s):
        if key not in rules:
            raise KeyError(f"{owner}: stat {key!r} has no combination rule; declare it in STATS")
        values = [s[key] for s in stats if key in s]
        rule = rules[key]
        if rule == FIRST or any(v is None for v in values):
            out[key] = values[0]
        elif rule == MAX:
            out[key] = max(values)
        elif rule == SUM:
            out[key] = sum(values)
        else:
            raise ValueError(f"{owner}: unknown combination rule {rule!r} for stat {key!r}")
    return out
