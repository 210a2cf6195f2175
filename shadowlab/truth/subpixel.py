"""Sub-pixel samples of a frame: exact surface points behind several positions inside each
covered pixel, shared by the ray-traced truth (``raytrace:pixel_samples=N``) and rasterising
techniques that resolve shadows below the pixel.

For each covered pixel of a :class:`~shadowlab.gpu.frame.Frame` (its compact order) and each offset
of :func:`sample_pattern`, the camera ray through (col + ox, row + oy) is formed exactly as the
frame forms its pixel-centre rays (:func:`shadowlab.truth.pixel_rays._pixel_ray_terms`), so with one sample
the rays are bitwise the frame's. Embree (robust mode, every object) finds the triangle the ray
meets first; the float64 point is then that ray met with the triangle's plane by the frame's
own :func:`~shadowlab.truth.pixel_rays.plane_hits`, and the shadow-ray origin is the truth's offset rule
(:func:`shadowlab.truth.tracing.offset_points`). Which samples are evaluated for a light is the
frame's rule (:func:`shadowlab.truth.pixel_rays.evaluated_rule`), applied per sample.

A sample may see another triangle than the G-buffer saw at its pixel's centre — that is the
point of sub-pixel samples — and, at n = 1, Embree's float32 ray may pick a different triangle
than the rasteriser at a shared edge (a handful of pixels; tests/truth/test_subpixel.py counts them).
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass, field

import numpy as np

from .pixel_rays import _pixel_ray_terms, evaluated_rule, plane_hits, plane_numerators
from .tracing import DEFAULT_OFFSET_SCALE, nearest_hits, object_scene, occluded, offset_points

#: The most sub-pixel samples per pixel (the rasterising techniques' sample-mask width).
MAX_SAMPLES = 32

#: Per frame: {n: SubpixelSamples}.
_SAMPLES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def radical_inverse_base2(i: np.ndarray, bits: int) -> np.ndarray:
    """Van der Corput's radical inverse in base 2 of the integers ``i`` (each < 2**bits): their
    binary digits mirrored about the point, as float64 multiples of 2**-bits."""
    i = np.asarray(i, np.int64)
    out = np.zeros(i.shape, np.int64)
    for b in range(bits):
        out |= ((i >> b) & 1) << (bits - 1 - b)
    return out / float(2 ** bits)


def sample_pattern(n: int) -> np.ndarray:
    """``n`` sub-pixel offsets, float64 (n, 2) in [0, 1)² (x right, y down from the pixel's
    top-left corner): the Hammersley point set, centred in its strata.

        x_i = (i + ½) / n,    y_i = Φ₂(i) + ½ · 2^−m,    m = ⌈log₂ n⌉,  i = 0 … n−1

    with Φ₂ the base-2 radical inverse (Hammersley 1960; Pharr, Jakob & Humphreys, PBRT 3rd ed.,
    §7.4.1). Why this pattern: deterministic (the truth and a rasteriser see the same positions),
    one point in each of n equal columns, the y coordinates in distinct rows of 2^m, and for n a
    power of two a (0, m, 2)-net in base 2 — every dyadic box of area 1/n holds exactly one
    point (Niederreiter 1992, §4.1), which the half-stratum shift keeps (a point at k·2^−m moves
    by less than one 2^−m stratum). n = 1 gives the pixel centre (½, ½)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= MAX_SAMPLES:
        raise ValueError(f"sample_pattern: n must be an integer from 1 to {MAX_SAMPLES}, got {n!r}")
    n = int(n)
    bits = (n - 1).bit_length()  # m = ⌈log₂ n⌉
    i = np.arange(n)
    x = (i + 0.5) / n
    y = radical_inverse_base2(i, bits) + 0.5 / float(2 ** bits)
    return np.stack([x, y], axis=1)


