"""Hybrid ray-traced shadows: a shadow map classifies every pixel as surely lit, surely shadowed or
uncertain, and Embree shadow rays are traced for the uncertain ones only.

The idea is that of AMD FidelityFX Hybrid Shadows (GPUOpen, FidelityFX SDK: a shadow map marks
what it is sure of, tiles with too few uncertain pixels are left to the map, rays resolve the
rest), and in spirit of NVIDIA's HFTS (Story & Wyman, "HFTS: Hybrid Frustum-Traced Shadows in
The Division", SIGGRAPH 2016 talk: exact, traced hard shadows only where they matter, a
filtered map elsewhere). Here the rays are the truth's own, so wherever a full-length ray is
traced the answer is the truth's bit for bit, and the only errors are the classifier's (a pixel
called sure wrongly), the dropped tiles' and — with ``shorten`` — a shortened ray's (below).

Passes (hard lights: point, spot, directional, target-direct):

- ``depth``: the casters' depth from the light into an atlas fitted to the receivers that can be
  shadowed (the map toolkit: :func:`~shadowlab.techniques.maps.toolkit.fit_light_views`,
  :class:`~shadowlab.techniques.maps.toolkit.Atlas`, :func:`~shadowlab.techniques.maps.toolkit.depth_pass`;
  one face, or a point light's six cube faces).
- ``classify`` (``hybrid_rt_classify.glsl``, full screen over the G-buffer): the receiver is compared
  with each of the (2r+1)² texels around the texel holding it (r = ``spread``) with shadow_map's
  constant bias in its world form (``bias`` × the scene's extent, a distance towards the light,
  on perspective maps; ``bias`` × the depth range, i.e. window depth, on orthographic ones):
  every tap lit → surely lit, every tap shadowed → surely shadowed, else uncertain. A kernel
  that reaches past the face's edge is uncertain too: the map is fitted to the receivers that
  can be shadowed, so a shadow can run up to the edge, and taps clamped to the edge texel would
  call its rim sure. The pass also writes the nearest tap's answer and the distance a shadow
  ray must reach (below).
- ``trace`` (CPU): the class image read back; per 8x8 screen tile (from the top-left pixel) the
  uncertain evaluated pixels are counted, and a tile with fewer than ``cutoff`` of them takes the
  nearest tap's answer for them (AMD's tile cut-off; 0 traces every uncertain pixel); the others
  get one Embree shadow ray each, from the same float32 offset origins the truth uses
  (:func:`shadowlab.truth.tracing.offset_origins`, :meth:`Light.shadow_rays`) against the same
  robust Embree scene of the casters (:func:`shadowlab.truth.tracing.caster_scene`).

Ray shortening (``shorten``): the shadow ray from P towards the light projects onto P's own
texel (it runs along the light's ray through P), so any caster on it nearer to the light than
the smallest depth d_min stored in the kernel would have been rasterised into the kernel and
lowered that minimum — as long as it covers a texel centre there. The ray therefore only has to
reach from P to where its window depth falls to d_min; the classification pass solves for that
distance exactly (the form of :func:`~shadowlab.techniques.maps.toolkit.window_to_world`) and adds a
margin of ``margin`` world texels at that point plus the bias's world size; the ray's ``tfar``
becomes that distance (in the ray's parameter: the unnormalised rays of a point light measure
the whole segment as 1) where it is shorter than the truth's. The argument is not exact, hence
the margin: a caster that covers no texel centre of the kernel (thinner than a texel) is not in
the map at all, and a caster sloped steeply across the kernel lies nearer the light at P's uv
than at the texel centres where it was stored; either can sit just in front of d_min, and a
ray stopped there misses it where the full segment would not (a triangle soup of small,
randomly tilted triangles needs tens of texels). ``shorten=false`` traces the whole segment.

Area lights are not handled (``LIGHTS`` is the hard types): the soft form (a blocker-search
region as the classifier, stratified rays for the uncertain pixels) is left for later.

Stats: ``rays`` traced per render, ``rays_per_pixel`` (rays / evaluated pixels: the truth traces
1), ``uncertain_pixels`` (evaluated pixels the map was unsure of), ``traced_pixels`` (those in
traced tiles) and ``dropped_pixels`` (those left to the nearest tap), ``memory_bytes`` (the
depth atlas and the class image), ``passes``. :meth:`HybridRT.component_images` gives the
classifier's answer per pixel, so that its own error can be measured against the truth.
"""
from __future__ import annotations

