"""Imperfect shadow maps (Ritschel, Grosch, Kim, Seidel, Dachsbacher & Kautz 2008, "Imperfect
shadow maps for efficient computation of indirect illumination", ACM TOG 27(5), SIGGRAPH Asia):
a tiny depth map per light rendered from a point set instead of the triangles, its holes filled
by pull-push — the cheap map a renderer can afford for every light beyond the few that get a
full shadow map.

**The point set.** The casters are approximated by points sampled on their triangles uniformly
by area (:func:`caster_points`), as a function of the scene alone (recomputed at each set-up,
the same every time): point *i* is the *i*-th
point of the 3D Halton sequence (bases 2, 3, 5; index 0 skipped). Its first coordinate picks the
triangle by inverting the cumulative area (so any 2^m consecutive points put one point in each
of 2^m equal slices of the total area: area-stratified), the other two place it in the triangle
by the square-root warp (uniform by area). Low discrepancy, not random: no seed, and the same
scene always gives the same points. Each light splats ``points`` of them, a subset of its own —
the light of index *l* takes indices l·``points`` + 1 … (l + 1)·``points`` — as Ritschel et al.
give each virtual point light its own subset of one shared set, so that the maps' errors are
independent from light to light.

**Passes.**

1. ``splat`` (``shadowlab/techniques/maps/imperfect_splat.glsl``): the points as GL_POINTS of one
   texel through each face's light matrix into its rect of the atlas, with a depth test
   (nearest wins), writing window depth to an R32F texture cleared to the hole marker
   (1, :data:`~shadowlab.techniques.maps.toolkit.CLEAR_DEPTH`). No triangles: a texel that no point reached is a
   *hole* (``hole_texels``).
2. ``pull`` and ``push`` (``shadowlab/techniques/maps/imperfect_pullpush.glsl``, compute; with
   ``pull_push=true``): *pull* builds a pyramid in which each coarser texel averages the valid
   depths of its four finer texels (the valid ones only: Ritschel et al. pull the average, not
   the nearest depth); *push* then fills every hole of each finer level with the bilinear
   interpolation of the (valid) coarser texels around it, coarsest level first, into a second
   pyramid whose finest level is the map. ``levels`` = 0 builds the pyramid down to one texel
   per face (every hole of a face with at least one point is filled: ``hole_texels_after`` = 0);
   ``levels`` = n stops n levels up, so holes wider than about 2^n texels stay holes (lit) —
   the guard against smearing caster depths over a map's true background where the casters do
   not fill the light's view (an outdoor sun over a ground that does not cast). With
   ``pull_push=false`` the holes stay: each is lit, and shadows leak through the point set's
   gaps — the artefact pull-push exists for.
3. ``lookup``: the map toolkit's depth comparison (``shadowlab/techniques/maps/shadow_lookup.glsl``, as
   shadow_map's, compiled with a define of its own so that the two never share a program's
   uniforms) over the shared G-buffer, with a constant
   ``bias`` (shadow_map's ``bias_space=world``: a distance towards the light, ``bias`` × the
   scene's extent on perspective maps converted to window depth at each receiver; ``bias`` ×
   the depth range on orthographic ones) plus ``slope_scale`` × the receiver plane's depth
   change over one texel (shadow_map's ``slope`` term). An imperfect map needs both beyond a
   shadow map's: a texel's depth is a point's somewhere in the texel (not at its centre), and a
   filled hole's is interpolated from texels up to 2^k away, so a sloped receiver that is also
   a caster (a floor) compares against its own surface a texel or more off; and the points
   themselves lie on the surfaces, so the receiver's own points are in the map. ``filter``:
   nearest or texel-exact PCF (3x3, 5x5).

**What pull-push cannot fix.** A texel is a hole only if no point at all reached it. Where an
occluder's points are sparser than one per texel, the texels between them are reached by the
points of the surfaces behind it (a floor under a table: the splat has no occlusion between
points other than the depth test within a texel), so they hold the far surface's depth, are
not holes, and the occluder's shadow leaks there whatever pull-push does. Only density fixes
it: more points, or fewer texels for the same points. The opposite error is at silhouettes: a
texel any occluder point reaches is the occluder's whole texel (nearest wins), and a hole on a
silhouette is filled with an average of occluder and background depths that still lies in
front of the background, so shadows grow by about a texel.

**Projection.** The toolkit's fitted views, not Ritschel et al.'s paraboloids: the light's own
``shadow_views`` fitted to the receivers that can be shadowed (:func:`~shadowlab.techniques.maps.toolkit.fit_light_views`,
``fit=shadowable``) — one frustum for a spot, an orthographic view for a directional or
target-direct light, for a point light a cube of six faces or one frustum (``projection``,
``auto`` as shadow_map chooses). The points are splatted through the same light matrices a
shadow map of the light would use, so its lookup, texel mapping (the texel-footprint metric)
and bias conventions apply unchanged, and an imperfect map and a full one of the same light
differ only in how the depths got there. A paraboloid (one hemisphere per virtual point light,
no lookup face selection) suits Ritschel et al.'s thousands of VPLs with one atlas texture
each; here a light is an ordinary per-light technique and its map can be fitted to what the
camera sees, which a paraboloid cannot.

Lights: point, spot, directional, target-direct; area lights through the pipeline's light
sampling (``LIGHT_SAMPLED``: each of ``light_samples`` stand-in point lights gets its own map).
The resolution must be a power of two (the pyramid's faces then stay aligned at every level).

Differences from the paper: no paraboloid projection (above); the points are splatted one
texel each into the light's fitted views, and their count per light is a parameter; the
pyramid's depth is a parameter (the paper fills every hole); Ritschel et al. use the maps for
indirect light from VPLs, here for the direct shadows of ordinary lights (the use of issue 40:
the lights a shadow budget does not give a full map).
"""
from __future__ import annotations

