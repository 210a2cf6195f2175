"""Real-time ray-traced soft shadows (hard case SS3): a few light samples per pixel, the ratio
estimator, an edge-stopping à-trous denoiser and temporal accumulation — the pipeline of
Heitz, Hill & McGuire, "Combining analytic direct illumination and stochastic shadows"
(I3D 2018; ACM TOG), with the spatial filter of Dammertz, Sewtz, Hanika & Lensch,
"Edge-avoiding À-Trous wavelet transform for fast global illumination filtering" (HPG 2010)
and the reverse-reprojected history of Nehab et al. 2007 (as in SVGF, Schied et al. 2017 §4.1).

**Samples.** Each evaluated pixel traces ``samples`` (N = 1..16) shadow rays to the area light,
exactly as the sampled truth does (:mod:`shadowlab.techniques.rays.raytrace`): the truth's offset
origins (:func:`shadowlab.truth.tracing.offset_origins`), N stratified points uniform by area over
the light (:meth:`AreaLight.sample_for`), samples that do not face the point or lie below its
tangent plane not traced. Per pixel this gives two counts: ``live`` = #samples facing the
point and above its horizon, and ``free`` = #live samples whose segment is unoccluded. The
random stream is seeded (``seed``) and decorrelated per frame in an animation (the frame's
index from :class:`shadowlab.geometry.reprojection.FrameStep`); it never shares the truth's stream.

**What the ratio estimator is here.** Heitz et al. write direct light as
L = L_unshadowed · (∫ f V / ∫ f), with f the *unshadowed integrand* (BRDF · cos · emitted
radiance · geometry): the first factor analytic (LTC), the second, the shadow term, estimated
as a ratio of two Monte Carlo sums over the *same* samples, Σ f_k V_k / Σ f_k, so the noise is
only in the shadow term and both sums are denoised before dividing (their §3–4). In this lab the
shading (``shadowlab/gpu/shade.glsl``, docs/architecture.md#the-shading-pass-shadowlabgpushadingpy) lights an area light as a point light at its centre
and multiplies its diffuse and specular terms by a *visibility* V that is defined unweighted
(docs/metrics.md; :mod:`shadowlab.scene.area_lights`): the fraction, **by area**, of the light facing
P that P sees unoccluded, samples below P's tangent plane counting as hidden. So the integrand
of V's unshadowed part is not BRDF · cos / r², it is the clamped indicator

    f(y) = [y on the emitting side facing P] · [(y − P)·N_P > 0]      (uniform area measure),

whose integral, divided by the area, is the analytic unshadowed fraction U(P) (a rect clipped
by P's tangent plane: :func:`rect_unshadowed`). The ratio estimator of V is then

    V̂_ratio = U(P) · Σ_k f_k u_k / Σ_k f_k = U · free / live       (u_k: segment unoccluded),

against the plain average V̂_plain = (1/N) Σ_k f_k u_k = free / N (the truth's estimator at N
samples). **Where the whole light faces P and is above its horizon (U = 1, f ≡ 1: the floors
and tops under the shipped soft scenes' lights, most of their evaluated pixels) the two
are the same number** — bit for bit without the denoiser (live = N); with it, the filter of
the numerator over the filter of a denominator that is 1 all around is the filter of free / N,
up to rounding (and to the few taps from cut pixels nearby). They differ only where P's
tangent plane or the light's plane cuts the light — the sides of boxes facing the light,
soft_below_plane's slab (part of the light below its plane): there the
ratio takes the clipped part exactly from U and spends all its samples' information on the
shadow of the visible part — lower variance, a small bias of the ratio of estimates
(consistent: it vanishes as N grows) — and where no live sample is left (live = 0, U > 0) it
says "unshadowed" (ratio 1, V = U), the only value with no sample to contradict it.
``ratio=false`` is the plain average (and its filtered form filters free / N directly).
Were the lab's V weighted by the BRDF and cos θ / r² (a shaded area light), f would carry
those weights and the ratio would differ everywhere; with the lab's definition it cannot.

**Denoiser** (``iterations`` passes, 0 = off): the edge-avoiding à-trous transform (Dammertz
et al. 2010, §3): pass i convolves with the 5 × 5 B3-spline kernel h = (1, 4, 6, 4, 1)/16 ⊗
itself, its taps 2^i pixels apart ("holes"), each tap weighted also by edge-stopping functions
of the G-buffer — here the frame's *exact* float64 points and camera-facing normals
(``frame.position``; ``frame.compact_normal`` through ``frame.to_image``):

    w(p, q) = h(q − p) · exp(−‖n_p − n_q‖² / σ_n²) · exp(−(|n_p · (x_q − x_p)| / (f_p ‖q − p‖))² / σ_x²)

The normal term is Dammertz's (their eq. 5 with n). The position term is the distance of the
tap's point from p's tangent plane, in units of how far the tap is on screen (f_p: p's pixel
footprint, :meth:`Frame.pixel_footprint`; ‖q − p‖ in pixels) — the scale-free form of
Dammertz's ‖x_p − x_q‖² that SVGF uses for depth (Schied et al. 2017 §4.3, depth weight with
its screen-space gradient): it stops at a caster standing on a receiver (a jump off the plane)
but not along a plane, however far in world units the holes reach. Both weights depend only on
the G-buffer, so the numerator and denominator of the ratio get the *same* weights (Heitz
et al. §4: denoise both, then divide). Dammertz's third (colour) term is left out for that
reason: a weight on the noisy signal would differ between the two images.

**Temporal accumulation** (``temporal_alpha`` = a, 0 = off; ``shadowlab animate`` only): an
exponential moving average of the per-pixel sums (free/N and live/N) with the reverse-
reprojected history (Nehab et al. 2007, §3; the technique reprojects with the frames' exact
points itself, :func:`shadowlab.geometry.reprojection.reproject`, matching within :data:`HISTORY_FOOTPRINTS`
pixel footprints rather than the flicker metrics' quarter footprint, which under a camera pan
kept only a small share of the pixels):

    S_k(p) = (1 − a_p) · s_k(p) + a_p · S_{k−1}(q),   a_p = min(a, n_p / (n_p + 1)),

with q p's pixel in frame k − 1 and n_p the frames already accumulated there (a plain average
while fewer than a/(1 − a) frames are held, as SVGF's α = max(α, 1/n), §4.1), and a reset
(S = s, n = 1) wherever the reprojection is invalid (disoccluded, off screen, another surface).
Before blending, the reprojected history is clamped, per channel, to μ ∓ γσ of the current
frame's sums over a 5 × 5 window (``temporal_clamp`` = γ, 0 = off; the neighbourhood clamp of
temporal anti-aliasing, Karis 2014, with Salvi's mean and deviation bounds): reprojection follows
the *surface*, so a shadow moving over a still floor leaves a valid but stale history behind it
(ghosting, the SS3 lag); where the current frame's neighbourhood is all lit or all shadowed
(σ = 0) the clamp replaces the stale value, while inside a noisy penumbra (large σ) it lets the
history through. Measured on soft_moving_caster (no denoiser, docs/soft-shadows.md): without
the clamp accumulation *raised* visibility_mae (the history trails the crate); with it,
accumulation lowered both visibility_mae and temporal_error, γ = 0.5 (the default) more than
γ = 1.
The accumulated sums are what the denoiser filters (SVGF's order: accumulate, then filter);
the history is the unfiltered sums, so the spatial blur never feeds back. a is the weight of the
*history* (SVGF's α is 1 − a). U is analytic and recomputed every frame: only the shadow
term is accumulated, so a moving light or receiver lags only in its shadow.

How state crosses frames: :meth:`Technique.begin_frame` (``shadowlab animate`` calls it before
measuring each light of each frame) hands over a :class:`~shadowlab.geometry.reprojection.FrameStep` (the
frame's index and the light); the technique keeps its own last result per light, with that
frame's exact points, and makes it the reprojected history when frame k + 1 begins. Renders are repeatable: each one recomputes the frame's result from the same history
and the same per-frame random stream. In compare and study nothing is accumulated.
"""
from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ...geometry import reprojection as temporal
from ...util.compiled import JIT as _JIT
from ...util.compiled import cores, in_parts, njit, split
from ...scene.area_lights import AreaLight, RectLight
from ...truth.tracing import DEFAULT_OFFSET_SCALE, caster_scene, occlusion_ids, offset_origins
from ..base import FIRST, SUM, Param, PlotStyle, Technique, TechniqueError
from .raytrace import CHUNK_RAYS, ChunkBuffers, area_chunk_rays

