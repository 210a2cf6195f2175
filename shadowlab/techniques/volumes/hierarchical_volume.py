"""Hierarchical shadow volumes: stencil shadow volumes whose per-pixel work is spent only in the
screen tiles that a shadow boundary crosses.

Aila & Akenine-Möller 2004, "A Hierarchical Shadow Volume Algorithm" (Graphics Hardware, §3-4):
the screen is cut into 8×8 tiles, each with the depth range [zmin, zmax] of the surfaces it
shows. A shadow-volume triangle that covers a whole tile and lies wholly in front of (or behind)
that range changes every pixel's count in the tile by the same ±1, so it is counted once for the
tile; one that covers none of it, or lies on the side where the depth test does not count it,
does nothing there. Only the tiles where some volume triangle's edge or depth plane crosses the
tile's pixels or depth range — the *boundary* tiles, along the shadow's outline — need
per-pixel stencil counting, so the per-pixel work grows with the length of the shadow boundary,
not with the area the volumes fill (the paper: "up to 11.5 times fewer pixels processed").
The paper does the tile tests in a modified rasteriser with a hierarchical stencil buffer; here
they are compute passes and the per-pixel work is the plain stencil volume's, masked to the
boundary tiles:

1. ``tiles`` (compute): each tile's window-depth range over the pixels that hold a surface, read
   from a copy of the technique's own depth pre-pass (the depths the stencil test compares
   with; a tile showing no surface is left out); tile size ``tile`` (8×8 by default).
2. ``classify`` (compute, two programs): every volume triangle — with its counting rule: z-pass
   front +1 / back −1 on depth pass, z-fail back +1 / front −1 on depth fail, two-sided caps of
   unlit faces with the other face's operations — is clipped in homogeneous clip space to the
   near plane and the frustum's sides (points at infinity have w = 0; the clip positions are
   the per-pixel stage's own, ``shadow_volume_clip.glsl``); its window-depth plane comes from
   the clip-space corners without dividing by w (the 4D normal of the subspace they span). Per
   tile row, the run of tiles the clipped polygon reaches is cut into spans, and each (triangle,
   tile) pair is classified: (a) no pixel centre of the tile covered, or the triangle's depth
   over the tile wholly on the side where the depth test does not count it: no effect; (b)
   every pixel centre covered (the tile's corner centres inside every edge by a margin; the
   clipped polygon is convex) and its depth wholly on the counting side: ±1 to the tile's count
   (an atomic add); otherwise (c) the tile is a boundary tile. The depth range is first bounded
   by the plane at the tile's corners and, where that settles nothing (steep planes, slivers),
   by the exact range over the part of the clipped triangle inside the tile (depth taken at the
   corners of that part, interpolated along the polygon's edges). Margins cover the
   rasteriser's rounding: a quarter pixel of position, many units of the 24-bit depth buffer,
   more where clip coordinates are large against w; anything uncertain (near-degenerate, edge-on) is boundary:
   a wrong "boundary" costs time, never a pixel. A triangle with two bit-identical corners (a
   directional light's side triangles meet at one point at infinity) has no fragment anywhere
   and is skipped.
3. ``volume``, ``caps``: the plain volume's stencil passes, unchanged (:class:`ShadowVolume`:
   z-pass, z-fail or per-caster auto, caps, infinite far plane or depth clamp), drawn by a
   program whose fragment stage discards every fragment outside the boundary tiles. In a
   boundary tile every volume triangle is counted per pixel, so the tile count is used only in
   the other tiles: nothing is counted twice.
4. ``count``: one full-screen pass under "stencil == 0": a boundary tile is lit where its
   stencil is 0, another tile where its count is 0 modulo 256 (the stencil's own wrapping).

Exactness: wherever the classification is right, every pixel's count equals the plain volume's,
so the two masks are identical on every pixel that shows a surface (pixels that show none may
differ: the tiles ignore them, as nothing reads them). The tests assert identical masks on the
hard cases at several sizes and every tile size.

Choices and deviations from the paper: CPU silhouettes only (``silhouette=cpu`` is forced: the
classification reads the volume triangles from the CPU-built arrays); the tile depth ranges are
read from the technique's depth pre-pass by a compute pass instead of a hierarchical z-buffer;
the tile tests run as compute passes over (triangle, tile) pairs before any per-pixel work,
instead of inside the rasteriser; the per-pixel pass discards fragments outside boundary tiles
in its fragment stage, so llvmpipe still rasterises them (a hardware implementation skips the
tiles before rasterising): ``volume_fragments`` and ``pixel_ops`` count the fragments that reach
stencil work, as the hardware design would, and ``all_volume_fragments`` the plain volume's
figure for the same frame. The span list is sized on the GPU's count and grown (and the pass
run again) when it would overflow, never silently. Beyond the paper: the exact depth range over
the triangle's part in a tile, which settles tiles the plane bound cannot (long slivers from
finely tessellated silhouettes); in z-fail, caps lying on the visible surface tie with it and
leave their tiles boundary, as in the paper.
"""
from __future__ import annotations