@dataclass(eq=False)
class SubpixelSamples:
    """The exact surface points behind ``n`` sub-pixel positions of each of a frame's M covered
    pixels (compact order): ``points`` float64 (M, n, 3) and ``normals`` (M, n, 3) (unit,
    turned towards the camera; NaN points and zero normals where ``hit`` is False), ``hit`` bool
    (M, n) (the camera ray met a triangle with a valid point), ``object`` int32 (M, n) (its
    object, −1 on a miss), ``origins`` float32 (M, n, 3) the truth's offset shadow-ray origins
    (:func:`shadowlab.truth.tracing.offset_points`, by default with :data:`DEFAULT_OFFSET_SCALE`), and
    ``receives`` bool (M, n) (the sample's object receives shadows; False on a miss) and
    ``triangle`` int64 (M, n) (the frame's triangle index, as ``frame.triangle_id``; −1 on a
    miss)."""

    n: int
    points: np.ndarray = field(repr=False)
    normals: np.ndarray = field(repr=False)
    hit: np.ndarray = field(repr=False)
    object: np.ndarray = field(repr=False)
    origins: np.ndarray = field(repr=False)
    receives: np.ndarray = field(repr=False)
    triangle: np.ndarray = field(repr=False)

    def evaluated(self, light) -> np.ndarray:
        """Bool (M, n): the samples evaluated for ``light`` — the frame's rule
        (:func:`shadowlab.truth.pixel_rays.evaluated_rule`: receiving, valid, N·L > 0, λ > 0, distance > 0)
        applied to each sample that hit (a miss is never evaluated)."""
        out = np.zeros(self.hit.shape, bool)
        flat = np.flatnonzero(self.hit)
        pts, nrm = self.points.reshape(-1, 3)[flat], self.normals.reshape(-1, 3)[flat]
        ones = np.ones(len(flat), bool)
        out.reshape(-1)[flat] = evaluated_rule(light, pts, nrm, ones, self.receives.reshape(-1)[flat])
        return out

    def rays(self, light, evaluated: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The shadow rays of the evaluated samples, as the truth traces them
        (:meth:`Light.shadow_rays` from the offset origins): origins (K, 3) float32, directions
        (K, 3) float32, tfar (K,) float32 and ``index`` (K,) int64 into the flattened (M·n)
        samples. ``evaluated`` (M, n) if already computed, else :meth:`evaluated`."""
        ev = self.evaluated(light) if evaluated is None else evaluated
        index = np.flatnonzero(ev)
        org = np.ascontiguousarray(self.origins.reshape(-1, 3)[index])
        dirs, tfar = light.shadow_rays(org, self.points.reshape(-1, 3)[index])
        return org, dirs, tfar, index

    def coverage(self, lit: np.ndarray, evaluated: np.ndarray) -> np.ndarray:
        """Float64 (M,): the fraction of each pixel's evaluated samples that are ``lit`` (both
        bool (M, n)); 1.0 where none of its samples is evaluated (nothing to shadow, as the
        frame's unevaluated pixels are 1)."""
        if lit.shape != self.hit.shape or evaluated.shape != self.hit.shape:
            raise ValueError(f"coverage: lit {lit.shape} and evaluated {evaluated.shape} must both be "
                             f"{self.hit.shape} (pixels, samples)")
        counted = evaluated.sum(axis=1)
        lit_counted = (lit & evaluated).sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(counted > 0, lit_counted / np.maximum(counted, 1), 1.0)


def sample_directions(frame, offset: tuple[float, float]) -> np.ndarray:
    """Unnormalised float64 camera-ray directions (M, 3) through (col + ox, row + oy) of each of
    ``frame``'s covered pixels (compact order), summed from the frame's own tables
    (:func:`shadowlab.truth.pixel_rays._pixel_ray_terms`) as the frame sums them: at the centre (½, ½),
    bitwise the frame's pixel-centre rays."""
    row, col = np.divmod(frame.pixel_index, frame.width)
    col_term, row_term = _pixel_ray_terms(frame.camera, frame.width, frame.height, (float(offset[0]), float(offset[1])))
    dirs = np.take(col_term, col, axis=0)  # (−back + x·right) + y·up, as the frame adds them
    dirs += np.take(row_term, row, axis=0)
    return dirs


def subpixel_samples(frame, n: int, offset_scale: float = DEFAULT_OFFSET_SCALE) -> SubpixelSamples:
    """The :class:`SubpixelSamples` of ``frame`` at ``n`` samples per pixel
    (:func:`sample_pattern`), their ray origins offset by ``offset_scale`` (the truth's rule),
    built once per (frame, n, offset_scale) and kept, weakly keyed by the frame."""
    pattern = sample_pattern(n)  # checks n
    per_frame = _SAMPLES.setdefault(frame, {})
    key = (n, float(offset_scale))
    if key not in per_frame:
        per_frame[key] = _build(frame, pattern, offset_scale)
    return per_frame[key]


def _build(frame, pattern: np.ndarray, offset_scale: float = DEFAULT_OFFSET_SCALE) -> SubpixelSamples:
    """Trace and intersect the camera rays of every (covered pixel, offset of ``pattern``)."""
    m, n = len(frame.pixel_index), len(pattern)
    eye = np.asarray(frame.camera.eye, np.float64)
    numerator = plane_numerators(frame.triangles, frame.triangle_normals, eye)
    # Embree geometry k = object k, primitive f = its face f; the frame's triangle index is the
    # object's first triangle (frame._upload concatenates objects in scene order) plus f.
    first_triangle = np.array([r.first // 3 for r in frame.object_ranges], np.int64)
    receives_by_object = np.array([o.receives for o in frame.scene.objects], bool)
    scene = object_scene(frame)
    eye32 = eye.astype(np.float32)
    extent = frame.scene.extent()

    points = np.full((m, n, 3), np.nan)
    normals = np.zeros((m, n, 3))
    hit = np.zeros((m, n), bool)
    obj = np.full((m, n), -1, np.int32)
    triangle = np.full((m, n), -1, np.int64)
    origins = np.full((m, n, 3), np.nan, np.float32)
    for s, offset in enumerate(pattern):
        dirs = sample_directions(frame, offset)
        # fresh origin and tfar arrays per call: Embree writes the hit distances into tfar
        found = nearest_hits(scene, np.tile(eye32, (m, 1)), dirs.astype(np.float32), np.full(m, np.inf, np.float32))
        geom = np.asarray(found["geomID"], np.int64)
        seen = np.flatnonzero(geom >= 0)
        tri = first_triangle[geom[seen]] + np.asarray(found["primID"], np.int64)[seen]
        p, nrm, valid = plane_hits(eye, np.ascontiguousarray(dirs[seen]), tri, frame.triangle_normals, numerator)
        good = seen[valid]
        p, nrm, tri = p[valid], nrm[valid], tri[valid]
        points[good, s] = p
        normals[good, s] = nrm
        hit[good, s] = True
        obj[good, s] = frame.triangle_object[tri]
        triangle[good, s] = tri
        origins[good, s] = offset_points(p, nrm, extent, offset_scale)
    receives = np.zeros((m, n), bool)
    receives[hit] = receives_by_object[obj[hit]]
    return SubpixelSamples(n, points, normals, hit, obj, origins, receives, triangle)


def sample_visibility(samples: SubpixelSamples, light, scene) -> tuple[np.ndarray, np.ndarray, int]:
    """Hard-light visibility of every sub-pixel sample, by one Embree shadow ray per evaluated
    sample (:meth:`SubpixelSamples.rays`; ``scene`` the frame's caster scene, None when nothing
    casts): (lit bool (M, n) — True also where a sample is not evaluated, as the truth's
    unevaluated pixels are 1 —, evaluated bool (M, n), rays traced)."""
    evaluated = samples.evaluated(light)
    lit = np.ones(evaluated.shape, bool)
    if scene is None:
        return lit, evaluated, 0
    org, dirs, tfar, index = samples.rays(light, evaluated)
    lit.reshape(-1)[index] = ~occluded(scene, org, dirs, tfar)
    return lit, evaluated, len(index)