#: Most light samples per pixel: a real-time budget (SS3 is about 1–4).
MAX_SAMPLES = 16
#: Entropy word mixed into every seed of this technique's stream, so that rt_soft:seed=s never
#: draws the truth's jitter (the truth seeds chunk i with [s, i]).
STREAM_SALT = 0x52545346  # "RTSF"
#: B3-spline coefficients (Dammertz et al. 2010 §3: h = 1/16 (1, 4, 6, 4, 1)).
B3 = np.array([1.0, 4.0, 6.0, 4.0, 1.0]) / 16.0
#: Accumulated frames counted per pixel at most (enough for any a < 1 - 1/64).
MAX_HISTORY = 64
#: Temporal accumulation's same-surface test: the reprojected pixel's exact point within this
#: many pixel footprints of the current one. The metrics' quarter footprint
#: (:data:`shadowlab.geometry.reprojection.SAME_SURFACE_FOOTPRINTS`) keeps only a small share of the
#: pixels under a camera pan (the nearest pixel centre is up to half a pixel diagonal off, more
#: on a slanted floor, as on soft_moving_caster: tests/techniques/rays/test_rt_soft.py); 2
#: footprints keeps a surface's nearest pixel and still rejects a caster's top over the floor.
HISTORY_FOOTPRINTS = 2.0
#: Half-width of the neighbourhood clamp's window (5 x 5 pixels).
CLAMP_RADIUS = 2