import numpy as np

from ...geometry.frusta import LightView
from ...gpu import glstate, programs, targets
from ...gpu.glstate import PassState
from ..base import FIRST, MAX, SUM, Param, PlotStyle, Technique, TechniqueError, TuneRange
from .contact import ContactShadows
from .toolkit import ATLAS_DEFINES, CLEAR_DEPTH, FILTERS, GBUFFER_TAPS, Atlas, TexelMapping, fit_light_views, \
    lookup_pass

#: Invocations per work group side of the pull-push dispatches (8 x 8).
LOCAL_SIZE = 8
#: The pull-push shader's ``u_mode`` values (``imperfect_pullpush.glsl``).
PULL, PUSH = 0, 1
#: The Halton bases of the point set's three coordinates: triangle choice, then the two
#: coordinates of the square-root warp inside it.
HALTON_BASES = (2, 3, 5)
#: The lookup filters an R32F map allows: texel-exact ones (no hardware depth comparison).
IMPERFECT_FILTERS = tuple(f for f, r in FILTERS.items() if r is not None)
#: Texels each compute invocation reads: pull, four children; push, its own and four coarser.
PULL_TAPS, PUSH_TAPS = 4, 5


def radical_inverse(indices: np.ndarray, base: int) -> np.ndarray:
    """Float64 (N,): the van der Corput radical inverse of the non-negative integers ``indices``
    in ``base`` — the digits of i in that base mirrored about the radix point (Halton 1960)."""
    i = np.asarray(indices, np.int64).copy()
    out = np.zeros(len(i))
    scale = 1.0 / base
    while np.any(i > 0):
        out += (i % base) * scale
        i //= base
        scale /= base
    return out


def caster_points(triangles: np.ndarray, start: int, count: int) -> np.ndarray:
    """Float64 (count, 3): points start + 1 … start + count of the scene's point set on
    ``triangles`` (T, 3, 3), uniform by area (module docstring): Halton point i = (h2, h3, h5)
    picks the triangle whose slice of the cumulative area holds h2 and the point
    a + √h3 · ((1 − h5)(b − a) + h5 (c − a)) in it (the square-root warp: uniform over the
    triangle). Empty when the triangles have no area."""
    tris = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
    area = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
    total = float(area.sum())
    if count <= 0 or not total > 0.0:
        return np.zeros((0, 3))
    idx = np.arange(start + 1, start + count + 1, dtype=np.int64)
    u, v, w = (radical_inverse(idx, b) for b in HALTON_BASES)
    cdf = np.cumsum(area)
    tri = np.minimum(np.searchsorted(cdf, u * total, side="right"), len(tris) - 1)
    a, b, c = tris[tri, 0], tris[tri, 1], tris[tri, 2]
    r = np.sqrt(v)[:, None]
    return a + r * ((1.0 - w)[:, None] * (b - a) + w[:, None] * (c - a))


