"""The ray-traced ground truth (docs/architecture.md#evaluation-evaluator-in-shadowlabmeasurementpipelinepy): one shadow ray per evaluated pixel through Embree
for hard lights, N stratified light samples per evaluated pixel for area lights.

The ray starts at the exact float64 point where the pixel-centre camera ray meets the triangle
the G-buffer saw (computed once per frame by :class:`shadowlab.gpu.frame.Frame`). Embree works in
float32, so the point is moved off its own surface before rounding:

    origin = float32(P + ε · N),   ε = offset_scale · max(‖P‖∞, scene extent)

with N the unit geometric normal turned to the camera (for an evaluated pixel N·L > 0, so
this is also the light's side). The offset scales with the magnitude of the coordinates, as
in Wächter & Binder, "A Fast and Robust Method for Avoiding Self-Intersection" (Ray Tracing
Gems, ch. 6): a fixed offset is too small far from the origin (acne, hard case RT1) and too
large near it (skips thin occluders, RT3). With the default 2^-18 (≈ 32 float32 ulps) the
offset exceeds the float32 rounding of P (½ ulp) and Embree's own error, which is relative to
the scene's extent, by an order of magnitude, yet stays below 1e-5 of the scene's size.
Embree runs in robust (watertight) mode, so shadow rays through shared edges and vertices do
not leak (Woop, Benthin & Wald 2013; hard case RT2). Each light type says which rays reach it
(:meth:`shadowlab.scene.lights.Light.shadow_rays`).

The Embree scene and the offset origins depend only on the frame (and the offset scale): they
are built once per frame by :mod:`shadowlab.truth.tracing`, which blob shadows and the occluder-layer
metric share.

Sub-pixel samples (``pixel_samples`` = N > 1, hard lights only): the truth of a pixel's
coverage rather than of its centre. Each covered pixel's N camera samples
(:mod:`shadowlab.truth.subpixel`: a stratified Hammersley pattern, exact float64 points, the same
offset rule) that the frame's evaluated rule keeps get one shadow ray each, and an evaluated
pixel's V is the fraction of its evaluated samples that reach the light (1 where none is
evaluated); pixels the frame does not evaluate stay 1. It is what an exact rasteriser with N
samples per pixel should produce, and resolves casters thinner than a pixel. N = 1 is the
pixel-centre path below, unchanged.

Area lights (:class:`shadowlab.scene.area_lights.AreaLight`; docs/metrics.md, docs/soft-shadows.md). The visibility of the
light from P is the fraction, by area, of the emitting surface facing P that P sees
unoccluded; samples below P's tangent plane (camera-facing geometric normal) count as occluded
(P's own surface hides them), and a point behind a one-sided light (rect, disc) sees none of
it (V = 0). The truth estimates it by Monte Carlo over the light's area:

    V̂(P) = (1/N) Σ_k  facing_k · [(y_k − P)·N_P > 0] · unoccluded(origin → y_k)

with N = ``samples`` points y_k from :meth:`AreaLight.sample_for`: the unit square cut into N
equal-area strata, one uniformly jittered point per stratum, mapped onto the surface by an
area-preserving map (rect: affine; disc: Shirley & Chiu's concentric map; sphere: the cap P
sees, uniform in cos θ and φ) — so each y_k is uniform over an equal-area piece of the surface
and V̂ is unbiased. Each shadow ray is the float32 segment origin → y_k (unnormalised
direction y_k − origin, stopped at :data:`shadowlab.scene.lights.T_LIGHT` of the way, as for a point
light), from the same offset origin as the hard truth.

Error bound (``truth_stderr_max`` = 0.5/√N): the variance of a stratified estimator never
exceeds that of N independent uniform samples (equal-area strata, one sample each: stratified
sampling with proportional allocation; Pharr, Jakob & Humphreys, PBRT 3rd ed., §7.3; Owen,
"Monte Carlo theory, methods and examples", on stratification), whose Bernoulli variance is
V(1 − V)/N ≤ 1/(4N); so the per-pixel standard error is at most 0.5/√N (1/64 at N = 1024),
and far smaller wherever V is 0 or 1 or the penumbra is crossed by few strata.

Decorrelation (``decorrelate``): by default every pixel draws its own jitter (a fresh stream
per chunk of pixels, seeded by (``seed``, chunk index)), so the estimator's error is noise, not
a pattern shared by neighbouring pixels. ``decorrelate=false`` uses one jittered pattern (the
same stratum coordinates) for every pixel — docs/architecture.md#evaluation-evaluator-in-shadowlabmeasurementpipelinepy: only if the run says so — whose error
is correlated across the image (visible banding), useful to compare with the light-sampling
average of the hard techniques. Same seed, same samples → the same bits.

Pixels are processed (:mod:`shadowlab.truth.area`, where this estimator's code lives) in chunks of at most :data:`CHUNK_RAYS` samples, at most
:data:`MAX_RAYS_HELD` held at once across the worker threads (Embree, numpy's generator and the
compiled passes release the GIL); only samples that face P and lie above its horizon are traced.

Speed (issue 27): around the Embree calls, the per-sample work — a rect light's samples, the
horizon test, the segments, the per-pixel count of Embree's answers — runs in compiled passes
(:mod:`shadowlab.truth.compiled`) into ray buffers each worker thread reuses
(:class:`ChunkBuffers`), instead of numpy's chain of (M, N, 3) temporaries. The random stream
is unchanged (numpy's ``Generator.random`` draws the jitter as before) and so are the bits:
:func:`area_chunk_rays_reference` keeps the numpy formulation, and tests/truth/test_compiled_truth.py
holds the compiled path to it bit for bit.
"""
from __future__ import annotations