# ---------------------------------------------------------------------------- compiled kernels
@njit(**_JIT)
def rect_unshadowed(points, normals, corners, light_normal, area, out):
    """U(P) per point (M,): the fraction of a one-sided rect's area that faces P and lies
    strictly above P's tangent plane ((y − P)·N > 0), the analytic integral of the ratio
    estimator's f (module docstring). ``corners`` (4, 3) in order around the rect,
    ``light_normal`` its unit emitting normal, ``area`` its area. The rect is clipped by the
    plane (Sutherland–Hodgman against one plane) and the clipped polygon's area is half the
    norm of Σ v_i × v_{i+1} (a planar polygon)."""
    poly = np.empty((8, 3))
    for i in range(points.shape[0]):
        p0, p1, p2 = points[i, 0], points[i, 1], points[i, 2]
        # one-sided: P must lie in front of the emitting plane
        if ((p0 - corners[0, 0]) * light_normal[0] + (p1 - corners[0, 1]) * light_normal[1]
                + (p2 - corners[0, 2]) * light_normal[2]) <= 0.0:
            out[i] = 0.0
            continue
        n0, n1, n2 = normals[i, 0], normals[i, 1], normals[i, 2]
        k = 0
        clipped = 0
        for c in range(4):
            a = corners[c]
            b = corners[(c + 1) % 4]
            da = (a[0] - p0) * n0 + (a[1] - p1) * n1 + (a[2] - p2) * n2
            db = (b[0] - p0) * n0 + (b[1] - p1) * n1 + (b[2] - p2) * n2
            if da > 0.0:
                poly[k, 0], poly[k, 1], poly[k, 2] = a[0], a[1], a[2]
                k += 1
            else:
                clipped += 1
            if (da > 0.0) != (db > 0.0):  # the edge crosses the plane: keep the crossing
                t = da / (da - db)
                poly[k, 0] = a[0] + t * (b[0] - a[0])
                poly[k, 1] = a[1] + t * (b[1] - a[1])
                poly[k, 2] = a[2] + t * (b[2] - a[2])
                k += 1
        if k < 3:
            out[i] = 0.0
            continue
        if k == 4 and clipped == 0:  # the whole rect above the horizon: exactly 1, not a rounded area ratio
            out[i] = 1.0
            continue
        sx = sy = sz = 0.0
        for j in range(k):
            a = poly[j]
            b = poly[(j + 1) % k]
            sx += a[1] * b[2] - a[2] * b[1]
            sy += a[2] * b[0] - a[0] * b[2]
            sz += a[0] * b[1] - a[1] * b[0]
        out[i] = min(1.0, 0.5 * np.sqrt(sx * sx + sy * sy + sz * sz) / area)


