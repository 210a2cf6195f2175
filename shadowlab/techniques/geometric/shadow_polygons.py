"""Exact object-space shadow polygons for static lights (Atherton, Weiler & Greenberg 1978).

For every convex receiver polygon (a receiver triangle) and every convex caster polygon (a
caster triangle; only the light-facing ones of a closed mesh, whose shadows already make up the
whole shadow), the receiver's shadowed part is computed exactly, in float64, with the tolerance
``epsilon`` (× the scene's size): :func:`shadowlab.geometry.polygon_clipping.shadow_fragment`
defines it for one pair. Pairs are culled first (:func:`candidate_pairs` defines a candidate):
some receiver vertex must lie behind the caster's plane, and no side plane of the caster's
frustum may have the whole receiver outside. Three back-ends give the same fragments bit for
bit (``fragment_triangles(clipper=...)``): by default culling and clipping run in one compiled
loop (:mod:`shadowlab.geometry.compiled_clipping`, numba); ``'batch'`` culls with dense matrix
tests and clips tens of thousands of pairs at once in numpy
(:mod:`shadowlab.geometry.batch_clipping`); ``'scalar'`` loops over the one-pair clipper (the
reference, for tests and before/after experiments). The fragments are computed
once per light (``setup``: the preprocessing, reported as ``preprocess_ms`` and inside
``setup_ms``) and drawn each frame as geometry (``render``), each fragment only on the pixels
where the G-buffer saw its own receiver triangle.

Size: the culling streams over the casters and the clipping over the pairs, so neither the
pairs nor their temporaries are ever all held (a few hundred MB at most); what grows is the
fragments' geometry, 120 bytes a triangle while it is gathered, allowed up to half the memory
available at setup (``MEMORY_SHARE``: on a machine with 20 GiB free, about 90 million fragment
triangles) and an error beyond. Long preprocessing shows a progress bar on a terminal.

Several lights: for each receiver triangle, only the ``max_lights`` lights with the largest
unshadowed contribution (λ · N·L · luminance at its centroid) get fragments; the others leave it
lit, and the metrics show what dropping them costs (``dropped_faces`` counts them).
"""
from __future__ import annotations

import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ...gpu import glstate, memory, programs
from ...geometry import adjacency as adj
from ...geometry import batch_clipping as bc
from ...geometry import polygon_clipping as pc
from ...geometry.frusta import side_planes
from ...geometry.triangles import triangle_normals, triangle_planes
from ...geometry.vectors import dot3
from ...gpu.glstate import PassState
from ..base import FIRST, SUM, Param, PlotStyle, Technique, TechniqueError, TuneRange

#: Receiver/caster pair tests of the bulk culling per step (bounds its temporaries, ~200 MB).
PAIR_TESTS_PER_STEP = 1 << 22
#: Candidate pairs clipped together (bounds the batch clipper's temporaries, ~150 MB).
CLIP_BATCH = 1 << 16
#: The preprocessing's back-ends, fastest first: compiled (numba) culling and clipping, numpy
#: batch clipping, the one-pair clipper in a Python loop (the reference). Same fragments.
CLIPPERS = ("compiled", "batch", "scalar")
#: Share of the memory available at setup that the fragments' geometry may take: beyond it the
#: technique stops with an error rather than push the machine into swap.
MEMORY_SHARE = 0.5
#: Bytes a fragment triangle holds while the fragments are gathered: float64 vertices (72),
#: their float32 copy (36) and the receiver ids (12).
BYTES_PER_FRAGMENT_TRIANGLE = 120
_LUMA = np.array([0.2126, 0.7152, 0.0722])