import numpy as np

from ...scene.area_lights import AreaLight
# The area path's estimator lives in the truth layer (shared with maps/hybrid_rt); its names are
# re-exported here, where rt_soft, the experiments and the tests have always found them.
from ...truth.area import (  # noqa: F401
    CHUNK_RAYS, MAX_RAYS_HELD, ChunkBuffers, SharedJitter, area_chunk_counts, area_chunk_rays,
    area_chunk_rays_reference, area_chunks, area_visibility, area_workers,
)
from ...truth.subpixel import MAX_SAMPLES, sample_visibility, subpixel_samples
from ...truth.tracing import DEFAULT_OFFSET_SCALE, caster_scene, occluded, offset_origins
from ..base import FIRST, SUM, Param, PlotStyle, Technique, TechniqueError

class RayTraced(Technique):
    """Exact hard shadows: one shadow ray per evaluated pixel from the float64 hit point (or per
    evaluated sub-pixel sample, ``pixel_samples`` > 1); for an area light, the stratified estimate of its visible fraction from ``samples`` rays per
    pixel (module docstring)."""

    name = "raytrace"
    summary = "ray-traced ground truth (Embree, robust mode, magnitude-scaled offset; area lights: stratified samples)"
    cpu = True
    PASSES = ("trace",)
    PARAMS = {
        "offset_scale": Param(DEFAULT_OFFSET_SCALE, "shadow-ray origin offset along the normal, relative to "
                                          "max(|P|inf, scene extent)", min=0.0, max=1e-2),
        "samples": Param(1024, "area lights: stratified light samples (shadow rays) per pixel; "
                               "standard error <= 0.5/sqrt(samples)", min=1, max=65536),
        "seed": Param(0, "area lights: seed of the sample jitter (same seed, same bits)", min=0),
        "decorrelate": Param(True, "area lights: independent jitter per pixel (false: one jittered "
                                   "pattern shared by every pixel)"),
        "pixel_samples": Param(1, "hard lights: camera samples per pixel (shadowlab.truth.subpixel pattern); "
                                  "V = fraction of a pixel's evaluated samples lit; 1 = the pixel centre only",
                               min=1, max=MAX_SAMPLES),
    }
    #: Rays are work per render; the samples per pixel and the error bound describe the truth.
    STATS = {"rays": SUM, "samples": FIRST, "truth_stderr_max": FIRST}
    #: The reference: black stars where a plot shows it at all.
    STYLE = PlotStyle("#000000", "*")

    def setup(self, frame, slot) -> None:
        """Offset origins (per frame) and the evaluated pixels of this light; with
        ``pixel_samples`` > 1 (hard lights only) the frame's sub-pixel samples."""
        from ...truth import compiled as compiled_truth

        compiled_truth.warm()  # compile or load the kernels here, not in the timed pass
        self.is_area = isinstance(self.light, AreaLight)
        if self.is_area and self.pixel_samples > 1:
            raise TechniqueError(f"{self.name}: pixel_samples={self.pixel_samples} is for hard lights only; "
                                 f"light {slot.index} is a {self.light.type_name} area light (use samples=..., "
                                 f"pixel_samples=1)")
        self.subpixel = (subpixel_samples(frame, self.pixel_samples, self.offset_scale) if self.pixel_samples > 1
                         else None)
        self.sample_lit = None
        self.scene = caster_scene(frame) if frame.has_casters else None
        self.origins = offset_origins(frame, self.offset_scale)
        self.evaluated = slot.evaluated
        self.eval_origins = np.ascontiguousarray(self.origins[self.evaluated])
        self.eval_points = frame.compact_position[self.evaluated]
        self.eval_normals = frame.compact_normal[self.evaluated]
        self.blocked = np.zeros(len(self.eval_origins), bool)
        self.fraction = np.ones(len(self.eval_origins))
        self.rays = 0 if self.is_area else len(self.eval_origins)

    def render(self) -> None:
        """Trace one shadow ray per evaluated pixel (hard lights; per evaluated sub-pixel sample
        with ``pixel_samples`` > 1) or ``samples`` per pixel (area lights)."""
        with self.timed_pass("trace", cpu=True):
            if self.is_area:
                self.fraction, self.rays = area_visibility(
                    self.scene, self.light, self.eval_points, self.eval_normals, self.eval_origins,
                    self.samples, self.seed, self.decorrelate)
                return
            if self.subpixel is not None:
                self.sample_lit, self.sample_evaluated, self.rays = sample_visibility(
                    self.subpixel, self.light, self.scene)
                return
            if self.scene is None:  # nothing casts: every ray reaches the light
                return
            dirs, tfar = self.light.shadow_rays(self.eval_origins, self.eval_points)
            self.blocked = occluded(self.scene, self.eval_origins, dirs, tfar)

    def visibility(self) -> np.ndarray:
        """Float32 (H, W), row 0 = top: hard lights 1 where the shadow ray reached the light,
        else 0; area lights the sampled visible fraction (multiples of 1/samples); 1 on pixels
        that are not evaluated."""
        vis = np.ones(len(self.evaluated), np.float32)
        idx = np.flatnonzero(self.evaluated)
        if self.is_area:
            vis[idx] = self.fraction
        elif self.subpixel is not None:  # the frame's evaluated pixels: their samples' coverage
            vis[idx] = self.subpixel.coverage(self.sample_lit, self.sample_evaluated)[idx]
        else:
            vis[idx[self.blocked]] = 0.0
        return self.frame.to_image(vis, fill=1.0)

    def sample_visibility(self) -> np.ndarray:
        """Bool (M, pixel_samples) after :meth:`render`: each sub-pixel sample lit (True also for
        samples not evaluated); with ``pixel_samples=1`` the pixel-centre result as (M, 1)."""
        if self.is_area:
            raise TechniqueError(f"{self.name}: sample_visibility is for hard lights only")
        if self.subpixel is not None:
            if self.sample_lit is None:
                raise RuntimeError(f"{self.name}: sample_visibility() before render()")
            return self.sample_lit
        lit = np.ones(len(self.evaluated), bool)
        lit[np.flatnonzero(self.evaluated)[self.blocked]] = False
        return lit[:, None]

    def work(self, counted: dict, stats: dict) -> dict:
        """Shadow rays traced by Embree per render."""
        return {"trace": {"rays": stats["rays"]}}

    def stats(self) -> dict:
        """Shadow rays traced per render, samples per pixel (1 for hard lights) and the bound
        on the per-pixel standard error of the truth (0.5/√samples for area lights, 0 for hard
        lights: docs/architecture.md#evaluation-evaluator-in-shadowlabmeasurementpipelinepy)."""
        if self.subpixel is not None:  # exact per sample: the coverage of the pattern, no estimate
            return {"rays": int(self.rays), "samples": int(self.pixel_samples), "truth_stderr_max": 0.0}
        if not self.is_area:
            return {"rays": int(len(self.eval_origins)), "samples": 1, "truth_stderr_max": 0.0}
        return {"rays": int(self.rays), "samples": int(self.samples),
                "truth_stderr_max": 0.5 / float(np.sqrt(self.samples))}