@njit(**_JIT)
def atrous_rows(src, out, pos, nrm, footprint, mask, step, inv_sn2, inv_sx2, kernel, row0, row1):
    """One edge-avoiding à-trous pass (Dammertz et al. 2010 §3; weights in the module
    docstring) over rows [row0, row1) of ``src`` (H, W, C) into ``out``: taps ``step`` pixels
    apart, only pixels with ``mask`` read or written (others copied). ``inv_sn2`` = 1/σ_n²,
    ``inv_sx2`` = 1/σ_x² (0 switches a term off). Every channel gets the same weights."""
    h, w, c = src.shape
    acc = np.empty(c)
    for y in range(row0, row1):
        for x in range(w):
            if not mask[y, x]:
                for ch in range(c):
                    out[y, x, ch] = src[y, x, ch]
                continue
            px0, px1, px2 = pos[y, x, 0], pos[y, x, 1], pos[y, x, 2]
            n0, n1, n2 = nrm[y, x, 0], nrm[y, x, 1], nrm[y, x, 2]
            fp = footprint[y, x]
            for ch in range(c):
                acc[ch] = 0.0
            wsum = 0.0
            for j in range(5):
                yy = y + (j - 2) * step
                if yy < 0 or yy >= h:
                    continue
                for i in range(5):
                    xx = x + (i - 2) * step
                    if xx < 0 or xx >= w or not mask[yy, xx]:
                        continue
                    wt = kernel[j] * kernel[i]
                    if i != 2 or j != 2:
                        d0 = nrm[yy, xx, 0] - n0
                        d1 = nrm[yy, xx, 1] - n1
                        d2 = nrm[yy, xx, 2] - n2
                        # Dammertz eq. (5) on normals: exp(-|n_p - n_q|^2 / sigma_n^2)
                        e = (d0 * d0 + d1 * d1 + d2 * d2) * inv_sn2
                        # distance of q's point from p's tangent plane, per footprint x screen
                        # distance (SVGF's depth weight, Schied et al. 2017 §4.3)
                        plane = abs((pos[yy, xx, 0] - px0) * n0 + (pos[yy, xx, 1] - px1) * n1
                                    + (pos[yy, xx, 2] - px2) * n2)
                        r = plane / (fp * step * np.sqrt((i - 2.0) ** 2 + (j - 2.0) ** 2))
                        e += r * r * inv_sx2
                        wt *= np.exp(-e)
                    wsum += wt
                    for ch in range(c):
                        acc[ch] += wt * src[yy, xx, ch]
            for ch in range(c):
                out[y, x, ch] = acc[ch] / wsum  # the centre tap is always in: wsum > 0


@njit(**_JIT)
def neighbourhood_bounds(img, mask, radius, gamma, lo, hi):
    """Per pixel of ``mask`` and channel: the mean μ and standard deviation σ of ``img`` (H, W,
    C) over the masked pixels of the (2r + 1)² window around it, as the bounds μ ∓ γσ in ``lo``
    and ``hi`` (H, W, C) — the neighbourhood clamp of temporal anti-aliasing (Karis 2014,
    "High quality temporal supersampling"; Salvi's variance clipping, GDC 2016) that keeps a
    reprojected history from outliving what the current frame shows."""
    h, w, c = img.shape
    for y in range(h):
        for x in range(w):
            if not mask[y, x]:
                continue
            for ch in range(c):
                s = 0.0
                s2 = 0.0
                n = 0
                for yy in range(max(0, y - radius), min(h, y + radius + 1)):
                    for xx in range(max(0, x - radius), min(w, x + radius + 1)):
                        if mask[yy, xx]:
                            v = img[yy, xx, ch]
                            s += v
                            s2 += v * v
                            n += 1
                mu = s / n
                sd = np.sqrt(max(0.0, s2 / n - mu * mu))
                lo[y, x, ch] = mu - gamma * sd
                hi[y, x, ch] = mu + gamma * sd


