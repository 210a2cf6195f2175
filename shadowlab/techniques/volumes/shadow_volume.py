"""Stencil shadow volumes (Crow 1977; Heidmann 1991), z-pass, z-fail or both, with real 8-bit stencil.

Per light and caster: silhouette edges from edge adjacency (``silhouette=cpu``: numpy over the
edge table of :mod:`shadowlab.geometry.adjacency`; ``silhouette=gpu``: a geometry shader over
``GL_TRIANGLES_ADJACENCY``), extruded to infinity as w = 0 points. Counting happens in the
stencil of the G-buffer's depth-stencil attachment, two-sided (``glStencilOpSeparate``) with
wrapping increments and decrements; colour and depth writes are off. A pixel is lit where
its count is 0.

- ``mode=zpass``: count volume faces in front of the surface (front +1, back −1). Wrong when
  the camera is inside a volume or the near plane cuts one (hard case SV1).
- ``mode=zfail`` (Carmack 2000; Everitt & Kilgard 2002, "Practical and Robust Stenciled
  Shadow Volumes"): count faces behind the surface (back +1, front −1 on depth fail), which
  needs closed volumes: near caps (the light-facing faces) and far caps (the same, extruded).
- ``mode=auto`` (the default; Everitt & Kilgard 2002, §5): per caster, z-fail only where its
  volume may contain a point of the near-plane rectangle — conservatively, where the caster's
  bounding box meets the light's "occlusion pyramid", the convex hull of the light and that
  rectangle (for lights at infinity, the rectangle swept towards the light) — and z-pass, with
  no caps, for the others. Counts of different casters add in the stencil, and each method
  gives its own caster's count exactly, so the two mix in one stencil buffer; the mask is
  z-fail's on every evaluated pixel (they differ only on pixels that show no surface, which
  nothing reads), at about z-pass's cost when the camera is outside the volumes. ``stats()``
  says how many casters, and triangles, went each way.
- ``far=infinite``: the camera projection with its far plane at infinity (Everitt & Kilgard,
  with their ε so that w = 0 points stay inside the clip volume); ``far=clamp``: the finite
  projection with ``GL_DEPTH_CLAMP`` (NV_depth_clamp), which also drops the near plane: it is
  restored as clip distance 0, and the depth pre-pass runs under the same clamp and clipping as
  the caps so that they tie with it bit for bit (see shadowlab/techniques/volumes/shadow_volume_common.glsl);
  ``far=finite``: neither — far caps and sides are clipped and z-fail loses shadow (hard case
  SV2, kept to reproduce it on purpose: with ``mode=zfail``, or in auto's z-fail casters).

Near caps coincide with the casters' own lit faces. The technique renders its own depth
pre-pass (in ``setup``, untimed: it is primary visibility under the projection it needs) with
the very program and vertex data that draw the caps, so a cap's depth equals the surface's
bit for bit and a lit face is never counted inside its own volume (no acne). Caps that must be
turned round (two-sided mode) keep their vertex order and are drawn with the stencil
operations of the other face instead, for the same reason.

Open meshes, non-manifold edges, inconsistent winding and a light inside a closed caster are
detected per object and handled with the two-sided multiplicity scheme (see
:mod:`shadowlab.geometry.adjacency`); the run notes say which objects needed it. The GPU path cannot
describe non-manifold edges in an adjacency buffer: such objects fall back to the CPU path,
and the notes say so.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...gpu import gl, glstate, programs
from ...geometry import adjacency as adj
from ...geometry import transforms as tf
from ...gpu.glstate import PassState, Stencil
from ..base import MAX, SUM, Param, PlotStyle, Technique

#: Everitt & Kilgard's ε for the infinite projection: keeps w = 0 points just inside the far plane.
INFINITE_EPSILON = 2.4e-7
#: Smallest size of the per-frame vertex and index buffers (bytes): the silhouette changes size
#: from frame to frame, and this headroom keeps small changes from reallocating GL buffers.
MIN_DYNAMIC_BUFFER_BYTES = 1 << 16
#: u_stage values of shadowlab/techniques/volumes/shadow_volume_gs.glsl (STAGE_VOLUME, STAGE_FLIPPED_CAPS there).
GS_STAGE_VOLUME, GS_STAGE_FLIPPED_CAPS = 1, 2


@dataclass
class CasterPlan:
    """How one caster object is drawn for the current light."""

    index: int
    table: adj.EdgeTable
    two_sided: bool
    path: str  # 'cpu' or 'gpu'
    first_triangle: int  # offset of the object's triangles in the frame's vertex order
    zfail: bool = True  # counted with z-fail (and caps); False: z-pass, no caps


class ShadowVolume(Technique):
    """Stencil shadow volumes with CPU or GPU silhouettes, z-pass, z-fail or per-caster auto, three far-plane modes."""

    name = "shadow_volume"
    summary = "stencil shadow volumes (z-pass / z-fail, infinite far plane or depth clamp)"
    PARAMS = {
        "mode": Param("auto", "stencil counting: zpass (Heidmann), zfail (Carmack; Everitt & Kilgard), or auto "
                              "(per caster: z-fail where its volume may reach the near-plane rectangle, else "
                              "z-pass; z-fail's mask at about z-pass's cost)",
                      choices=("zpass", "zfail", "auto")),
        "silhouette": Param("cpu", "silhouette extraction: cpu (numpy edge table) or gpu (geometry shader)",
                            choices=("cpu", "gpu")),
        "far": Param("infinite", "far plane: infinite projection, clamp (GL_DEPTH_CLAMP), or finite (SV2 artefact)",
                     choices=("infinite", "clamp", "finite")),
    }
    #: Counts in the G-buffer's stencil, after its own depth pre-pass into the same attachment.
    WRITES = frozenset({"depth_stencil"})
    PASSES = ("silhouette", "volume", "caps", "count")
    STYLE = PlotStyle("#d62728", "s")
    STATS = {"silhouette_edges": SUM, "stencil_peak_count": MAX, "zpass_casters": SUM, "zfail_casters": SUM,
             "zpass_caster_triangles": SUM, "zfail_caster_triangles": SUM, "volume_fragments": SUM,
             "stencil_updates": SUM, "fill_per_pixel": SUM, "volume_triangles": SUM, "pixel_ops": SUM}
    LIGHT_SAMPLED = True  # light_samples=N: averaged over N points of an area light (shadowlab.measurement.light_sampling)

    # ------------------------------------------------------------------ setup
    def setup(self, frame, slot) -> None:
        """Plan each caster, build programs and buffers, and render the depth pre-pass."""
        ctx = frame.ctx
        if self.far == "infinite":
            cam = frame.camera
            self.proj = tf.perspective_infinite(cam.fov_y, frame.width / frame.height, cam.near, INFINITE_EPSILON)
        else:
            self.proj = frame.projection
        self.matrices = {"u_view": programs.mat_bytes(frame.view), "u_proj": programs.mat_bytes(self.proj)}
        starts = np.cumsum([0] + [len(o.faces) for o in frame.scene.objects])
        self.plans: list[CasterPlan] = []
        for i, obj in enumerate(frame.scene.objects):
            if not obj.casts:
                continue
            table = obj.edges
            inside = (not self.light.at_infinity and table.closed
                      and adj.light_inside_closed_mesh(table, self.light.position))
            two_sided = not table.closed or inside
            path = self.silhouette
            if two_sided:
                why = "the light is inside it" if inside else table.describe()
                self.notes.append(f"object '{obj.name}': {why}; volumes use the two-sided multiplicity scheme")
            if path == "gpu" and not table.manifold:
                self.notes.append(f"object '{obj.name}': non-manifold edges cannot be described to the geometry "
                                  f"shader; its silhouette falls back to the CPU path")
                path = "cpu"
            self.plans.append(CasterPlan(i, table, two_sided, path, int(starts[i])))
        self._choose_methods(frame)
        # Depth clamp also turns off clipping at the near plane: the volume programs then restore
        # it as clip distance 0 (see shadowlab/techniques/volumes/shadow_volume_common.glsl).
        self.defines = {"NEAR_CLIP": 1} if self.far == "clamp" else None
        self.clip_distances = 1 if self.far == "clamp" else 0
        self.vs_prog = self.volume_program()
        for key, val in self.matrices.items():
            self.vs_prog[key].write(val)
        programs.set_uniforms(self.vs_prog, self.light.uniforms())
        # The scene's triangles twice: as surface points (pre-pass, near caps) and extruded to
        # infinity (far caps); caps are then drawn by index, with no per-frame vertex copies.
        corners = frame.triangles.reshape(-1, 3)
        self.scene4 = self.own(ctx.buffer(_flagged(corners, 0.0).tobytes()))
        self.scene_ext = self.own(ctx.buffer(_flagged(corners, 1.0).tobytes()))
        self.scene4_vao = self.own(ctx.vertex_array(self.vs_prog, [(self.scene4, "3f 1f", "in_pos", "in_extrude")]))
        self.volume_buffers: dict[bool, tuple] = {}  # zfail flag -> (vbo, vao) of CPU-path volumes
        self.indexed: dict[str, tuple] = {}
        self.gpu, self.gs_prog = {}, None
        if any(p.path == "gpu" for p in self.plans):
            self.gs_prog = self.program("shadow_volume_gs.glsl", defines=self.defines)
            programs.set_uniforms(self.gs_prog, self.light.uniforms())
            for key, val in self.matrices.items():
                self.gs_prog[key].write(val)
            programs.set_uniforms(self.gs_prog, {"u_two_sided": False, "u_caps": True,
                                                 "u_far_cap": not self.light.at_infinity})
            for p in self.plans:
                if p.path == "gpu":
                    vbo = self.own(ctx.buffer(p.table.vertices.astype("f4").tobytes()))
                    ibo = self.own(ctx.buffer(p.table.adjacency_indices().tobytes()))
                    vao = self.own(ctx.vertex_array(self.gs_prog, [(vbo, "3f", "in_pos")], index_buffer=ibo,
                                                    index_element_size=4))
                    self.gpu[p.index] = (vbo, ibo, vao)
        self.vis_tex, self.target = self.visibility_target((frame.width, frame.height),
                                                           share_depth_stencil=frame.depth_stencil_for(self))
        self.const_prog = self.program("constant.glsl")
        self.quad = self.fullscreen_quad(self.const_prog)
        self._depth_prepass()

    def volume_program(self):
        """The CPU path's program (depth pre-pass, caps, CPU-path volumes). A subclass may return
        another with the same vertex and geometry stages (hierarchical_volume: its own fragment
        stage), so that the pre-pass and every cap it draws still tie bit for bit."""
        return self.program("shadow_volume.glsl", defines=self.defines)

    def _depth_prepass(self) -> None:
        """Scene depth under this technique's projection, drawn by the CPU path's program; the GPU
        path's geometry shader takes its caps from the same shared vertex stage."""
        self.target.use()
        # The same clipping and depth clamp as the volume passes: a near cap must tie with the
        # surface it lies on bit for bit, and a triangle clipped differently (depth clamp drops
        # the near plane) is rasterised from other vertices and rounds differently.
        glstate.apply(PassState(depth_test=True, depth_func="<", depth_write=True, color_write=False,
                                depth_clamp=self.far == "clamp", clip_distances=self.clip_distances))
        self.target.clear_depth_stencil()
        # One pre-pass program for both silhouette paths (they share the vertex stage): their
        # volumes then meet the same depths, also where a side starts on a surface (contacts).
        self.scene4_vao.render()
        gl.check_errors("shadow volume depth pre-pass")

    # ------------------------------------------------------------------ z-pass or z-fail per caster
    def _choose_methods(self, frame) -> None:
        """Set each plan's counting method. ``mode=auto``: z-fail only for the casters whose
        volume may contain a point of the near-plane rectangle (where z-pass miscounts)."""
        if self.mode != "auto":
            for p in self.plans:
                p.zfail = self.mode == "zfail"
            return
        if not self.plans:
            return
        objs = frame.scene.objects
        bounds = np.stack([objs[p.index].bounds() for p in self.plans])
        needs = volumes_may_reach_near_plane(bounds, near_plane_quad(frame), self.light, frame.scene.extent())
        for p, zfail in zip(self.plans, needs):
            p.zfail = bool(zfail)
        nz = int(np.sum(needs))
        if nz:
            names = ", ".join(f"'{objs[p.index].name}'" for p in self.plans if p.zfail)
            self.notes.append(f"mode=auto: z-fail for {nz} of {len(self.plans)} casters (their volumes may "
                              f"reach the near plane: {names}); z-pass for the others")

    def _methods(self) -> list[bool]:
        """The counting methods in use, as ``zfail`` flags, z-pass first."""
        return [z for z in (False, True) if any(p.zfail == z for p in self.plans)]

    # ------------------------------------------------------------------ per-frame work
    def cpu_volume_geometry(self) -> dict:
        """Per counting method in use (``zfail`` flag → arrays): volume vertices (sides and far
        caps, vec4) and near-cap, flipped-cap and far-cap triangle indices for the CPU path
        (the cap arrays are empty for z-pass)."""
        out = {}
        for zfail in self._methods():
            verts, caps, flipped, far = [], [], [], []
            for p in self.plans:
                if p.path != "cpu" or p.zfail != zfail:
                    continue
                t = p.table
                lit = adj.facing(t, self.light)
                sil = adj.silhouette_edges(t, lit, p.two_sided)
                a, b = _flagged(t.vertices[sil[:, 0]], 0.0), _flagged(t.vertices[sil[:, 1]], 0.0)
                ae, be = a.copy(), b.copy()
                ae[:, 3] = be[:, 3] = 1.0
                # Triangles (b, a, a') and (b, a', b'): the same as the geometry shader emits.
                verts.append(np.stack([b, a, ae, b, ae, be], axis=1).reshape(-1, 4))
                if zfail:
                    faces_lit = np.flatnonzero(lit)
                    faces_dark = np.flatnonzero(~lit) if p.two_sided else np.zeros(0, np.int64)
                    caps.append(faces_lit + p.first_triangle)
                    flipped.append(faces_dark + p.first_triangle)
                    if not self.light.at_infinity:  # far cap: the light-facing orientation, reversed
                        far.append(_triangle_indices(faces_lit + p.first_triangle, (0, 2, 1)))
                        far.append(_triangle_indices(faces_dark + p.first_triangle))
            out[zfail] = pack_volume_geometry(verts, caps, flipped, far)
        return out

    @staticmethod
    def _counting(zfail: bool, flipped: bool = False) -> Stencil:
        """The stencil counting of one method; ``flipped`` swaps the faces' operations (caps of
        unlit faces drawn in their stored order in two-sided mode)."""
        if not zfail:  # Heidmann: on depth pass, front +1, back -1
            front, back = ("keep", "keep", "incr_wrap"), ("keep", "keep", "decr_wrap")
        else:  # Everitt & Kilgard: on depth fail, back +1, front -1
            front, back = ("keep", "decr_wrap", "keep"), ("keep", "incr_wrap", "keep")
        if flipped:
            front, back = back, front
        return Stencil("always", 0, 0xFF, front, back)

    def _volume_state(self, zfail: bool, depth_func: str = "<", stencil: bool = True) -> PassState:
        """The state every volume draw runs under: depth test without depth writes, no colour,
        depth clamp and the near clip distance for ``far=clamp``, stencil counting of ``zfail``."""
        return PassState(depth_test=True, depth_func=depth_func, depth_write=False, color_write=False,
                         depth_clamp=self.far == "clamp", clip_distances=self.clip_distances,
                         stencil=self._counting(zfail) if stencil else None)

    def _dynamic(self, store: dict, key, nbytes: int, make_vao) -> tuple:
        """(buffer, vertex array) kept in ``store[key]`` and re-filled each frame: a dynamic buffer
        of at least ``nbytes`` and ``make_vao(buffer)``, both owned; replaced by larger ones
        when ``nbytes`` outgrows it."""
        entry = store.get(key)
        if entry is None or entry[0].size < nbytes:
            if entry is not None:
                self.free(entry[1], entry[0])
            buf = self.own(self.frame.ctx.buffer(reserve=max(nbytes, MIN_DYNAMIC_BUFFER_BYTES), dynamic=True))
            entry = store[key] = (buf, self.own(make_vao(buf)))
        return entry

    def _draw_indexed(self, key: str, vbo, idx: np.ndarray) -> None:
        """Triangles of ``vbo`` (the scene's corners, flagged) picked by vertex indices; the index
        buffer and its vertex array are kept per ``key`` and only re-filled each frame."""
        data = idx.astype("i4").tobytes()
        ibo, vao = self._dynamic(self.indexed, key, len(data), lambda buf: self.frame.ctx.vertex_array(
            self.vs_prog, [(vbo, "3f 1f", "in_pos", "in_extrude")], index_buffer=buf, index_element_size=4))
        ibo.write(data)
        vao.render(vertices=len(idx))

    def _draw_volumes(self, zfail: bool, volume, cap_idx, flip_idx, far_idx, counting: bool = True) -> None:
        """The volume geometry of the casters counted with ``zfail``, under that method's volume
        state already applied (used by render and stats); ``counting`` switches the stencil
        operations for flipped caps."""
        ctx = self.frame.ctx
        with self.timed_pass("volume"):
            if len(volume):
                vbo, vao = self._dynamic(self.volume_buffers, zfail, volume.nbytes, lambda buf: ctx.vertex_array(
                    self.vs_prog, [(buf, "3f 1f", "in_pos", "in_extrude")]))
                vbo.write(volume.tobytes())
                vao.render(vertices=len(volume))
            for p in self.plans:
                if p.path != "gpu" or p.zfail != zfail:
                    continue
                vao = self.gpu[p.index][2]
                self.gs_prog["u_two_sided"].value = p.two_sided
                self.gs_prog["u_caps"].value = zfail
                self.gs_prog["u_stage"].value = GS_STAGE_VOLUME
                vao.render(ctx.TRIANGLES_ADJACENCY)
                if p.two_sided and zfail:
                    if counting:
                        glstate.set_stencil(self._counting(zfail, flipped=True))
                    self.gs_prog["u_stage"].value = GS_STAGE_FLIPPED_CAPS
                    vao.render(ctx.TRIANGLES_ADJACENCY)
                    if counting:
                        glstate.set_stencil(self._counting(zfail))
        if not zfail:
            return
        with self.timed_pass("caps"):
            if len(far_idx):
                self._draw_indexed("far", self.scene_ext, far_idx)
            for key, idx, flipped in (("caps", cap_idx, False), ("flipped", flip_idx, True)):
                if len(idx):
                    if counting:
                        glstate.set_stencil(self._counting(zfail, flipped))
                    self._draw_indexed(key, self.scene4, idx)
            if counting:
                glstate.set_stencil(self._counting(zfail))

    def render(self) -> None:
        """Silhouettes (CPU path), stencil counting (z-pass casters, then z-fail casters, into
        the same stencil: counts of different casters add), then stencil → visibility."""
        from OpenGL import GL

        with self.timed_pass("silhouette", cpu=True):
            self._geometry = self.cpu_volume_geometry()
        with self.timed_pass("volume"):  # the stencil clear is the volume pass's first step
            self.target.use()
            glstate.apply(self._volume_state(zfail=True))  # stencil writes on, for the clear
            GL.glClearStencil(0)
            GL.glClear(GL.GL_STENCIL_BUFFER_BIT)
        for zfail, geometry in self._geometry.items():
            glstate.apply(self._volume_state(zfail))
            self._draw_volumes(zfail, *geometry)
        with self.timed_pass("count"):
            # Visibility: 0 everywhere, 1 where the count is 0.
            glstate.apply(PassState(depth_write=False, stencil=Stencil("==", 0, 0xFF)))
            GL.glClearBufferfv(GL.GL_COLOR, 0, (0.0, 0.0, 0.0, 0.0))
            self.const_prog["u_value"].value = 1.0
            self.quad.render()

    def work(self, counted: dict, stats: dict) -> dict:
        """Stencil updates of the volume passes (exact, from :meth:`stats`'s occlusion counts);
        the triangles of casters on the CPU silhouette path (``silhouette=cpu``, or a
        non-manifold caster's fallback under ``gpu``), tested for facing each render."""
        out = {"volume": {"stencil_updates": stats["stencil_updates"]}}
        objs = self.frame.scene.objects
        cpu = sum(len(objs[p.index].faces) for p in self.plans if p.path == "cpu")
        if cpu:
            out["silhouette"] = {"cpu_triangles": cpu}
        return out

    def stats(self) -> dict:
        """Silhouette edges, volume triangles, stencil fill and peak count (untimed extra passes),
        and how many casters (and their triangles) were counted with z-pass and with z-fail."""
        stencil = self.target.read_stencil().astype(np.int64)
        objs = self.frame.scene.objects
        out = {
            # Extruded edges (an edge of multiplicity m counts |m| times), on every path.
            "silhouette_edges": sum(len(adj.silhouette_edges(p.table, adj.facing(p.table, self.light), p.two_sided))
                                    for p in self.plans),
            "stencil_peak_count": int(np.max(np.minimum(stencil, 256 - stencil))),  # counts wrap modulo 256
            "zpass_casters": sum(not p.zfail for p in self.plans),
            "zfail_casters": sum(p.zfail for p in self.plans),
            "zpass_caster_triangles": sum(len(objs[p.index].faces) for p in self.plans if not p.zfail),
            "zfail_caster_triangles": sum(len(objs[p.index].faces) for p in self.plans if p.zfail),
        }
        # Fill: fragments of all volume geometry with the depth test ALWAYS (so no class is
        # missed), and those that update the stencil under the real depth test; the stencil
        # test is off, so the counts left by render() stay as they are.
        self.target.use()
        fragments = updates = prims = 0
        for zfail, geometry in self._geometry.items():
            fill = {}
            for name, func in (("volume_fragments", "always"), ("passed", "<")):
                glstate.apply(self._volume_state(zfail, func, stencil=False))
                q = gl.query("shadow_volume fill", samples=True, primitives=True)
                with q:
                    self._draw_volumes(zfail, *geometry, counting=False)
                fill[name] = q.samples
                if name == "volume_fragments":
                    prims += q.primitives
            fragments += fill["volume_fragments"]
            updates += fill["volume_fragments"] - fill["passed"] if zfail else fill["passed"]
        out["volume_fragments"] = int(fragments)
        out["stencil_updates"] = int(updates)
        out["fill_per_pixel"] = out["volume_fragments"] / (self.frame.width * self.frame.height)
        # The volume family's common footing (docs/shadow-volumes.md): per-pixel operations of
        # the per-pixel stage; here every volume fragment meets the depth and stencil tests.
        out["pixel_ops"] = out["volume_fragments"]
        out["volume_triangles"] = int(prims)  # primitives generated (geometry shader output included)
        return out


