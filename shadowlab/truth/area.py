"""The sampled visibility of an area light (the truth's area path, moved here from
:mod:`shadowlab.techniques.rays.raytrace` so that techniques of other families can trace the same
estimator: the hybrid ray tracer's uncertain pixels, :mod:`shadowlab.techniques.maps.hybrid_rt`).

The estimator (stratified samples of :meth:`~shadowlab.scene.area_lights.AreaLight.sample_for`,
samples below the point's tangent plane occluded, float32 segments to the samples from the offset
origins) and its error bound are documented in :mod:`shadowlab.techniques.rays.raytrace`; the
compiled passes it runs in are :mod:`shadowlab.truth.compiled`.
"""
from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..scene.area_lights import AreaLight, above_horizon
from ..scene.lights import T_LIGHT
from .tracing import occlusion_ids

#: Samples (shadow rays) per chunk of pixels of an area light.
CHUNK_RAYS = 2 ** 20
#: At most this many samples held at once (all worker threads together).
MAX_RAYS_HELD = 2 ** 21

class SharedJitter:
    """Stands in for a :class:`numpy.random.Generator` in :meth:`AreaLight.sample_for`:
    ``random((M, n, 2))`` gives every point the same jitter ``uv`` (n, 2) float64 — the same
    stratified pattern for every pixel (``decorrelate=false``; for a sphere, the same
    coordinates on each point's own cap)."""

    def __init__(self, uv: np.ndarray):
        self.uv = uv

    def random(self, shape) -> np.ndarray:
        """``uv`` broadcast to ``shape`` (…, n, 2) (read-only view)."""
        if tuple(shape[-2:]) != self.uv.shape:
            raise ValueError(f"shared jitter of shape {self.uv.shape} asked for {tuple(shape)}")
        return np.broadcast_to(self.uv, shape)


def area_chunk_rays(light: AreaLight, points: np.ndarray, normals: np.ndarray, origins: np.ndarray, n: int,
                    rng, rows: bool = True, out: tuple[np.ndarray, np.ndarray] | None = None
                    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray]:
    """The shadow rays of an area light for M points: samples that face the point and lie above
    its horizon, per point (M,) int64; the point of each ray (K,) int64 (None when all M·n
    samples are live — then ray k belongs to point k // n — or when ``rows`` is false); origins
    (K, 3) and unnormalised directions (K, 3) float32 (the light sample is reached at t = 1).
    The rays of a point are consecutive, in sample order.

    ``points`` (M, 3) float64 exact surface points, ``normals`` (M, 3) their camera-facing unit
    normals, ``origins`` (M, 3) float32 their offset ray origins; ``rng`` a Generator (or
    :class:`SharedJitter`) for :meth:`AreaLight.sample_for`. ``out``: float32 buffers (at least
    M·n, 3) for the origins and directions, which are then returned as views of them (the
    worker threads of :func:`area_visibility` reuse theirs from chunk to chunk).

    The horizon test and the segments are one compiled pass
    (:func:`shadowlab.truth.compiled.segment_rays`, issue 27), bit for bit
    :func:`area_chunk_rays_reference` (tests/truth/test_compiled_truth.py holds them equal)."""
    from .compiled import segment_rays

    m = len(points)
    samples, facing = light.sample_for(points, n, rng)
    if out is None:
        out = (np.empty((m * n, 3), np.float32), np.empty((m * n, 3), np.float32))
    elif any(b.dtype != np.float32 or b.shape[1:] != (3,) or len(b) < m * n or not b.flags.c_contiguous for b in out):
        raise ValueError(f"ray buffers must be C-contiguous float32 (>= {m * n}, 3) for {m} points x {n} samples")
    counts = np.empty(m, np.int64)
    k = segment_rays(np.ascontiguousarray(samples, np.float64), np.ascontiguousarray(facing, bool),
                     np.ascontiguousarray(points, np.float64), np.ascontiguousarray(normals, np.float64),
                     np.ascontiguousarray(origins, np.float32), counts, out[0], out[1])
    which = None
    if rows and k != m * n:
        which = np.repeat(np.arange(m), counts)
    return counts, which, out[0][:k], out[1][:k]


def area_chunk_rays_reference(light: AreaLight, points: np.ndarray, normals: np.ndarray, origins: np.ndarray,
                              n: int, rng) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray]:
    """:func:`area_chunk_rays` in plain numpy (the truth's code before issue 27): the reference
    the compiled path must equal bit for bit, and the definition to read."""
    samples, facing = light.sample_for(points, n, rng)
    live = facing & above_horizon(samples, points, normals)
    counts = live.sum(axis=1)
    if live.all():  # the common case: no compaction needed
        rows = None
        org = np.repeat(origins, n, axis=0)
        target = samples.reshape(-1, 3)
    else:
        rows, cols = np.nonzero(live)
        org = origins[rows]
        target = samples[rows, cols]
    return counts, rows, org, (target - org).astype(np.float32)