import numpy as np

from ...gpu import glstate, programs, targets
from ...gpu.glstate import PassState
from ...truth.tracing import caster_scene, occluded, offset_origins
from ..base import FIRST, MAX, SUM, Param, PlotStyle, Technique, TuneRange
from .toolkit import ATLAS_DEFINES, GBUFFER_TAPS, Atlas, depth_pass, fit_light_views
from .contact import ContactShadows

#: Screen tiles the cut-off counts uncertain pixels in (AMD's 8x8 tiles), pixels on a side.
TILE = 8
#: The class image's values (hybrid_rt_classify.glsl's CLASS_*).
CLASS_LIT, CLASS_SHADOWED, CLASS_UNCERTAIN = 1.0, 0.0, 0.5


class HybridRT(ContactShadows, Technique):
    """Hybrid ray-traced shadows (module docstring): a shadow map's (2r+1)² kernel classifies
    each pixel as surely lit, surely shadowed or uncertain; uncertain pixels of tiles that pass
    the cut-off get the truth's own shadow ray, optionally shortened by the map's depth."""

    name = "hybrid_rt"
    summary = ("hybrid ray-traced shadows (AMD FidelityFX Hybrid Shadows): a shadow map classifies pixels, "
               "Embree rays only for the uncertain ones")
    PARAMS = {
        "resolution": Param(2048, "shadow map width and height in texels (per cube face)", min=16, max=16384,
                            # a coarse map leaves more pixels uncertain (more rays); 8192 is a cube atlas's limit
                            tune=TuneRange(128, 8192, log=True)),
        "spread": Param(1, "classification kernel radius r in texels: (2r+1)^2 taps must agree for a pixel to "
                           "be called sure (0: the nearest tap alone, never uncertain: a plain shadow map)",
                        min=0, max=8,
                        # 1-2 texels cover the map's aliasing; past 3 most of the penumbra-free image is traced
                        tune=TuneRange(0, 3)),
        "cutoff": Param(0, "tiles of 8x8 pixels with fewer uncertain pixels than this take the nearest tap's "
                           "answer instead of rays (0: trace every uncertain pixel; 65: trace none)",
                        min=0, max=TILE * TILE + 1,
                        # AMD's cut-off drops tiles with a handful of uncertain pixels; 16 already drops edges
                        tune=TuneRange(0, 16)),
        "shorten": Param(True, "shorten each ray to the distance (from the point towards the light) of the "
                               "kernel's smallest stored depth plus a margin: nearer casters would be in the map"),
        "margin": Param(64.0, "shorten: how far past the kernel's smallest stored depth each ray still looks, in "
                               "world texels at that depth (plus the bias's world size)",
                        min=0.0, max=1e6,
                        # 4 texels already misses tilted sub-texel triangles (sv_soup); past a few hundred
                        # texels the rays are hardly shortened at all
                        tune=TuneRange(1.0, 512.0, log=True)),
        "bias": Param(0.002, "constant depth bias of the classifier: on perspective maps a distance towards the "
                             "light, as a fraction of the scene's extent; on orthographic maps window depth "
                             "(a fraction of the depth range): shadow_map's bias_space=world",
                      # as shadow_map's: acne below ~1e-6, 0.05 detaches every contact
                      min=0.0, max=1.0, tune=TuneRange(1e-6, 0.05, log=True)),
        "depth_bits": Param(24, "depth format: 16 / 24 fixed point, 32 float", choices=(16, 24, 32)),
    }
    PASSES = ("depth", "classify", "trace")
    LIGHTS = frozenset({"point", "spot", "directional", "target_direct"})
    #: Rays and pixels are work per render; the memory a peak; rays_per_pixel describes the one
    #: light it is measured for (the technique is not light-sampled).
    STATS = {"rays": SUM, "rays_per_pixel": FIRST, "uncertain_pixels": SUM, "traced_pixels": SUM,
             "dropped_pixels": SUM, "memory_bytes": MAX, "passes": SUM}
    STYLE = PlotStyle("#6b6ecf", "P")
    READS = frozenset({"position"})  # the classifier needs the point only (no normal offset)
    #: The depth and classification passes run on the GPU (finished around their timing); the
    #: trace pass is timed as CPU work (timed_pass(cpu=True)).
    cpu = False

    def setup(self, frame, slot) -> None:
        """Fit the map, allocate the atlas and the class image, set the classifier's uniforms;
        the truth's Embree scene and offset origins of the evaluated pixels."""
        from ...truth import compiled as compiled_truth

        compiled_truth.warm()  # the truth's compiled passes (ray directions) loaded here, not in a timed render
        faces, notes = fit_light_views(frame, slot, self.resolution)
        self.notes.extend(notes)
        self.atlas = Atlas.grid(faces, self.resolution, self.name)
        self.map = self.own(targets.DepthTexture.create(self.atlas.size, self.depth_bits))
        self.depth_prog = self.program("shadow_depth.glsl")
        self.class_prog = self.program("hybrid_rt_classify.glsl", defines=dict(ATLAS_DEFINES))
        face = self.atlas.faces[0]
        perspective = face.proj[3, 3] != 1.0
        extent = float(frame.scene.extent())
        # shadow_map's bias_space=world: a world distance on perspective maps, window depth on
        # orthographic ones (there one world distance everywhere: bias x the depth range)
        bias_window, bias_world = (0.0, self.bias * extent) if perspective else (float(self.bias), 0.0)
        margin_bias = bias_world if perspective else float(self.bias) * float(face.depth_range)
        programs.set_uniforms(self.class_prog, self.light.uniforms())
        self.atlas.write_uniforms(self.class_prog)
        programs.set_uniforms(self.class_prog, {
            "u_map": len(self.READS), "u_bias": bias_window, "u_bias_world": bias_world,
            "u_spread": int(self.spread), "u_texel_world": float(face.texel_world),
            "u_texel_angle": float(face.texel_angle), "u_margin_texels": float(self.margin),
            "u_margin_bias": margin_bias})
        self.quad = self.fullscreen_quad(self.class_prog)
        size = (frame.width, frame.height)
        self.class_tex = self.own(frame.ctx.texture(size, 4, dtype="f4"))
        self.class_fbo = self.own(frame.ctx.framebuffer(color_attachments=[self.class_tex]))
        # the truth's rays: its Embree scene of the casters and its offset origins
        self.scene = caster_scene(frame) if frame.has_casters else None
        self.evaluated = slot.evaluated
        self.eval_index = np.flatnonzero(slot.evaluated)
        self.eval_pixels = frame.pixel_index[self.eval_index]  # row-major pixel of each, row 0 = top
        self.eval_origins = np.ascontiguousarray(offset_origins(frame)[self.eval_index])
        self.eval_points = frame.compact_position[self.eval_index]
        tile_cols = -(-frame.width // TILE)
        rows, cols = np.divmod(self.eval_pixels, frame.width)
        self.eval_tiles = (rows // TILE) * tile_cols + cols // TILE
        self.tiles = tile_cols * -(-frame.height // TILE)
        self.cls = np.full(len(self.eval_index), CLASS_LIT, np.float32)
        self.result = np.ones(len(self.eval_index), np.float32)
        self.counts = {"rays": 0, "uncertain": 0, "traced": 0, "dropped": 0}

    def render(self) -> None:
        """Depth from the light, the classification pass, then (CPU) the tile cut-off and the
        shadow rays of the uncertain pixels of the traced tiles."""
        with self.timed_pass("depth"):
            depth_pass(self.frame, self.map, self.depth_prog, self.atlas)
        with self.timed_pass("classify"):
            self.class_fbo.use()
            self.frame.ctx.viewport = (0, 0, self.frame.width, self.frame.height)
            glstate.apply(PassState())
            self.bind_gbuffer(self.class_prog)
            self.map.texture.use(len(self.READS))
            self.quad.render()
        with self.timed_pass("trace", cpu=True):
            self._trace(targets.read_texture(self.class_tex, 4).reshape(-1, 4)[self.eval_pixels])

    def _trace(self, classified: np.ndarray) -> None:
        """From the evaluated pixels' (class, nearest tap, reach, -) rows: the cut-off per tile,
        then one shadow ray per uncertain pixel of a traced tile; fills :attr:`cls`,
        :attr:`result` and :attr:`counts`."""
        cls, nearest, reach = classified[:, 0], classified[:, 1], classified[:, 2]
        uncertain = cls == CLASS_UNCERTAIN
        result = np.where(uncertain, nearest, cls).astype(np.float32)
        per_tile = np.bincount(self.eval_tiles[uncertain], minlength=self.tiles)
        traced = uncertain & (per_tile[self.eval_tiles] >= self.cutoff)
        idx = np.flatnonzero(traced)
        if len(idx) and self.scene is not None:
            origins = self.eval_origins[idx]
            dirs, tfar = self.light.shadow_rays(origins, self.eval_points[idx])
            if self.shorten:
                # reach is a world distance from P; the ray's parameter measures |dir| per unit
                dist = reach[idx]
                length = np.sqrt(np.einsum("ij,ij->i", dirs.astype(np.float64), dirs.astype(np.float64)))
                short = np.where(dist >= 0, dist / length, np.inf)
                tfar = np.minimum(tfar, short).astype(np.float32)
            result[idx] = np.where(occluded(self.scene, origins, dirs, tfar), 0.0, 1.0)
        self.cls, self.result = cls, result
        self.counts = {"rays": int(len(idx)) if self.scene is not None else 0, "uncertain": int(uncertain.sum()),
                       "traced": int(len(idx)), "dropped": int(uncertain.sum() - len(idx))}

    def visibility(self) -> np.ndarray:
        """Float32 (H, W), row 0 = top: the classifier's sure answers, the rays' where traced,
        the nearest tap's in dropped tiles; 1 on pixels that are not evaluated."""
        vis = np.ones(len(self.evaluated), np.float32)
        vis[self.eval_index] = self.result
        return self.frame.to_image(vis, fill=1.0)

    def component_images(self) -> dict[str, np.ndarray]:
        """{"classifier": float32 (H, W), row 0 = top}: 1 where the map called the pixel surely
        lit, 0 surely shadowed, NaN where it was uncertain (traced or in a dropped tile) and
        where the pixel is not evaluated — what the classifier's own error is measured on."""
        answer = np.where(self.cls == CLASS_UNCERTAIN, np.nan, self.cls).astype(np.float32)
        out = np.full(len(self.evaluated), np.nan, np.float32)
        out[self.eval_index] = answer
        return {"classifier": self.frame.to_image(out, fill=np.nan)}

    def work(self, counted: dict, stats: dict) -> dict:
        """Texture taps of the classification (the G-buffer's position and normal, the kernel's
        (2r+1)² texels and the nearest one again) and the shadow rays traced."""
        taps = self.taps_work(counted, {"classify": GBUFFER_TAPS + (2 * self.spread + 1) ** 2 + 1})
        return {**taps, "trace": {"rays": stats["rays"]}}

    def stats(self) -> dict:
        """Rays, rays per evaluated pixel, uncertain / traced / dropped pixels, memory (depth
        atlas and class image) and passes (one depth pass per face, the classification, the
        trace)."""
        evaluated = max(1, len(self.eval_index))
        return {"rays": self.counts["rays"], "rays_per_pixel": self.counts["rays"] / evaluated,
                "uncertain_pixels": self.counts["uncertain"], "traced_pixels": self.counts["traced"],
                "dropped_pixels": self.counts["dropped"],
                "memory_bytes": int(self.map.nbytes + self.frame.width * self.frame.height * 16),
                "passes": len(self.atlas.faces) + 2}
