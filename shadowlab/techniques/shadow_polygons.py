"""Exact object-space shadow polygons for static lights (Atherton, Weiler & Greenberg 1978).

For every convex receiver polygon (a receiver triangle) and every convex caster polygon (a
caster triangle; only the light-facing ones of a closed mesh, whose shadows already make up the
whole shadow), :func:`shadowlab.geometry.polygon_clipping.shadow_fragment` computes the receiver's
shadowed part exactly, in float64, with the tolerance ``epsilon`` (× the scene's size). Pairs are
culled first, all pairs at once in numpy: the light must see the receiver, some receiver vertex
must lie behind the caster's plane, and no side plane of the caster's frustum may have the whole
receiver outside. The fragments are computed once per light (``setup``: the preprocessing,
timed separately as ``preprocess_ms``) and drawn each frame as geometry (``render``), each
fragment only on the pixels where the G-buffer saw its own receiver triangle.

Several lights: for each receiver triangle, only the ``max_lights`` lights with the largest
unshadowed contribution (λ · N·L · luminance at its centroid) get fragments; the others leave it
lit, and the metrics show what dropping them costs (``dropped_faces`` counts them).
"""
from __future__ import annotations

import time

import numpy as np

from .. import gl, glstate
from ..geometry import adjacency as adj
from ..geometry import polygon_clipping as pc
from ..geometry.frusta import side_planes
from ..geometry.triangles import triangle_normals, triangle_planes
from ..glstate import PassState
from .base import Param, Technique, TechniqueError

#: Candidate pairs above which the technique refuses (a Python loop per pair: meant for
#: polyhedral scenes of modest size, the static-light trade-off it exists to show).
MAX_PAIRS = 200_000
_LUMA = np.array([0.2126, 0.7152, 0.0722])


class ShadowPolygons(Technique):
    """Precomputed exact shadow fragments (convex clipping) rendered as geometry."""

    name = "shadow_polygons"
    summary = "exact object-space shadow polygons (convex clipping), precomputed per static light"
    PASSES = ("draw",)
    PARAMS = {
        "epsilon": Param(1e-9, "geometric tolerance of every predicate, relative to the scene's size",
                         min=0.0, max=1e-1),
        "max_lights": Param(8, "per receiver face, the lights that get shadows (largest contribution first)",
                            min=1, max=8),
    }

    def setup(self, frame, light_index: int) -> None:
        """Compute the fragments for this light (the preprocessing) and upload them."""
        t0 = time.perf_counter()
        self.frame = frame
        scene = frame.scene
        light = scene.lights[light_index]
        light_h = light.homogeneous()
        eps = self.epsilon * scene.extent()
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
                keep = self._kept_faces(obj, light_index)
                self.dropped_faces += int((~keep).sum())
                receivers.append(obj.triangles[keep])
                receiver_ids.append(starts[i] + np.flatnonzero(keep))
        rec_tris = np.concatenate(receivers) if receivers else np.zeros((0, 3, 3))
        rec_ids = np.concatenate(receiver_ids) if receiver_ids else np.zeros(0, np.int64)
        pairs = self._candidate_pairs(rec_tris, caster_tris, light_h, eps)
        if len(pairs) > MAX_PAIRS:
            raise TechniqueError(f"{self.name}: {len(pairs)} receiver/caster polygon pairs to clip (limit "
                                 f"{MAX_PAIRS}); exact shadow polygons are meant for polyhedral scenes of modest size")
        verts, ids = [], []
        self.fragment_count = 0
        for r, c in pairs:
            frag, _ = pc.shadow_fragment(rec_tris[r], caster_tris[c], light_h, eps)
            if len(frag):
                tris = pc.triangulate(frag)
                verts.append(tris.reshape(-1, 3))
                ids.append(np.full(len(tris) * 3, rec_ids[r], np.int32))
                self.fragment_count += 1
        self.pairs_clipped = len(pairs)
        vertices = np.concatenate(verts).astype("f4") if verts else np.zeros((0, 3), "f4")
        triangle_ids = np.concatenate(ids) if ids else np.zeros(0, np.int32)
        self.preprocess_ms = 1e3 * (time.perf_counter() - t0)
        ctx = frame.ctx
        self.prog = gl.program("shadow_fragments.glsl")
        self.prog["u_view_proj"].write(gl.mat_bytes(frame.view_projection))
        gl.set_uniforms(self.prog, {"u_ids": 0, "u_shadowed": 0.0})
        self.count = len(vertices)
        self.vbo = ctx.buffer(vertices.tobytes() if len(vertices) else b"\0" * 12)
        self.ibo_ids = ctx.buffer(triangle_ids.tobytes() if len(triangle_ids) else b"\0" * 4)
        self.vao = ctx.vertex_array(self.prog, [(self.vbo, "3f", "in_pos"), (self.ibo_ids, "1i", "in_triangle")])
        self.vis_tex = ctx.texture((frame.width, frame.height), 1, dtype="f4")
        self.vis_fbo = gl.framebuffer([self.vis_tex])

    def _kept_faces(self, obj, light_index: int) -> np.ndarray:
        """Bool per face: this light is among the face's ``max_lights`` strongest lights."""
        lights = self.frame.scene.lights
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
        rank = (contrib > contrib[light_index]).sum(axis=0)  # lights strictly stronger
        return rank < self.max_lights

    @staticmethod
    def _candidate_pairs(rec: np.ndarray, cas: np.ndarray, light_h: np.ndarray, eps: float,
                         chunk: int = 256) -> np.ndarray:
        """(receiver, caster) index pairs whose shadow and receiver can overlap, culled in bulk
        and conservatively: some receiver vertex behind (or on) the caster's plane, and no side
        plane of the caster's frustum with every receiver vertex outside it."""
        if len(rec) == 0 or len(cas) == 0:
            return np.zeros((0, 2), np.int64)
        n, d = triangle_planes(cas)
        sign = np.where(n @ light_h[:3] + d * light_h[3] >= 0, 1.0, -1.0)  # light on the positive side
        planes = side_planes(cas, light_h)  # (C, 3, 4): the frustum's side planes, inward
        sn, sd = planes[..., :3], planes[..., 3]
        out = []
        for c0 in range(0, len(cas), chunk):
            c = slice(c0, c0 + chunk)
            dist = sign[c, None, None] * (np.einsum("ck,rvk->crv", n[c], rec) + d[c, None, None])
            behind = (dist < eps).any(axis=2)  # (C, R)
            side = np.einsum("cek,rvk->cerv", sn[c], rec) + sd[c][:, :, None, None]
            outside = (side < -eps).all(axis=3).any(axis=1)  # (C, R): all vertices outside one plane
            ci, ri = np.nonzero(behind & ~outside)
            out.append(np.stack([ri, ci + c0], axis=1))
        return np.concatenate(out)

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

    def visibility(self) -> np.ndarray:
        """Binary visibility: 0 inside a fragment on its own receiver triangle."""
        return gl.read_texture(self.vis_tex, 1)[..., 0]

    def stats(self) -> dict:
        """Preprocessing time, pairs clipped, fragments and triangles produced, faces dropped."""
        return {"preprocess_ms": self.preprocess_ms, "pairs_clipped": self.pairs_clipped,
                "polygons": self.fragment_count, "fragment_triangles": self.count // 3,
                "dropped_faces": self.dropped_faces}

    def release(self) -> None:
        """Free GL objects."""
        gl.park()
        for obj in (self.vao, self.vbo, self.ibo_ids, self.prog, self.vis_fbo, self.vis_tex):
            obj.release()