class ShadowPolygons(Technique):
    """Precomputed exact shadow fragments (convex clipping) rendered as geometry."""

    name = "shadow_polygons"
    summary = "exact object-space shadow polygons (convex clipping), precomputed per static light"
    PASSES = ("draw",)
    STYLE = PlotStyle("#9467bd", "D")
    STATS = {"preprocess_ms": SUM, "compile_ms": SUM, "pairs_clipped": SUM, "polygons": SUM,
             "fragment_triangles": SUM, "dropped_faces": FIRST}
    LIGHT_SAMPLED = True  # light_samples=N: averaged over N points of an area light (shadowlab.measurement.light_sampling)
    PARAMS = {
        "epsilon": Param(1e-9, "geometric tolerance of every predicate, relative to the scene's size",
                         # from near float64 round-off to a tolerance that merges visible features
                         min=0.0, max=1e-1, tune=TuneRange(1e-12, 1e-4, log=True)),
        "max_lights": Param(8, "per receiver face, the lights that get shadows (largest contribution first)",
                            min=1, max=8),
    }

    def setup(self, frame, slot) -> None:
        """Compute the fragments for this light (the preprocessing) and upload them. The compiled
        kernel is loaded (or, on a fresh install, compiled) first, once per process: that time
        is in ``setup_ms`` and reported as ``compile_ms``, not in ``preprocess_ms``."""
        from ...geometry import compiled_clipping

        self.compile_ms = compiled_clipping.warm()
        t0 = time.perf_counter()
        light_h = slot.light.homogeneous()
        eps = self.epsilon * frame.scene.extent()
        rec_tris, rec_ids, caster_tris = self.polygons(frame, slot)
        work = fragment_triangles(rec_tris, caster_tris, light_h, eps, progress=_progress_bar(self.name))
        self.pairs_clipped = work.pairs
        self.fragment_count = work.fragments
        vertices = work.triangles.reshape(-1, 3).astype("f4")
        triangle_ids = np.repeat(rec_ids[work.receiver].astype(np.int32), 3)
        self.preprocess_ms = 1e3 * (time.perf_counter() - t0)
        ctx = frame.ctx
        self.prog = self.program("shadow_fragments.glsl")
        self.prog["u_view_proj"].write(programs.mat_bytes(frame.view_projection))
        programs.set_uniforms(self.prog, {"u_ids": 0, "u_shadowed": 0.0})
        self.count = len(vertices)
        self.vbo = self.own(ctx.buffer(vertices.tobytes() if len(vertices) else b"\0" * 12))
        self.ibo_ids = self.own(ctx.buffer(triangle_ids.tobytes() if len(triangle_ids) else b"\0" * 4))
        self.vao = self.own(ctx.vertex_array(self.prog, [(self.vbo, "3f", "in_pos"),
                                                         (self.ibo_ids, "1i", "in_triangle")]))
        self.vis_tex, self.vis_fbo = self.visibility_target((frame.width, frame.height))

    def polygons(self, frame, slot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the preprocessing of ``slot`` (or a scene light's index) clips: the receiver triangles (R, 3, 3) float64 that
        get its shadows (see ``max_lights``), their indices (R,) in the frame's triangle order,
        and the caster triangles (C, 3, 3) (a closed mesh's light-facing faces only); counts the
        faces left without this light's shadows in ``dropped_faces``."""
        slot = frame.as_slot(slot)
        scene = frame.scene
        light = slot.light
        starts = np.cumsum([0] + [len(o.faces) for o in scene.objects])
        casters = []
        for obj in scene.objects:
            if not obj.casts:
                continue
            tris = obj.triangles
            table = obj.edges
            if table.closed:  # a closed mesh's light-facing faces cast its whole shadow
                tris = tris[adj.facing(table, light)]
            casters.append(tris)
        caster_tris = np.concatenate(casters) if casters else np.zeros((0, 3, 3))
        receivers, receiver_ids = [], []
        self.dropped_faces = 0
        for i, obj in enumerate(scene.objects):
            if obj.receives:
                keep = self._kept_faces(obj, slot)
                self.dropped_faces += int((~keep).sum())
                receivers.append(obj.triangles[keep])
                receiver_ids.append(starts[i] + np.flatnonzero(keep))
        rec_tris = np.concatenate(receivers) if receivers else np.zeros((0, 3, 3))
        rec_ids = np.concatenate(receiver_ids) if receiver_ids else np.zeros(0, np.int64)
        return rec_tris, rec_ids, caster_tris

    def _kept_faces(self, obj, slot) -> np.ndarray:
        """Bool per face: the slot's light is among the face's ``max_lights`` strongest of the
        scene's lights as this render sees them (``slot.scene_lights``)."""
        lights = slot.scene_lights
        if len(lights) <= self.max_lights:
            return np.ones(len(obj.faces), bool)
        tris = obj.triangles
        centre = tris.mean(axis=1)
        normal, _ = triangle_normals(tris)
        contrib = []
        for light in lights:
            dirs, _ = light.to_light(centre)
            facing = np.abs(np.einsum("ij,ij->i", dirs, normal))  # two-sided receivers
            contrib.append(light.footprint(centre) * facing * float(light.color @ _LUMA))
        contrib = np.array(contrib)  # (lights, faces)
        rank = (contrib > contrib[slot.index]).sum(axis=0)  # lights strictly stronger
        return rank < self.max_lights

    def render(self) -> None:
        """Draw the precomputed fragments over the G-buffer."""
        from OpenGL import GL

        with self.timed_pass("draw"):
            self.vis_fbo.use()
            glstate.apply(PassState())
            GL.glClearBufferfv(GL.GL_COLOR, 0, (1.0, 0.0, 0.0, 0.0))
            self.frame.tex_ids.use(0)
            if self.count:
                self.vao.render(vertices=self.count)

    def stats(self) -> dict:
        """Preprocessing time (and the kernel's one-time load or compile), pairs clipped,
        fragments and triangles produced, faces dropped."""
        return {"preprocess_ms": self.preprocess_ms, "compile_ms": self.compile_ms, "pairs_clipped": self.pairs_clipped,
                "polygons": self.fragment_count, "fragment_triangles": self.count // 3,
                "dropped_faces": self.dropped_faces}


@dataclass
class FragmentTriangles:
    """The exact shadow of one light as triangles: ``triangles`` (T, 3, 3) float64, the index
    into the receiver triangles (T,) each lies on, and how many candidate pairs were clipped and
    how many gave a fragment."""

    triangles: np.ndarray
    receiver: np.ndarray
    pairs: int
    fragments: int


def candidate_pairs(rec: np.ndarray, cas: np.ndarray, light_h: np.ndarray, eps: float,
                    casters: slice | None = None) -> np.ndarray:
    """(receiver, caster) index pairs (N, 2), caster-major and receiver-ascending, whose shadow
    and receiver can overlap, culled in bulk and conservatively: some receiver vertex behind (or
    on) the caster's plane, and no side plane of the caster's frustum with every receiver vertex
    outside it. ``casters`` restricts the test to a range of caster triangles (indices stay
    global).

    The same pairs as testing the three vertices of every receiver against every caster's four
    planes (tests/geometry/test_batch_clipping.py holds it to that), found in two stages: each receiver's
    bounding sphere against the four planes (one float32 matrix product for all pairs), which
    only drops pairs the vertex test drops too, then the vertex test on the pairs left."""
    casters = casters or slice(0, len(cas))
    c0 = casters.start or 0
    cas = cas[casters]
    if len(rec) == 0 or len(cas) == 0:
        return np.zeros((0, 2), np.int64)
    n, d = triangle_planes(cas)
    sign = np.where(n @ light_h[:3] + d * light_h[3] >= 0, 1.0, -1.0)  # light on the positive side
    planes = side_planes(cas, light_h)  # (C, 3, 4): the frustum's side planes, inward
    # Stage 1: spheres (centre q, radius r) around the receivers. For a unit normal,
    # n·v + d ≤ n·q + d + r for every vertex v, so a sphere wholly outside a plane (or wholly
    # in front of the caster) has all its vertices there. The product runs in float32 (half the
    # memory traffic of the largest array). Its rounding is below 6 float32 ulps of
    # |n|·|q| + |d| per value, and the radius's below 2 √3 ulps of the largest coordinate, so
    # ``slack``, 64 ulps of the largest coordinate or offset, keeps the sphere test from ever
    # dropping a pair the vertex test keeps.
    centre = rec.mean(axis=1)
    radius = np.sqrt(np.max(np.sum((rec - centre[:, None]) ** 2, axis=2), axis=1))
    front = np.concatenate([sign[:, None] * n, (sign * d)[:, None]], axis=1)  # (C, 4), light side positive
    stacked = np.concatenate([front[:, None], planes], axis=1).reshape(-1, 4)  # (4C, 4)
    magnitude = 1.0 + max(float(np.abs(rec).max()), float(np.abs(stacked[:, 3]).max()))
    slack = 64 * float(np.finfo(np.float32).eps) * magnitude
    homogeneous = np.concatenate([centre, np.ones((len(rec), 1))], axis=1).T.astype(np.float32)
    value = (stacked.astype(np.float32) @ homogeneous).reshape(len(cas), 4, len(rec))
    reach = (radius + slack).astype(np.float32)
    maybe = value[:, 0] < eps + reach  # some point of the sphere behind (or on) the caster's plane
    for k in (1, 2, 3):  # no side plane with the whole sphere outside
        maybe &= value[:, k] >= -(eps + reach)
    ci, ri = np.nonzero(maybe)
    # Stage 2: the vertex test on the pairs left (the definition above).
    v = rec[ri]  # (N, 3, 3)
    dist = dot3(front[ci, None, :3], v) + front[ci, 3, None]
    behind = (dist < eps).any(axis=1)
    side = dot3(planes[ci, :, None, :3], v[:, None]) + planes[ci, :, 3][:, :, None]
    outside = (side < -eps).all(axis=2).any(axis=1)
    keep = behind & ~outside
    return np.stack([ri[keep], ci[keep] + c0], axis=1)


def fragment_triangles(rec: np.ndarray, cas: np.ndarray, light_h: np.ndarray, eps: float,
                       clipper: str = "compiled", progress: Callable[[int, int], None] | None = None,
                       memory_limit: int | None = None, threads: int | None = None) -> FragmentTriangles:
    """Every receiver triangle (R, 3, 3) clipped against the shadow of every caster triangle
    (C, 3, 3) from ``light_h``: the bulk culling (:func:`candidate_pairs`) a run of casters at a
    time, each run's pairs clipped ``CLIP_BATCH`` at a time, so the pairs are never all held;
    the fragments are fan-triangulated in pair order.

    ``clipper='compiled'`` (the default) culls and clips each run of casters in one call of
    :func:`shadowlab.geometry.compiled_clipping.fragment_run`; ``'batch'`` uses
    :func:`candidate_pairs` and :func:`shadowlab.geometry.batch_clipping.shadow_fragments`;
    both share the runs of casters among ``threads`` threads (default: the cores this process
    may use; numpy and the compiled kernel work outside the GIL) — the result does not depend
    on how many; ``'scalar'``
    runs the one-pair :func:`~shadowlab.geometry.polygon_clipping.shadow_fragment` in a Python
    loop, on one thread (the reference: kept for tests and before/after experiments).
    ``progress(done, total)`` is called as the casters are done. The fragments may take at most
    ``memory_limit`` bytes (default: ``MEMORY_SHARE`` of the memory available now); beyond it a
    :class:`TechniqueError` says so."""
    if clipper not in CLIPPERS:
        raise ValueError(f"clipper must be one of {', '.join(CLIPPERS)}, not {clipper!r}")
    if memory_limit is None:
        available = memory.available_bytes()
        memory_limit = int(MEMORY_SHARE * available) if available else None
    light_h = np.asarray(light_h, np.float64)
    threads = 1 if clipper == "scalar" else max(1, threads or len(os.sched_getaffinity(0)))
    step = max(1, PAIR_TESTS_PER_STEP // max(1, len(rec)))
    if threads > 1:  # at least two runs a thread, so that the threads finish together
        step = max(1, min(step, -(-len(cas) // (2 * threads))))
    starts = range(0, len(cas), step)

    if clipper == "compiled":
        culling = _CompiledCulling(rec, cas, light_h, eps)

    def one_run(c0: int):
        if clipper == "compiled":
            return (c0,) + culling.run(c0, min(c0 + step, len(cas)))
        found = candidate_pairs(rec, cas, light_h, eps, slice(c0, c0 + step))
        tris, owners, fragments = [], [], 0
        for b0 in range(0, len(found), CLIP_BATCH):
            batch = found[b0:b0 + CLIP_BATCH]
            t, row, n = _clip(rec, cas, batch, light_h, eps, clipper)
            tris.append(t)
            owners.append(batch[row, 0])
            fragments += n
        return c0, len(found), tris, owners, fragments

    tris, owners = [], []
    pairs = fragments = held = 0
    with ThreadPoolExecutor(max_workers=threads) as pool:
        for c0, n_pairs, t, o, n_frag in (pool.map(one_run, starts) if threads > 1 else map(one_run, starts)):
            pairs += n_pairs
            fragments += n_frag
            tris += t
            owners += o
            held += sum(len(x) for x in t) * BYTES_PER_FRAGMENT_TRIANGLE
            if memory_limit is not None and held > memory_limit:
                raise TechniqueError(
                    f"shadow_polygons: the exact shadow fragments outgrew {memory_limit / 2**30:.1f} GiB "
                    f"({MEMORY_SHARE:.0%} of the memory available at setup) after {pairs} candidate pairs; "
                    f"exact shadow polygons are meant for polyhedral scenes of modest size")
            if progress is not None:
                progress(min(c0 + step, len(cas)), len(cas))
    triangles = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
    receiver = np.concatenate(owners) if owners else np.zeros(0, np.int64)
    return FragmentTriangles(triangles, receiver, pairs, fragments)


class _CompiledCulling:
    """What the compiled kernel (:func:`shadowlab.geometry.compiled_clipping.fragment_run`)
    needs once per light: the casters' planes and frusta, the receivers' spheres."""

    def __init__(self, rec, cas, light_h, eps):
        from ...geometry import compiled_clipping as cc

        self.kernel = cc.fragment_run
        self.rec, self.cas = np.ascontiguousarray(rec, np.float64), np.ascontiguousarray(cas, np.float64)
        self.light_h, self.eps = np.ascontiguousarray(light_h, np.float64), float(eps)
        if len(rec) == 0 or len(cas) == 0:
            return
        n, d = triangle_planes(cas)
        sign = np.where(n @ light_h[:3] + d * light_h[3] >= 0, 1.0, -1.0)  # as in candidate_pairs
        self.front = np.ascontiguousarray(np.concatenate([sign[:, None] * n, (sign * d)[:, None]], axis=1))
        self.sides = np.ascontiguousarray(side_planes(cas, light_h))
        self.centre = rec.mean(axis=1)
        radius = np.sqrt(np.max(np.sum((rec - self.centre[:, None]) ** 2, axis=2), axis=1))
        # The sphere test in float64: its values round by a few ulps of |n|·|q| + |d|, the
        # radius by a few ulps of the largest coordinate; 64 ulps of the largest magnitude
        # keeps it from dropping a pair the vertex test keeps (see candidate_pairs).
        magnitude = 1.0 + max(float(np.abs(rec).max()), float(np.abs(self.front[:, 3]).max()),
                              float(np.abs(self.sides[..., 3]).max()))
        self.reach = radius + 64 * float(np.finfo(np.float64).eps) * magnitude

    def run(self, c0: int, c1: int):
        """Casters c0..c1: (pairs, [fan triangles], [their receivers], fragments)."""
        if len(self.rec) == 0 or len(self.cas) == 0:
            return 0, [], [], 0
        tris, owner, pairs, fragments = self.kernel(self.rec, self.cas, self.front, self.sides, self.centre,
                                                    self.reach, self.light_h, self.eps, c0, c1)
        return pairs, [tris], [owner], fragments


def _clip(rec, cas, batch, light_h, eps, clipper):
    """Fragments of the (receiver, caster) pairs ``batch`` (N, 2), fan-triangulated: triangles
    (T, 3, 3), the batch row (T,) of each, and how many pairs gave a fragment."""
    if clipper == "batch":
        frags = bc.shadow_fragments(bc.full(rec[batch[:, 0]]), bc.full(cas[batch[:, 1]]), light_h, eps)
        t, row = bc.fan_triangles(frags)
        return t, row, int(np.count_nonzero(frags.count))
    t, row = [], []
    for k, (r, c) in enumerate(batch):
        frag, _ = pc.shadow_fragment(rec[r], cas[c], light_h, eps)
        if len(frag):
            t.append(pc.triangulate(frag))
            row.append(np.full(len(frag) - 2, k))
    t_all = np.concatenate(t) if t else np.zeros((0, 3, 3))
    return t_all, (np.concatenate(row) if row else np.zeros(0, np.int64)), len(t)


def _progress_bar(name: str, after_s: float = 2.0) -> Callable[[int, int], None]:
    """A ``progress(done, total)`` callback that shows a bar on a terminal once the work has
    taken ``after_s`` seconds (tqdm's ``delay``); silent when stderr is not a terminal."""
    from tqdm import tqdm

    state = {}

    def progress(done: int, total: int) -> None:
        bar = state.get("bar")
        if bar is None:
            bar = state["bar"] = tqdm(total=total, desc=f"{name}: clipping", unit="caster", leave=False,
                                      delay=after_s, disable=not sys.stderr.isatty(), file=sys.stderr)
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return progress