@njit(**_JIT)
def accumulate(cur, hist, hist_len, source, valid, alpha, out, out_len):
    """Temporal accumulation (module docstring) of per-pixel sums ``cur`` (P, C) with the
    previous frame's ``hist`` (P', C) and its frame counts ``hist_len`` (P',): pixel p with a
    valid reprojection (``valid`` (P,), ``source`` (P,) its row in ``hist``)
    blends its history with weight min(alpha, n/(n+1)); others restart. Writes ``out`` (P, C)
    and ``out_len`` (P,)."""
    for p in range(cur.shape[0]):
        if valid[p]:
            q = source[p]
            n = hist_len[q]
            a = min(alpha, n / (n + 1.0))
            for ch in range(cur.shape[1]):
                out[p, ch] = (1.0 - a) * cur[p, ch] + a * hist[q, ch]
            out_len[p] = min(n + 1, MAX_HISTORY)
        else:
            for ch in range(cur.shape[1]):
                out[p, ch] = cur[p, ch]
            out_len[p] = 1


def warm() -> None:
    """Compile or load this module's kernels (outside any timed pass)."""
    rect_unshadowed(np.zeros((1, 3)), np.ones((1, 3)), np.eye(4, 3), np.ones(3), 1.0, np.zeros(1))
    img = np.zeros((1, 1, 2))
    atrous_rows(img, img.copy(), np.zeros((1, 1, 3)), np.zeros((1, 1, 3)), np.ones((1, 1)), np.ones((1, 1), bool),
                1, 1.0, 1.0, B3, 0, 1)
    neighbourhood_bounds(img, np.ones((1, 1), bool), 1, 1.0, img.copy(), img.copy())
    accumulate(np.zeros((1, 2)), np.zeros((1, 2)), np.ones(1, np.int64), np.zeros(1, np.int64),
               np.ones(1, bool), 0.5, np.zeros((1, 2)), np.zeros(1, np.int64))


# ---------------------------------------------------------------------------- the stages
def sample_sums(scene, light: AreaLight, points: np.ndarray, normals: np.ndarray, origins: np.ndarray, n: int,
                seed: int, frame_index: int = 0) -> tuple[np.ndarray, np.ndarray, int]:
    """Per point (M,): ``live`` (samples facing it and above its horizon: Σ f_k) and ``free``
    (those unoccluded: Σ f_k u_k), int64 out of ``n``, and the rays traced. The truth's rays
    (:func:`shadowlab.techniques.rays.raytrace.area_chunk_rays`: same sampling, same offset origins,
    same segments); chunk i draws from ``default_rng([STREAM_SALT, seed, frame_index, i])``.
    Chunks run on the cores (Embree releases the GIL); the result does not depend on how many."""
    from ...truth.compiled import unoccluded_counts

    m = len(points)
    per = max(1, CHUNK_RAYS // n)
    chunks = [(i, a, min(a + per, m)) for i, a in enumerate(range(0, m, per))]
    local = threading.local()

    def run(chunk):
        i, a, b = chunk
        if not hasattr(local, "buffers"):
            local.buffers = ChunkBuffers(per * n)
        bufs = local.buffers
        rng = np.random.default_rng([STREAM_SALT, seed, frame_index, i])
        live, _, org, dirs = area_chunk_rays(light, points[a:b], normals[a:b], origins[a:b], n, rng, rows=False,
                                             out=(bufs.org, bufs.dirs))
        if scene is None or len(org) == 0:
            return live, live.copy(), len(org)
        hit = occlusion_ids(scene, org, dirs, bufs.tfar[:len(org)])
        free = np.empty(b - a, np.int64)
        unoccluded_counts(live, hit, free)
        return live, free, len(org)

    workers = max(1, min(cores(), len(chunks)))
    if workers == 1:
        results = [run(c) for c in chunks]
    else:
        with ThreadPoolExecutor(workers) as pool:
            results = list(pool.map(run, chunks))
    if not results:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), 0
    return (np.concatenate([r[0] for r in results]), np.concatenate([r[1] for r in results]),
            int(sum(r[2] for r in results)))