import numpy as np

from ...gpu import gl, glstate, programs, targets
from ...gpu.gl import check_errors
from ...gpu.glstate import PassState, Stencil
from ..base import SUM, Param, PlotStyle, TechniqueError
from .shadow_volume import ShadowVolume, _flagged

#: Storage-buffer bindings (``hierarchical_volume_common.glsl``).
BINDING = {"tile_bounds": 0, "tile_count": 1, "tile_boundary": 2, "tri_vertices": 3, "tri_rules": 4,
           "triangles": 5, "spans": 6, "counters": 7, "tile_triangle": 8}
#: Counter slots (``hierarchical_volume_common.glsl``: COUNTER_*).
COUNTERS = ("spans", "tile_tests", "uncertain")
#: Most tiles per span (a run of tiles in one tile row): one invocation of the second
#: classification program.
SPAN = 16
#: Invocations per work group of the compute programs (their ``local_size_x``).
LOCAL_SIZE = 64
#: Bytes of one set-up volume triangle (``VolumeTriangle``, std430: 9 + 9 + 4 vec4).
TRIANGLE_BYTES = 22 * 16
#: Counting rules per volume triangle (``RULE_*`` in the GLSL); a near cap also carries its scene
#: triangle + 1, shifted by RULE_CAP_SHIFT.
RULE_ZFAIL, RULE_FLIPPED, RULE_CAP_SHIFT = 1, 2, 2
#: Pixels by which a tile's corner centres must lie inside (outside) every edge of a triangle
#: for it to count as covering (missing) the tile: the rasteriser snaps corners to sub-pixel
#: precision (1/256 pixel on llvmpipe, coarser on some GPUs) and clips in float32.
COVERAGE_MARGIN = 0.25
#: Window-depth error bound relative to the size of the depth plane's terms over the viewport
#: (the rasteriser interpolates depth in float32): 2^-17, 128 units of the 24-bit depth buffer.
DEPTH_RELATIVE_MARGIN = 2.0 ** -17
#: Position uncertainty (pixels) that the depth plane's slope turns into a depth error.
DEPTH_POSITION_MARGIN = 0.25
#: The span list's first size per volume triangle, and at least (grown to what a render asks for).
SPANS_PER_TRIANGLE = 8
MIN_SPANS = 1024
#: Retries of an overflowing span list before the run fails (each sizes it to what was asked).
MAX_RETRIES = 2