def area_chunk_counts(scene, light: AreaLight, points: np.ndarray, normals: np.ndarray, origins: np.ndarray,
                      n: int, rng, buffers: "ChunkBuffers | None" = None) -> tuple[np.ndarray, int]:
    """Unoccluded sample counts of an area light for M points: int64 (M,) out of ``n``, and the
    number of shadow rays traced. A sample counts if it faces the point, lies above the point's
    tangent plane and the float32 segment from the origin to it is unoccluded up to
    :data:`shadowlab.scene.lights.T_LIGHT` (:func:`area_chunk_rays` for the arguments); ``scene`` is
    the Embree scene of the casters (None: nothing casts). Each point's rays are consecutive,
    so the unblocked ones are counted per point in one compiled pass over Embree's answers
    (:func:`shadowlab.truth.compiled.unoccluded_counts`). ``buffers``: a worker thread's
    reusable ray buffers (:class:`ChunkBuffers`), else fresh ones."""
    from .compiled import unoccluded_counts

    if buffers is None:
        buffers = ChunkBuffers(len(points) * n)
    counts, _, org, dirs = area_chunk_rays(light, points, normals, origins, n, rng, rows=False,
                                           out=(buffers.org, buffers.dirs))
    if scene is None or len(org) == 0:
        return counts, len(org)
    hit = occlusion_ids(scene, org, dirs, buffers.tfar[:len(org)])
    free = np.empty(len(points), np.int64)
    unoccluded_counts(counts, hit, free)
    return free, len(org)


class ChunkBuffers:
    """Float32 ray buffers for ``rays`` shadow rays — origins and directions (rays, 3) and tfar
    (rays,) = :data:`~shadowlab.scene.lights.T_LIGHT` — that one worker thread reuses for every
    chunk of :func:`area_visibility`: fresh arrays per chunk would page-fault their memory in
    again each time."""

    def __init__(self, rays: int):
        self.org = np.empty((rays, 3), np.float32)
        self.dirs = np.empty((rays, 3), np.float32)
        self.tfar = np.full(rays, T_LIGHT, np.float32)


def area_chunks(m: int, n: int, seed: int, decorrelate: bool) -> list[tuple[int, int, object]]:
    """How :func:`area_visibility` cuts M points: (start, stop, rng) per chunk of
    ``CHUNK_RAYS // n`` points (at least one); chunk i draws from ``default_rng([seed, i])``
    (``decorrelate``), or every chunk shares one :class:`SharedJitter` drawn from
    ``default_rng(seed)``."""
    if n < 1:
        raise ValueError(f"area light visibility needs at least one sample, got {n}")
    per = max(1, CHUNK_RAYS // n)
    shared = None if decorrelate else SharedJitter(np.random.default_rng(seed).random((n, 2)))
    return [(a, min(a + per, m), shared if shared is not None else np.random.default_rng([seed, i]))
            for i, a in enumerate(range(0, m, per))]


def area_workers(n: int, chunks: int) -> int:
    """Worker threads for :func:`area_visibility`: the cores, at most :data:`MAX_RAYS_HELD`
    samples alive at once, no more than the chunks."""
    per = max(1, CHUNK_RAYS // n)
    from ..util.compiled import cores

    return max(1, min(cores(), MAX_RAYS_HELD // (per * n), chunks))


def area_visibility(scene, light: AreaLight, points: np.ndarray, normals: np.ndarray, origins: np.ndarray,
                    n: int, seed: int = 0, decorrelate: bool = True) -> tuple[np.ndarray, int]:
    """Sampled visibility of an area light (module docstring) at M points: float64 (M,) in
    [0, 1] (count / n), and the number of shadow rays traced. Chunks (:func:`area_chunks`) run
    on :func:`area_workers` threads; the result depends only on (seed, n, decorrelate), not on
    the thread count."""
    chunks = area_chunks(len(points), n, seed, decorrelate)
    rays = max((b - a for a, b, _ in chunks), default=0) * n
    local = threading.local()

    def run(chunk):
        a, b, rng = chunk
        if not hasattr(local, "buffers"):
            local.buffers = ChunkBuffers(rays)
        return area_chunk_counts(scene, light, points[a:b], normals[a:b], origins[a:b], n, rng, local.buffers)

    workers = area_workers(n, len(chunks))
    if workers == 1:
        results = [run(c) for c in chunks]
    else:
        with ThreadPoolExecutor(workers) as pool:
            results = list(pool.map(run, chunks))
    counts = np.concatenate([c for c, _ in results]) if results else np.zeros(0, np.int64)
    return counts / n, int(sum(r for _, r in results))