def unshadowed_fraction(light: AreaLight, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """U(P) (M,) float64: the analytic fraction of the light facing P and above its tangent
    plane (:func:`rect_unshadowed`); rect lights only (TechniqueError otherwise)."""
    if not isinstance(light, RectLight):
        raise TechniqueError(f"rt_soft: the ratio estimator's analytic term is implemented for rect lights; this is "
                             f"a {light.shape} light (use ratio=false, the plain average, for it)")
    out = np.empty(len(points))
    rect_unshadowed(np.ascontiguousarray(points, np.float64), np.ascontiguousarray(normals, np.float64),
                    np.ascontiguousarray(light.corners(), np.float64), np.asarray(light.normal, np.float64),
                    float(light.area), out)
    return out


def atrous(image: np.ndarray, position: np.ndarray, normal: np.ndarray, footprint: np.ndarray, mask: np.ndarray,
           iterations: int, sigma_normal: float, sigma_position: float) -> np.ndarray:
    """``iterations`` edge-avoiding à-trous passes (:func:`atrous_rows`, holes 1, 2, 4, ...) of
    ``image`` (H, W, C) float64 over the pixels of ``mask`` (H, W), guided by exact points
    ``position`` (H, W, 3), unit normals ``normal`` (H, W, 3) and pixel footprints (H, W). A
    σ of 0 switches its term off (weight 1). Row bands run on the cores. ``image`` is not
    modified: the passes ping-pong between two buffers of their own."""
    src = np.array(image, np.float64, order="C", copy=True)
    if iterations == 0:
        return src
    dst = np.empty_like(src)
    pos = np.ascontiguousarray(np.nan_to_num(position), np.float64)
    nrm = np.ascontiguousarray(np.nan_to_num(normal), np.float64)
    fp = np.ascontiguousarray(np.nan_to_num(footprint, nan=1.0), np.float64)
    mask = np.ascontiguousarray(mask, bool)
    inv_sn2 = 0.0 if sigma_normal == 0 else 1.0 / sigma_normal ** 2
    inv_sx2 = 0.0 if sigma_position == 0 else 1.0 / sigma_position ** 2
    h = src.shape[0]
    for it in range(iterations):
        step = 1 << it
        in_parts(lambda a, b: atrous_rows(src, dst, pos, nrm, fp, mask, step, inv_sn2, inv_sx2, B3, a, b),
                 split(h, src.size * 25))
        src, dst = dst, src
    return src


class RaySoft(Technique):
    """Few-sample ray-traced soft shadows: the ratio estimator, an edge-avoiding à-trous
    denoiser and temporal accumulation, each with a toggle (module docstring)."""

    name = "rt_soft"
    summary = ("ray-traced soft shadows, 1-16 samples/pixel: ratio estimator (Heitz et al. 2018), "
               "edge-avoiding a-trous denoiser (Dammertz et al. 2010), temporal accumulation")
    cpu = True
    PASSES = ("trace", "accumulate", "denoise")
    LIGHTS = frozenset({"area"})
    PARAMS = {
        "samples": Param(4, "light samples (shadow rays) per pixel, stratified over the light's area",
                         min=1, max=MAX_SAMPLES),
        "ratio": Param(True, "ratio estimator: V = U(P) * sum f V / sum f with U analytic (rect lights); "
                             "false: the plain average of the samples"),
        # 3: the lowest visibility_mae at 1 and 4 samples on soft_overlap and soft_moving_caster at
        # 320x240 (4 passes over-blur); the holes are in pixels, so the best count grows with the
        # image (soft_contact_hardening prefers 2)
        "iterations": Param(3, "a-trous denoiser passes (holes 1, 2, 4, ...); 0 = no denoiser", min=0, max=8),
        "sigma_normal": Param(0.5, "a-trous normal weight exp(-|n_p - n_q|^2 / sigma^2); 0 = off", min=0.0, max=10.0),
        "sigma_position": Param(1.0, "a-trous position weight: distance off p's tangent plane per pixel footprint "
                                     "x tap distance, exp(-(d)^2 / sigma^2); 0 = off", min=0.0, max=100.0),
        "temporal_alpha": Param(0.8, "animate: weight of the reprojected history in the moving average "
                                     "(0 = no temporal accumulation; still frames: none)", min=0.0, max=0.98),
        "temporal_clamp": Param(0.5, "animate: the history clamped to mean -/+ this many standard deviations of the "
                                     "current frame's 5x5 neighbourhood (against ghosting under motion); 0 = off",
                                min=0.0, max=10.0),
        "seed": Param(0, "seed of the light samples' jitter (decorrelated per animation frame)", min=0),
        "offset_scale": Param(DEFAULT_OFFSET_SCALE, "shadow-ray origin offset, as the truth's", min=0.0, max=1e-2),
    }
    STATS = {"rays": SUM, "samples": FIRST, "history_pixels": FIRST}
    STYLE = PlotStyle("#17becf", "h")

    def __init__(self, **params):
        super().__init__(**params)
        #: Per light index: (frame index, accumulated sums (M, 2), frame counts (M,), the frame's
        #: geometry, evaluated mask (H, W) and the evaluated pixels' flat indices (M,)) of the last
        #: frame rendered — the history of the next.
        self._last: dict = {}
        #: Per light index: the history the current frame blends with (None: none).
        self._history: dict = {}

    def begin_frame(self, step) -> None:
        """Roll the temporal state: the last result of light ``step.light`` becomes its history
        when it belongs to the frame before ``step.index``; frame 0 (or no step: the end of an
        animation) starts afresh."""
        super().begin_frame(step)
        if step is None:
            self._last.clear()
            self._history.clear()
            return
        last = self._last.get(step.light)
        self._history[step.light] = last if last is not None and last[0] == step.index - 1 else None

    def setup(self, frame, slot) -> None:
        """Untimed: kernels, the casters' Embree scene and the truth's offset origins (both per
        frame), the evaluated pixels, the analytic unshadowed fraction (ratio), the denoiser's
        guides, and (animate) this frame's geometry and the history it may blend with."""
        from ...truth import compiled as compiled_truth

        compiled_truth.warm()
        warm()
        if not isinstance(self.light, AreaLight):  # LIGHTS says area; a stand-in would be a bug
            raise TechniqueError(f"{self.name} needs an area light, got a {self.light.type_name} light")
        self.scene = caster_scene(frame) if frame.has_casters else None
        self.evaluated = slot.evaluated
        self.eval_idx = np.flatnonzero(self.evaluated)
        self.eval_pixels = frame.pixel_index[self.evaluated]  # flat (row-major) image index of each
        self.eval_points = frame.compact_position[self.evaluated]
        self.eval_normals = frame.compact_normal[self.evaluated]
        self.eval_origins = np.ascontiguousarray(offset_origins(frame, self.offset_scale)[self.evaluated])
        self.unshadowed = (unshadowed_fraction(self.light, self.eval_points, self.eval_normals) if self.ratio
                           else None)
        self.mask = frame.to_image(self.evaluated, fill=False, dtype=bool)
        if self.iterations:
            self.guide_position = frame.position
            self.guide_normal = frame.to_image(frame.compact_normal, fill=0.0, dtype=np.float64)
            self.guide_footprint = frame.pixel_footprint()
        step = self.animation_step
        self.frame_index = 0 if step is None else int(step.index)
        self.temporal = step is not None and self.temporal_alpha > 0 and step.light == slot.index
        self.geometry = temporal.FrameGeometry.of(frame) if self.temporal else None
        self.history = self._history.get(slot.index) if self.temporal else None
        self.rays = 0
        self.history_pixels = 0
        self.result = np.ones(len(self.eval_idx))

    def reprojected_history(self):
        """The history of this light reprojected into the current frame (Nehab et al. 2007,
        §3, with exact points: :func:`shadowlab.geometry.reprojection.reproject` within
        :data:`HISTORY_FOOTPRINTS`): the previous sums (P', 2) and frame counts (P',), and per
        current evaluated pixel the row of its match among them and whether it has one; None
        without a history."""
        if self.history is None:
            return None
        _, sums, lengths, prev_geometry, prev_mask, prev_pixels = self.history
        reproj = temporal.reproject(self.geometry, prev_geometry, self.mask, prev_mask, footprints=HISTORY_FOOTPRINTS)
        lookup = np.full(reproj.source.size, -1, np.int64)  # previous flat pixel → its row in ``sums``
        lookup[prev_pixels] = np.arange(len(prev_pixels))
        src = reproj.source.reshape(-1)[self.eval_pixels]
        valid = reproj.valid.reshape(-1)[self.eval_pixels]
        row = np.where(valid, lookup[np.where(valid, src, 0)], -1)
        valid &= row >= 0
        return sums, lengths, np.where(valid, row, 0).astype(np.int64), valid

    def clamped(self, sums: np.ndarray, hist: np.ndarray, source: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """The reprojected history (M, C) of each current pixel (``hist[source]``; anything
        where not ``valid``), clamped per channel to μ ∓ ``temporal_clamp`` · σ of the current
        sums over a :data:`CLAMP_RADIUS` window (:func:`neighbourhood_bounds`)."""
        h, w = self.frame.height, self.frame.width
        img = np.zeros((h * w, sums.shape[1]))
        img[self.eval_pixels] = sums
        lo, hi = np.zeros((h, w, sums.shape[1])), np.zeros((h, w, sums.shape[1]))
        neighbourhood_bounds(img.reshape(h, w, -1), self.mask, CLAMP_RADIUS, float(self.temporal_clamp), lo, hi)
        lo, hi = lo.reshape(h * w, -1)[self.eval_pixels], hi.reshape(h * w, -1)[self.eval_pixels]
        return np.clip(hist[source], lo, hi)

    def render(self) -> None:
        """Timed: trace ``samples`` rays per evaluated pixel; accumulate with the reprojected
        history (animate, ``temporal_alpha`` > 0); denoise; divide (ratio) or average."""
        with self.timed_pass("trace", cpu=True):
            live, free, self.rays = sample_sums(self.scene, self.light, self.eval_points, self.eval_normals,
                                                self.eval_origins, self.samples, self.seed, self.frame_index)
            sums = np.stack([free, live], axis=1) / float(self.samples)  # (M, 2): Σ f u / N, Σ f / N
        with self.timed_pass("accumulate", cpu=True):
            lengths = np.ones(len(sums), np.int64)
            past = self.reprojected_history()
            if past is not None:
                hist, hist_len, source, valid = past
                if self.temporal_clamp > 0:  # the history kept within the current frame's neighbourhood
                    hist = self.clamped(sums, hist, source, valid)  # now one row per current pixel
                    hist_len, source = hist_len[source], np.arange(len(sums))
                acc, acc_len = np.empty_like(sums), np.empty_like(lengths)
                accumulate(sums, hist, hist_len, source, valid, float(self.temporal_alpha), acc, acc_len)
                sums, lengths = acc, acc_len
            if self.temporal:  # the next frame's history (begin_frame hands it over)
                self._last[self.slot.index] = (self.frame_index, sums, lengths, self.geometry, self.mask,
                                               self.eval_pixels)
            self.history_pixels = int((lengths > 1).sum())
        with self.timed_pass("denoise", cpu=True):
            channels = sums if self.ratio else sums[:, :1]
            if self.iterations:
                h, w = self.frame.height, self.frame.width
                img = np.zeros((h * w, channels.shape[1]))
                img[self.eval_pixels] = channels
                img = atrous(img.reshape(h, w, -1), self.guide_position, self.guide_normal, self.guide_footprint,
                             self.mask, self.iterations, self.sigma_normal, self.sigma_position)
                channels = img.reshape(-1, channels.shape[1])[self.eval_pixels]
            if self.ratio:
                num, den = channels[:, 0], channels[:, 1]
                # Heitz et al. 2018: V = U · (filtered Σ f V) / (filtered Σ f); ratio 1 where no sample is live
                shadow = np.divide(num, den, out=np.ones_like(num), where=den > 0)
                self.result = self.unshadowed * np.clip(shadow, 0.0, 1.0)
            else:
                self.result = channels[:, 0]

    def visibility(self) -> np.ndarray:
        """Float32 (H, W), row 0 = top: the estimate on evaluated pixels, 1 elsewhere."""
        vis = np.ones(len(self.evaluated), np.float32)
        vis[self.eval_idx] = self.result
        return self.frame.to_image(vis, fill=1.0)

    def work(self, counted: dict, stats: dict) -> dict:
        """Shadow rays traced by Embree per render."""
        return {"trace": {"rays": stats["rays"]}}

    def stats(self) -> dict:
        """Rays traced per render, samples per pixel, and the pixels whose value carries an
        accumulated history (0 outside an animation)."""
        return {"rays": int(self.rays), "samples": int(self.samples), "history_pixels": int(self.history_pixels)}