class DepthCopy:
    """A ``GL_DEPTH24_STENCIL8`` texture with a framebuffer: the blit target that copies the
    depth pre-pass out of the frame's depth-stencil renderbuffer (a renderbuffer cannot be
    sampled; a depth blit needs identical formats), sampled as depth by the tile pass."""

    def __init__(self, size: tuple[int, int]):
        from OpenGL import GL
        from OpenGL.raw.GL.VERSION.GL_1_0 import glTexImage2D as raw_tex_image_2d

        self.size = (int(size[0]), int(size[1]))
        w, h = self.size
        self.tid = int(GL.glGenTextures(1))
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.tid)
        # the raw entry point: PyOpenGL's wrapper has no array type for GL_UNSIGNED_INT_24_8
        raw_tex_image_2d(GL.GL_TEXTURE_2D, 0, GL.GL_DEPTH24_STENCIL8, w, h, 0, GL.GL_DEPTH_STENCIL,
                         GL.GL_UNSIGNED_INT_24_8, None)
        # texelFetch needs a complete texture: no mipmaps, so no mipmap filter
        for pname in (GL.GL_TEXTURE_MIN_FILTER, GL.GL_TEXTURE_MAG_FILTER):
            GL.glTexParameteri(GL.GL_TEXTURE_2D, pname, GL.GL_NEAREST)
        for pname in (GL.GL_TEXTURE_WRAP_S, GL.GL_TEXTURE_WRAP_T):
            GL.glTexParameteri(GL.GL_TEXTURE_2D, pname, GL.GL_CLAMP_TO_EDGE)
        GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_COMPARE_MODE, GL.GL_NONE)
        GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_DEPTH_STENCIL_TEXTURE_MODE, GL.GL_DEPTH_COMPONENT)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        self.fid = int(GL.glGenFramebuffers(1))
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.fid)
        GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_STENCIL_ATTACHMENT, GL.GL_TEXTURE_2D, self.tid, 0)
        GL.glDrawBuffer(GL.GL_NONE)
        GL.glReadBuffer(GL.GL_NONE)
        status = GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
        if status != GL.GL_FRAMEBUFFER_COMPLETE:
            raise gl.GLError(f"depth copy framebuffer incomplete (status {hex(int(status))})")
        check_errors("DepthCopy")

    @property
    def nbytes(self) -> int:
        """GPU memory of the texture (4 bytes a pixel)."""
        return 4 * self.size[0] * self.size[1]

    def copy_from(self, fbo_glo: int) -> None:
        """Blit the depth of framebuffer ``fbo_glo`` (same size, ``GL_DEPTH24_STENCIL8``) into the
        texture, bit for bit (the scissor test must be off: :func:`glstate.apply` turns it off)."""
        from OpenGL import GL

        w, h = self.size
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, fbo_glo)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self.fid)
        GL.glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL.GL_DEPTH_BUFFER_BIT, GL.GL_NEAREST)
        check_errors("DepthCopy.copy_from")

    def use(self, unit: int) -> None:
        """Bind the texture on texture unit ``unit``."""
        from OpenGL import GL

        GL.glBindTextureUnit(unit, self.tid)

    def release(self) -> None:
        """Free the framebuffer and the texture."""
        from OpenGL import GL

        GL.glDeleteFramebuffers(1, [self.fid])
        GL.glDeleteTextures(1, [self.tid])