def pyramid_levels(resolution: int, levels: int) -> int:
    """The coarser levels the pull-push builds: ``levels``, or with 0 every level down to one
    texel per face (log2 ``resolution``)."""
    full = int(resolution).bit_length() - 1
    return full if levels == 0 else int(levels)


class ImperfectMap(ContactShadows, TexelMapping, Technique):
    """Imperfect shadow maps: a tiny per-light depth map splatted from a point set on the
    casters, its holes filled by pull-push, compared as a shadow map is."""

    name = "imperfect_map"
    summary = ("imperfect shadow maps (Ritschel et al. 2008): a tiny map per light splatted from points sampled "
               "on the casters, holes filled by pull-push")
    STYLE = PlotStyle("#9edae5", "P")
    LIGHTS = frozenset({"point", "spot", "directional", "target_direct", "area"})
    LIGHT_SAMPLED = True  # area lights: one imperfect map per light sample (shadowlab.measurement.light_sampling)
    READS = frozenset({"position", "normal"})
    PROVIDES = frozenset({"texel_mapping"})
    PASSES = ("splat", "pull", "push", "lookup")
    STATS = {"points_splatted": SUM, "map_texels": SUM, "hole_texels": SUM, "hole_texels_after": SUM,
             "memory_bytes": MAX, "faces": FIRST, "passes": SUM, "pyramid_levels": FIRST,
             "depth_range": FIRST, "texel_world": FIRST}
    PARAMS = {
        "points": Param(8192, "points splatted per light (per light sample), from the scene's point set on the "
                              "casters (Ritschel et al. splat about 8k per map)", min=1, max=1 << 24,
                        # 1k leaves most texels of a 64² map empty; 256k fill a 128² cube densely
                        tune=TuneRange(1024, 262144, log=True)),
        "resolution": Param(64, "map width and height in texels, per face; a power of two", min=4, max=4096,
                            # imperfect maps are tiny by design: 32²-128² in the paper's range
                            tune=TuneRange(16, 512, log=True)),
        "pull_push": Param(True, "fill the splat's holes by pull-push (false: holes stay and are lit: light leaks)"),
        "levels": Param(0, "pull-push pyramid levels above the map (0: down to one texel per face, every hole "
                           "filled; n: holes wider than about 2^n texels stay)", min=0, max=12),
        "bias": Param(0.004, "constant depth bias: a distance towards the light as a fraction of the scene's extent "
                             "(perspective maps) or of the depth range (orthographic maps), shadow_map's "
                             "bias_space=world", min=0.0, max=1.0,
                      # 1e-4 of the extent leaves the floor's own points shadowing it; 0.05 detaches contacts
                      tune=TuneRange(1e-4, 0.05, log=True)),
        "slope_scale": Param(2.0, "plus this multiple of the receiver plane's depth change over one texel (a "
                                  "filled hole's depth comes from texels around it)", min=0.0, max=1e3,
                             # 0 leaves acne on sloped receivers that cast; past ~8 texels shadows shrink
                             tune=TuneRange(0.0, 8.0)),
        "filter": Param("nearest", "nearest, pcf3, pcf5 (texel-exact percentage-closer filtering)",
                        choices=IMPERFECT_FILTERS),
        "projection": Param("auto", "point lights: cube (six faces), frustum (one), auto (as shadow_map)",
                            choices=("auto", "cube", "frustum")),
    }

    def __init__(self, **params):
        super().__init__(**params)
        r = self.resolution
        if r & (r - 1):
            raise TechniqueError(f"{self.name}: resolution must be a power of two (the pull-push pyramid's faces "
                                 f"stay aligned only then), got {r}")
        if self.levels > int(r).bit_length() - 1:
            raise TechniqueError(f"{self.name}: levels ({self.levels}) exceeds log2(resolution) = "
                                 f"{int(r).bit_length() - 1}, the pyramid's one-texel-per-face level")

    # -- set-up ----------------------------------------------------------------------
    def fit_views(self, frame, slot) -> tuple[list[LightView], list[str]]:
        """The map's faces (shadow_map's fit: the shadowable receivers) and notes for the run."""
        return fit_light_views(frame, slot, self.resolution, self.projection, 0.0, "shadowable")

    def setup(self, frame, slot) -> None:
        """Untimed: fit the faces, sample this light's points, allocate the splat target and the
        two pyramids, set up the programs."""
        ctx = frame.ctx
        faces, notes = self.fit_views(frame, slot)
        self.notes.extend(notes)
        self.atlas = Atlas.grid(faces, self.resolution, self.name)
        pts = caster_points(frame.casters().triangles, slot.index * self.points, self.points)
        if len(pts) == 0:
            self.notes.append(f"{self.name}: the scene has no caster area: nothing is splatted")
        self.points_count = len(pts)
        self.vbo = self.own(ctx.buffer(np.ascontiguousarray(pts, np.float32).tobytes() or b"\0" * 12))
        self.splat_prog = self.program("imperfect_splat.glsl")
        self.splat_vao = self.own(ctx.vertex_array(self.splat_prog, [(self.vbo, "3f", "in_pos")]))
        size = self.atlas.size
        self.levels_used = pyramid_levels(self.resolution, self.levels) if self.pull_push else 0

        def level(k):
            tex = self.own(ctx.texture((size[0] >> k, size[1] >> k), 1, dtype="f4"))
            tex.filter = (ctx.NEAREST, ctx.NEAREST)
            tex.repeat_x = tex.repeat_y = False
            return tex

        # pulled[k]: the splat (k = 0) and the pulled averages; filled[k]: the pushed levels
        self.pulled = [level(k) for k in range(self.levels_used + 1)]
        self.filled = [level(k) for k in range(self.levels_used)] + [self.pulled[-1]]
        self.depth_buffer = self.own(ctx.depth_renderbuffer(size))
        self.splat_fbo = self.own(ctx.framebuffer(color_attachments=[self.pulled[0]],
                                                  depth_attachment=self.depth_buffer))
        self.map_texture = self.filled[0]
        if self.levels_used:
            self.pullpush_prog = self.program("imperfect_pullpush.glsl", defines={"LOCAL_SIZE": LOCAL_SIZE})
            programs.set_uniforms(self.pullpush_prog, {"u_finer": 0, "u_coarser": 1, "u_target": 0})
        self.lookup_prog = self.program("shadow_lookup.glsl", defines={**ATLAS_DEFINES, "IMPERFECT_MAP": 1})
        programs.set_uniforms(self.lookup_prog, self.light.uniforms())
        self.atlas.write_uniforms(self.lookup_prog)
        programs.set_uniforms(self.lookup_prog, {"u_map": 2, **self.comparison_uniforms()})
        self.quad = self.fullscreen_quad(self.lookup_prog)
        self.vis_tex, self.vis_fbo = self.visibility_target((frame.width, frame.height))

    def comparison_uniforms(self) -> dict:
        """The lookup's uniforms: the constant bias as shadow_map's ``bias_space=world`` applies it
        (a world distance on perspective maps, window depth on orthographic ones), the slope
        term, the first face's texel size and the PCF radius; the per-tap comparisons, the normal
        offset and the oriented bias off."""
        face = self.atlas.faces[0]
        perspective = face.proj[3, 3] != 1.0
        extent = float(self.frame.scene.extent())
        return {
            "u_bias": 0.0 if perspective else float(self.bias),
            "u_bias_world": float(self.bias) * extent if perspective else 0.0,
            "u_slope_scale": float(self.slope_scale), "u_normal_offset": 0.0,
            "u_texel_world": float(face.texel_world), "u_texel_angle": float(face.texel_angle),
            "u_kernel_radius": FILTERS[self.filter], "u_depth_comparison": 0, "u_adaptive_epsilon": 0.0,
            "u_scene_extent": extent, "u_oriented": 0,
        }

    # -- the passes ----------------------------------------------------------------------
    def render(self) -> None:
        """Splat the points into every face, pull and push the holes full (``pull_push``), then
        the lookup."""
        from OpenGL import GL

        ctx = self.frame.ctx
        with self.timed_pass("splat"):
            self.splat_fbo.use()
            glstate.apply(PassState(depth_test=True, depth_func="<", depth_write=True))
            GL.glEnable(GL.GL_PROGRAM_POINT_SIZE)  # one texel per point: gl_PointSize = 1
            ctx.viewport = (0, 0, *self.atlas.size)
            self.splat_fbo.clear(red=CLEAR_DEPTH, depth=CLEAR_DEPTH)
            for face, rect in zip(self.atlas.faces, self.atlas.rects):
                ctx.viewport = rect
                self.splat_prog["u_light_view_proj"].write(programs.mat_bytes(face.view_proj))
                self.splat_vao.render(mode=GL.GL_POINTS, vertices=self.points_count)
            GL.glDisable(GL.GL_PROGRAM_POINT_SIZE)
        if self.levels_used:
            with self.timed_pass("pull"):
                for k in range(1, self.levels_used + 1):
                    self._dispatch(PULL, k, finer=self.pulled[k - 1], coarser=None, target=self.pulled[k])
            with self.timed_pass("push"):
                for k in range(self.levels_used - 1, -1, -1):
                    self._dispatch(PUSH, k, finer=self.pulled[k], coarser=self.filled[k + 1], target=self.filled[k])
        with self.timed_pass("lookup"):
            lookup_pass(self, self.vis_fbo, self.quad, self.map_texture)

    def _dispatch(self, mode: int, k: int, finer, coarser, target) -> None:
        """One pull or push dispatch writing level ``k`` (``target``), then a barrier so the next
        level's fetches see its stores."""
        prog = self.pullpush_prog
        finer.use(0)
        if coarser is not None:
            coarser.use(1)
        target.bind_to_image(0, read=False, write=True)
        w, h = target.size
        programs.set_uniforms(prog, {"u_mode": mode, "u_size": (w, h), "u_face": self.resolution >> k})
        prog.run(-(-w // LOCAL_SIZE), -(-h // LOCAL_SIZE))
        self.frame.ctx.memory_barrier()

    # -- figures ---------------------------------------------------------------------------
    def splat_depths(self) -> np.ndarray:
        """Float32 (height, width): the atlas after the splat (1 = a hole), row 0 = top. After
        :meth:`render`."""
        return targets.read_texture(self.pulled[0], 1)[..., 0]

    def map_depths(self) -> np.ndarray:
        """Float32 (height, width): the map the lookup compares with (after pull-push), row 0 =
        top. After :meth:`render`."""
        return targets.read_texture(self.map_texture, 1)[..., 0]

    def stats(self) -> dict:
        """Points splatted, the atlas's texels, its holes before and after pull-push, the memory
        of the splat target, depth buffer and pyramids, faces, passes, pyramid levels, and the
        first face's depth range and world texel size."""
        holes = int(np.count_nonzero(self.splat_depths() >= CLEAR_DEPTH))
        after = int(np.count_nonzero(self.map_depths() >= CLEAR_DEPTH)) if self.levels_used else holes
        textures = {id(t): t for t in self.pulled + self.filled}.values()
        memory = sum(t.width * t.height * 4 for t in textures) + self.atlas.texels * 4  # + the depth buffer
        face = self.atlas.faces[0]
        return {"points_splatted": self.points_count, "map_texels": self.atlas.texels, "hole_texels": holes,
                "hole_texels_after": after, "memory_bytes": memory, "faces": len(self.atlas.faces),
                "passes": len(self.atlas.faces) + 2 * self.levels_used + 1,  # splats, pulls and pushes, lookup
                "pyramid_levels": self.levels_used, "depth_range": face.depth_range,
                "texel_world": float(face.texel_world) or None}

    def work(self, counted: dict, stats: dict) -> dict:
        """Texture taps: each pull invocation reads four finer texels, each push invocation its
        own and four coarser ones; the lookup reads the G-buffer's position and normal and
        (2r+1)² map texels. The splat's vertices (points × faces: every face draws every point,
        clipping keeps the ones inside it) are counted by the draw hooks."""
        radius = FILTERS[self.filter]
        return self.taps_work(counted, {"pull": PULL_TAPS, "push": PUSH_TAPS,
                                        "lookup": GBUFFER_TAPS + (2 * radius + 1) ** 2})
