"""Exact object-space shadow polygons for static lights (Atherton, Weiler & Greenberg 1978).

For every convex receiver polygon (a receiver triangle) and every convex caster polygon (a
caster triangle; only the light-facing ones of a closed mesh, whose shadows already make up the
whole shadow), the receiver's shadowed part is computed exactly, in float64, with the tolerance
``epsilon`` (× the scene's size): :func:`shadowlab.geometry.clipping.scalar.shadow_fragment`
defines it for one pair. Pairs are culled first (:func:`candidate_pairs` defines a candidate):
some receiver vertex must lie behind the caster's plane, and no side plane of the caster's
frustum may have the whole receiver outside. Three back-ends give the same fragments bit for
bit (``fragment_triangles(clipper=...)``): by default culling and clipping run in one compiled
loop (:mod:`shadowlab.geometry.clipping.compiled`, numba); ``'batch'`` culls with dense matrix
tests and clips tens of thousands of pairs at once in numpy
(:mod:`shadowlab.geometry.clipping.batch`); ``'scalar'`` loops over the one-pair clipper (the
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
unshadowed contribution (λ · N·L · luminance at its centroid; lights contributing nothing there
are not among them) get fragments; the others leave it
lit, and the metrics show what dropping them costs (``dropped_faces`` counts them). This is the
seed's rule, which every technique now takes as a shadow budget (``budget=K,select=face``,
:mod:`shadowlab.lighting.selection`; a test holds the two selections equal).
"""
from __future__ import annotations

import sys
import time
from typing import Callable

import numpy as np

from ...gpu import glstate, memory, programs
from ...geometry import adjacency as adj
from ...geometry.clipping import CLIPPERS, FragmentMemoryError, fragment_triangles  # noqa: F401  (CLIPPERS: the back-ends)
from ...gpu.glstate import PassState
from ...lighting.selection import face_contributions, top_k_with_ties
from ..base import FIRST, SUM, Param, PlotStyle, Technique, TechniqueError, TuneRange

#: Share of the memory available at setup that the fragments' geometry may take: beyond it the
#: technique stops with an error rather than push the machine into swap.
MEMORY_SHARE = 0.5


class ShadowPolygons(Technique):
    """Precomputed exact shadow fragments (convex clipping) rendered as geometry."""

    name = "shadow_polygons"
    summary = "exact object-space shadow polygons (convex clipping), precomputed per static light"
    PASSES = ("draw",)
    STYLE = PlotStyle("#9467bd", "D")
    STATS = {"preprocess_ms": SUM, "compile_ms": SUM, "pairs_clipped": SUM, "polygons": SUM,
             "fragment_triangles": SUM, "dropped_faces": FIRST}
    READS = frozenset({"ids"})
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
        from ...geometry.clipping import compiled as compiled_clipping

        self.compile_ms = compiled_clipping.warm()
        t0 = time.perf_counter()
        light_h = slot.light.homogeneous()
        eps = self.epsilon * frame.scene.extent()
        rec_tris, rec_ids, caster_tris = self.polygons(frame, slot)
        available = memory.available_bytes()
        try:
            work = fragment_triangles(rec_tris, caster_tris, light_h, eps, progress=_progress_bar(self.name),
                                      memory_limit=int(MEMORY_SHARE * available) if available else None)
        except FragmentMemoryError as exc:
            raise TechniqueError(f"shadow_polygons: {exc} ({MEMORY_SHARE:.0%} of the memory available at setup); "
                                 f"exact shadow polygons are meant for polyhedral scenes of modest size") from None
        self.pairs_clipped = work.pairs
        self.fragment_count = work.fragments
        vertices = work.triangles.reshape(-1, 3).astype("f4")
        triangle_ids = np.repeat(rec_ids[work.receiver].astype(np.int32), 3)
        self.preprocess_ms = 1e3 * (time.perf_counter() - t0)
        ctx = frame.ctx
        self.prog = self.program("shadow_fragments.glsl")
        self.prog["u_view_proj"].write(programs.mat_bytes(frame.view_projection))
        programs.set_uniforms(self.prog, {"u_shadowed": 0.0})
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
        contrib = face_contributions(lights, obj.triangles)  # (lights, faces): λ · |N·L| · luminance at centroids
        return top_k_with_ties(contrib, self.max_lights)[slot.index]  # the seed's rule, as a budget's face policy

    def render(self) -> None:
        """Draw the precomputed fragments over the G-buffer."""
        from OpenGL import GL

        with self.timed_pass("draw"):
            self.vis_fbo.use()
            glstate.apply(PassState())
            GL.glClearBufferfv(GL.GL_COLOR, 0, (1.0, 0.0, 0.0, 0.0))
            self.bind_gbuffer(self.prog)
            if self.count:
                self.vao.render(vertices=self.count)

    def stats(self) -> dict:
        """Preprocessing time (and the kernel's one-time load or compile), pairs clipped,
        fragments and triangles produced, faces dropped."""
        return {"preprocess_ms": self.preprocess_ms, "compile_ms": self.compile_ms, "pairs_clipped": self.pairs_clipped,
                "polygons": self.fragment_count, "fragment_triangles": self.count // 3,
                "dropped_faces": self.dropped_faces}


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