def near_plane_quad(frame) -> np.ndarray:
    """The corners (4, 3) of the camera's near-plane rectangle in world space (the viewport's
    edge, where the rays of z-pass counting begin after near-plane clipping)."""
    cam, view = frame.camera, frame.view
    right, up, back = view[0, :3], view[1, :3], view[2, :3]
    eye = np.asarray(cam.eye, np.float64)
    half_h = cam.near * np.tan(np.radians(cam.fov_y) / 2.0)
    half_w = half_h * frame.width / frame.height
    centre = eye - cam.near * back
    return np.array([centre + sx * half_w * right + sy * half_h * up
                     for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


def volumes_may_reach_near_plane(bounds: np.ndarray, quad: np.ndarray, light, scale: float) -> np.ndarray:
    """Bool (K,): for casters with axis-aligned ``bounds`` (K, 2, 3), whether the shadow volume
    may contain a point of the near-plane rectangle ``quad`` (4, 3) — conservatively (Everitt &
    Kilgard 2002, §5): whether the box meets the light's "occlusion pyramid", the convex hull of
    the light and the rectangle (for a light at infinity: the rectangle swept towards the light,
    until past every box's lowest corner along the light's direction; volumes are extruded along
    that direction there). A point x lies in a caster's volume only if the segment from the
    light to x meets the caster, so a box disjoint from the pyramid has no near-plane point in
    its volume and z-pass counts it exactly. Disjointness is shown by
    a separating axis (box axes, the pyramid's face normals, cross products of edges); where none
    is found — or within a margin of ``scale`` (the scene's size) times 1e-4, and with the
    rectangle grown by 1 % — the answer is True (z-fail: always right)."""
    bounds = np.asarray(bounds, np.float64)
    if not len(bounds):
        return np.zeros(0, bool)
    centre = quad.mean(axis=0)
    quad = centre + 1.01 * (quad - centre)
    right, up = quad[1] - quad[0], quad[3] - quad[0]
    normal = np.cross(right, up)
    margin = 1e-4 * max(scale, 1e-6)
    if light.at_infinity:
        d = np.asarray(light.direction, np.float64)
        d = d / np.linalg.norm(d)
        # The sweep q - t d (t >= 0) only needs to pass every box: beyond that it meets none.
        # A box's lowest point along d is its corner picked per axis by the sign of d (not
        # always its min or max corner).
        box_low = float(np.min(np.minimum(bounds[:, 0] * d, bounds[:, 1] * d).sum(axis=1)))
        reach = float(np.max(quad @ d)) - box_low + 1.0 + margin
        verts = np.concatenate([quad, quad - max(reach, 1.0) * d])
        edges = [right, up, d]
        faces = [normal, np.cross(right, d), np.cross(up, d)]
    else:
        lp = np.asarray(light.position, np.float64)
        verts = np.concatenate([lp[None], quad])
        spokes = [q - lp for q in quad]
        edges = [right, up] + spokes
        faces = [normal] + [np.cross(spokes[k], spokes[(k + 1) % 4]) for k in range(4)]
    box_axes = np.eye(3)
    axes = list(box_axes) + faces + [np.cross(a, e) for a in box_axes for e in edges] \
        + [np.cross(normal, e) for e in edges]
    axes = np.array(axes)
    length = np.linalg.norm(axes, axis=1)
    axes = axes[length > 1e-12 * max(1.0, float(length.max()))]
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    proj = verts @ axes.T  # (V, A)
    p_lo, p_hi = proj.min(axis=0), proj.max(axis=0)
    lo, hi = bounds[:, 0] - margin, bounds[:, 1] + margin
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    b_mid = mid @ axes.T  # (K, A)
    b_half = half @ np.abs(axes).T
    separated = (p_hi[None] < b_mid - b_half - margin) | (p_lo[None] > b_mid + b_half + margin)
    return ~separated.any(axis=1)


def pack_volume_geometry(verts: list, caps: list, flipped: list, far: list) -> tuple:
    """One counting method's volume geometry as :meth:`ShadowVolume._draw_volumes` takes it, from
    the per-caster pieces: volume vertices (vec4, concatenated), near-cap and flipped-cap vertex
    indices (from triangle indices) and far-cap vertex indices (already per vertex). Shared by
    the subclasses that build their own pieces (``cc_volume``)."""
    volume = np.concatenate(verts) if verts else np.zeros((0, 4), "f4")
    cap_idx = _triangle_indices(np.concatenate(caps) if caps else np.zeros(0, np.int64))
    flip_idx = _triangle_indices(np.concatenate(flipped) if flipped else np.zeros(0, np.int64))
    far_idx = np.concatenate(far) if far else np.zeros(0, np.int64)
    return volume, cap_idx, flip_idx, far_idx


def _flagged(pts: np.ndarray, extrude: float) -> np.ndarray:
    """float32 (N, 4): world points (rounded to float32 like the GPU path's) and the extrude flag."""
    out = np.empty((len(pts), 4), np.float32)
    out[:, :3] = pts
    out[:, 3] = extrude
    return out


def _triangle_indices(triangles: np.ndarray, corners=(0, 1, 2)) -> np.ndarray:
    """Vertex indices (3 per triangle, corners in the given order) into the frame's unwelded
    vertex order."""
    return (triangles[:, None] * 3 + np.asarray(corners)).ravel()