class HierarchicalVolume(ShadowVolume):
    """Stencil shadow volumes counted per tile where a tile lies wholly inside or outside each
    volume triangle's reach, and per pixel only in boundary tiles (module docstring)."""

    name = "hierarchical_volume"
    summary = ("hierarchical shadow volumes (Aila & Akenine-Möller 2004): tiles inside or outside every volume "
               "counted at once, per-pixel stencil work only in boundary tiles")
    PARAMS = {
        **{k: p for k, p in ShadowVolume.PARAMS.items() if k not in ("light_samples", "silhouette")},
        "tile": Param(8, "tile width and height in pixels (the paper: 8)", choices=(4, 8, 16, 32)),
    }
    #: The classification reads the volume triangles the CPU path builds.
    silhouette = "cpu"
    PASSES = ("silhouette", "tiles", "classify", "volume", "caps", "count")
    STYLE = PlotStyle("#fd8d3c", "X")
    STATS = {**ShadowVolume.STATS, "tiles_inside": SUM, "tiles_outside": SUM, "tiles_boundary": SUM,
             "tile_tests": SUM, "pixel_ops": SUM, "all_volume_fragments": SUM, "uncertain_triangles": SUM,
             "span_retries": SUM}

    # ------------------------------------------------------------------ setup
    def setup(self, frame, slot) -> None:
        """The tile buffers, the plain volume's setup (programs, buffers, depth pre-pass drawn by
        this technique's program), a copy of the pre-pass depth, the compute programs."""
        ctx = frame.ctx
        self.size = (frame.width, frame.height)
        self.tile_grid = (-(-frame.width // self.tile), -(-frame.height // self.tile))
        tiles = self.tile_grid[0] * self.tile_grid[1]
        self.buffers = {
            "tile_bounds": self.own(ctx.buffer(reserve=8 * tiles)),
            "tile_count": self.own(ctx.buffer(reserve=4 * tiles)),
            "tile_boundary": self.own(ctx.buffer(reserve=4 * tiles)),
            "tile_triangle": self.own(ctx.buffer(reserve=4 * tiles)),
            "counters": self.own(ctx.buffer(reserve=4 * len(COUNTERS))),
        }
        # The pre-pass's triangle per pixel, drawn with the pre-pass's depth (the frame's
        # depth-stencil, which the plain volume's target shares too).
        self.triangle_tex = self.own(ctx.texture(self.size, 1, dtype="f4"))
        self.triangle_target = self.own(targets.ScreenTarget.create(
            self.size, [self.triangle_tex], share_depth_stencil=frame.depth_stencil_for(self)))
        self.span_capacity = 0
        self.retries = 0
        self.counts = dict.fromkeys(COUNTERS, 0)
        super().setup(frame, slot)  # draws the depth pre-pass with volume_program() (mask off)
        corners = frame.triangles.reshape(-1, 3)
        self.corners4, self.corners_ext = _flagged(corners, 0.0), _flagged(corners, 1.0)
        glstate.apply(PassState())  # scissor off for the blit
        self.depth_copy = self.own(DepthCopy(self.size))
        self.depth_copy.copy_from(self.target.fbo_glo)
        self.target.use()  # moderngl's current framebuffer bound again
        grid = {"u_tile": self.tile, "u_tiles": self.tile_grid, "u_size": self.size}
        self.tiles_prog = self.program("hierarchical_volume_tiles.glsl")
        programs.set_uniforms(self.tiles_prog, {**grid, "u_depth": 0, "u_triangle": 1})
        self.triangles_prog = self.program("hierarchical_volume_triangles.glsl", defines={"SPAN": SPAN})
        for key, val in self.matrices.items():
            self.triangles_prog[key].write(val)
        programs.set_uniforms(self.triangles_prog, {
            **self.light.uniforms(), **grid, "u_clip_far": self.far == "finite", "u_margin_px": COVERAGE_MARGIN,
            "u_depth_rel": DEPTH_RELATIVE_MARGIN, "u_depth_px": DEPTH_POSITION_MARGIN})
        self.classify_prog = self.program("hierarchical_volume_classify.glsl", defines={"SPAN": SPAN})
        programs.set_uniforms(self.classify_prog, {**grid, "u_depth_rel": DEPTH_RELATIVE_MARGIN})
        self.resolve_prog = self.program("hierarchical_volume_resolve.glsl")
        programs.set_uniforms(self.resolve_prog, grid)
        self.resolve_quad = self.fullscreen_quad(self.resolve_prog)
        self.storage: dict = {}

    def volume_program(self):
        """The plain volume's vertex and geometry stages with a fragment stage that discards
        fragments outside boundary tiles (``hierarchical_volume.glsl``)."""
        prog = self.program("hierarchical_volume.glsl", defines=self.defines)
        programs.set_uniforms(prog, {"u_tile": self.tile, "u_tiles": self.tile_grid, "u_size": self.size,
                                     "u_mask_tiles": False})
        return prog

    def _depth_prepass(self) -> None:
        """The plain volume's depth pre-pass (the same program, vertices, clipping and depth
        clamp, into the same depth-stencil), every fragment kept (the mask is off; the tile
        buffer is bound all the same, so the program never reads an unbound buffer), also
        writing each pixel's scene triangle to :attr:`triangle_tex` (−1 where none)."""
        from OpenGL import GL

        self.buffers["tile_boundary"].bind_to_storage_buffer(BINDING["tile_boundary"])
        self.vs_prog["u_mask_tiles"].value = False
        self.triangle_target.use()
        glstate.apply(PassState(depth_test=True, depth_func="<", depth_write=True, color_write=True,
                                depth_clamp=self.far == "clamp", clip_distances=self.clip_distances))
        self.triangle_target.clear_depth_stencil()
        GL.glClearBufferfv(GL.GL_COLOR, 0, (-1.0, -1.0, -1.0, -1.0))
        self.scene4_vao.render()  # one draw of every scene triangle: primitive i is triangle i
        gl.check_errors("hierarchical volume depth pre-pass")

    # ------------------------------------------------------------------ per-frame work
    def volume_triangles(self, geometry: dict) -> tuple[np.ndarray, np.ndarray]:
        """Every volume triangle the stencil passes draw, as float32 (3T, 4) corners (world
        point, extrude flag: the per-pixel stage's own vertex data) and int32 (T,) counting
        rules (:data:`RULE_ZFAIL`, :data:`RULE_FLIPPED`, a near cap's scene triangle), from
        :meth:`cpu_volume_geometry`."""
        verts, rules = [], []
        for zfail, (volume, cap_idx, flip_idx, far_idx) in geometry.items():
            rule = RULE_ZFAIL if zfail else 0
            none = np.zeros(0, np.int64)
            for part, r, caps in ((volume, rule, none), (self.corners_ext[far_idx], rule, none),
                                  (self.corners4[cap_idx], rule, cap_idx), (self.corners4[flip_idx],
                                                                            rule | RULE_FLIPPED, flip_idx)):
                if len(part):
                    verts.append(np.asarray(part, np.float32).reshape(-1, 4))
                    r = np.full(len(part) // 3, r, np.int32)
                    if len(caps):  # near caps: their scene triangle (corner index // 3) + 1
                        r |= (caps[0::3] // 3 + 1).astype(np.int32) << RULE_CAP_SHIFT
                    rules.append(r)
        if not verts:
            return np.zeros((0, 4), np.float32), np.zeros(0, np.int32)
        return np.concatenate(verts), np.concatenate(rules)

    def _storage(self, key: str, nbytes: int):
        """An owned storage buffer of at least ``nbytes`` kept under ``key`` and replaced by a
        larger one when outgrown."""
        buf = self.storage.get(key)
        if buf is None or buf.size < nbytes:
            if buf is not None:
                self.free(buf)
            buf = self.storage[key] = self.own(self.frame.ctx.buffer(reserve=max(16, nbytes)))
        return buf

    def _bind(self) -> None:
        """Bind every storage buffer to its binding point (nothing is inherited from before)."""
        for name, buf in {**self.buffers, **self.storage}.items():
            buf.bind_to_storage_buffer(BINDING[name])

    def _classify(self, verts: np.ndarray, rules: np.ndarray) -> None:
        """Set up the volume triangles and cut their tile boxes into spans, then classify every
        (triangle, tile) pair; a span list too small is grown and the pass run again
        (:data:`MAX_RETRIES`), never truncated silently."""
        ctx = self.frame.ctx
        count = len(rules)
        self._storage("tri_vertices", verts.nbytes).write(verts.tobytes())
        self._storage("tri_rules", rules.nbytes).write(rules.tobytes())
        self._storage("triangles", TRIANGLE_BYTES * count)
        if self.span_capacity < SPANS_PER_TRIANGLE * count or not self.span_capacity:
            self.span_capacity = max(MIN_SPANS, SPANS_PER_TRIANGLE * count)
        for attempt in range(MAX_RETRIES + 1):
            self._storage("spans", 16 * self.span_capacity)
            self._bind()
            self.buffers["counters"].clear()
            self.triangles_prog["u_triangles"].value = count
            self.triangles_prog["u_span_capacity"].value = self.span_capacity
            programs.dispatch(self.triangles_prog, count, LOCAL_SIZE)
            ctx.memory_barrier()
            self.counts = dict(zip(COUNTERS, np.frombuffer(self.buffers["counters"].read(), np.uint32).tolist()))
            asked = int(self.counts["spans"])
            if asked <= self.span_capacity:
                break
            if attempt == MAX_RETRIES:
                raise TechniqueError(f"{self.name}: the span list of {self.span_capacity} overflowed ({asked} asked "
                                     f"for) after {MAX_RETRIES} retries")
            self.notes.append(f"span list of {self.span_capacity} overflowed ({asked} asked for): retried with "
                              f"{asked}")
            self.retries += 1
            self.span_capacity = asked
        if asked:
            self.classify_prog["u_spans"].value = asked
            programs.dispatch(self.classify_prog, asked, LOCAL_SIZE)
            ctx.memory_barrier()

    def render(self) -> None:
        """Silhouettes (CPU) and the volume triangles; tile depth ranges; the tile
        classification; stencil counting in boundary tiles (z-pass casters, then z-fail casters,
        as in the plain volume); then tiles and stencil → visibility."""
        from OpenGL import GL

        ctx = self.frame.ctx
        with self.timed_pass("silhouette", cpu=True):
            self._geometry = self.cpu_volume_geometry()
            verts, rules = self.volume_triangles(self._geometry)
        with self.timed_pass("tiles"):
            glstate.apply(PassState())  # no sampler object on unit 0 (the depth copy is read raw)
            self._bind()
            self.depth_copy.use(0)
            self.triangle_tex.use(1)
            programs.dispatch(self.tiles_prog, self.tile_grid[0] * self.tile_grid[1], LOCAL_SIZE)
            ctx.memory_barrier()
        with self.timed_pass("classify"):
            self._classify(verts, rules)
        with self.timed_pass("volume"):  # the stencil clear is the volume pass's first step
            self.target.use()
            glstate.apply(self._volume_state(zfail=True))  # stencil writes on, for the clear
            GL.glClearStencil(0)
            GL.glClear(GL.GL_STENCIL_BUFFER_BIT)
            self._bind()
            self.vs_prog["u_mask_tiles"].value = True
        for zfail, geometry in self._geometry.items():
            glstate.apply(self._volume_state(zfail))
            self._draw_volumes(zfail, *geometry)
        with self.timed_pass("count"):
            glstate.apply(PassState(depth_write=False, stencil=Stencil("==", 0, 0xFF)))
            GL.glClearBufferfv(GL.GL_COLOR, 0, (0.0, 0.0, 0.0, 0.0))
            self._bind()
            self.resolve_quad.render()

    # ------------------------------------------------------------------ figures
    def tile_classes(self) -> dict:
        """Tiles by class after a render: ``boundary`` (counted per pixel), ``inside`` (settled
        at tile level, in shadow: count ≠ 0 modulo 256) and ``outside`` (settled, lit; tiles
        that show no surface included)."""
        n = self.tile_grid[0] * self.tile_grid[1]
        boundary = np.frombuffer(self.buffers["tile_boundary"].read(), np.uint32)[:n] != 0
        count = np.frombuffer(self.buffers["tile_count"].read(), np.int32)[:n]
        inside = ~boundary & ((count & 255) != 0)
        return {"boundary": int(boundary.sum()), "inside": int(inside.sum()),
                "outside": int(n - boundary.sum() - inside.sum())}

    def stats(self) -> dict:
        """The plain volume's figures, measured on the masked passes (so ``volume_fragments``,
        ``stencil_updates`` and the stencil peak are those of the boundary tiles), the plain
        figure ``all_volume_fragments`` (the same passes unmasked), the tile classes, the
        (triangle, tile) pairs classified, the triangles too degenerate to classify and the
        span list's retries."""
        self._bind()
        self.vs_prog["u_mask_tiles"].value = True
        out = super().stats()
        self.vs_prog["u_mask_tiles"].value = False
        self.target.use()
        everything = 0
        for zfail, geometry in self._geometry.items():
            glstate.apply(self._volume_state(zfail, "always", stencil=False))
            q = gl.query("hierarchical_volume fill", samples=True)
            with q:
                self._draw_volumes(zfail, *geometry, counting=False)
            everything += q.samples
        self.vs_prog["u_mask_tiles"].value = True
        classes = self.tile_classes()
        out.update({"tiles_inside": classes["inside"], "tiles_outside": classes["outside"],
                    "tiles_boundary": classes["boundary"], "tile_tests": int(self.counts["tile_tests"]),
                    "pixel_ops": out["volume_fragments"], "all_volume_fragments": int(everything),
                    "uncertain_triangles": int(self.counts["uncertain"]), "span_retries": int(self.retries)})
        return out
