"""Virtual shadow maps: a huge virtual depth map of which only the pages the view needs exist.

After Unreal Engine 5's virtual shadow maps (Epic Games, "Virtual Shadow Maps", Unreal Engine 5
documentation, 2022; the idea goes back to Lefohn, Sengupta & Owens 2007, "Resolution-matched
shadow maps", ACM TOG 26(4), and Fernando et al. 2001, "Adaptive shadow maps"): one light view
of ``virtual_resolution``² texels (default 16384²) split into pages of ``page_size``² texels
(default 128²), with a mip pyramid of levels m = 0 .. M−1 (level m has V / 2^m texels per side)
or, for directional lights, clipmap levels centred on the camera (``fit=clipmap``, below).
Only pages that visible pixels need get memory, from a physical pool of ``pool_pages`` pages in
one depth texture, and the lookup finds them through a page table.

Passes (``shadowlab/techniques/maps/virtual_request.glsl``, ``shadowlab/techniques/maps/virtual_lookup.glsl``, the depth pass is
``shadowlab/techniques/maps/shadow_depth.glsl``):

1. ``request`` (compute): every evaluated G-buffer pixel computes the level whose texels are
   about its own size, m = clamp(floor(log2(pixel world footprint / level-0 texel) +
   ``lod_bias``), 0, M−1) — pixel footprint = distance to the eye × 2·tan(fov/2)/height, the
   level-0 texel ``texel_world`` (orthographic) or ``texel_angle`` × distance from the light
   (perspective) — and marks that page, and the page of the coarsest level, in a request mask of
   one uint per page per level;
2. ``allocate`` (CPU): the mask is read back; the requested pages get physical slots from the
   coarsest level down, so that when the pool is too small the excess *fine* pages are dropped
   (``pages_dropped``, a note) and their pixels fall back to a coarser resident level (UE5 also
   falls back to coarser mips); the page table (one R32I texture: level m's pages in rows
   ``table_row[m]`` ..) is written;
3. ``depth``: every resident page is cleared and rendered in its slot's viewport
   through its own sub-projection — the level's projection followed by the 2D scale and
   translation in NDC that maps the page's uv rectangle onto the viewport — with the casters
   whose bounding boxes miss the page's sub-frustum culled per object on the CPU (the 8 corners
   against the page's four side planes in clip space);
4. ``lookup``: a full-screen pass over the G-buffer: the wanted level as in (1), walked up to the
   finest resident level, the page table, then the physical texel compared with constant
   ``bias`` plus ``slope_scale`` × the receiver's depth change over one texel of that level
   (shadow_map's ``slope`` variant; ``shadowlab/techniques/maps/receiver_plane.glsl``). Points off the virtual
   map are lit, as with shadow_map.

The light view is shadow_map's default fit (:func:`shadowlab.techniques.maps.toolkit.fit_light_views`
at the virtual resolution, ``fit=shadowable``): directional, target-direct and spot lights, and
point lights as one perspective frustum or a cube (``projection``, ``auto`` as shadow_map). A
cube is six virtual maps, one per face (the face of the major axis of light-to-point, as
``shadowlab/techniques/maps/cube_face.glsl``), sharing the pool: page keys are (face, level, x, y), the request
mask and the page table hold the six faces one after the other. Area lights: light-sampled,
like shadow_map.

Deviations from UE5's design:

- the mip pyramid is the default for every light type; UE5 uses clipmaps for directional
  lights (``fit=clipmap`` below) and mips for local lights. In the pyramid the number of levels
  is derived, not a parameter: M = log2(V / P) + 1, so the coarsest level is a single page
  (every pixel's fallback, requested by every pixel);
- page caching (``cache=true``, in animations): :class:`shadowlab.techniques.maps.page_cache.PageCache` keeps the pages from frame to
  frame, keyed by (face, level, light-space page) with a signature of the level's view and the
  casters over the page; only pages whose signature changed are rendered again. Only
  ``fit=scene`` and ``fit=clipmap`` keep pages while the camera moves (``fit=shadowable``'s view
  follows the view);
- each rendered page is cleared by a quad writing gl_FragDepth (``shadowlab/techniques/maps/page_clear.glsl``) over its
  viewport, as UE5 clears only the pages it renders (a glClear of the whole pool costs every
  render the pool's size, however few pages it renders; the lab keeps the scissor test off);
- pages are dropped within a level in page order (UE5 has no single rule here either; it
  reports the overflow); casters are culled per object, not per cluster (Nanite);
- no per-page depth ranges or HZB culling, no filtering (nearest, one tap: UE5 uses SMRT).
- the level follows distance only (pixel size over texel size at the point), as UE5's does: a
  receiver at a grazing angle to the light or the camera gets texels longer than a pixel along
  one axis (the texel footprint's tail above a pixel on sun_scene); texels about a pixel wide
  also mean a larger boundary error than a 2048² map's tenth-of-a-pixel texels on small scenes
  (sun_scene; with ``lod_bias=-1``, finer pages, it falls below the 2048² map's).

Clipmaps (``fit=clipmap``, directional lights only; UE5's "clipmap" levels, Epic Games 2022,
"Virtual Shadow Maps": each level a full virtual map, twice the previous one's side, centred on
the camera and snapped to whole pages so that pages stay put while it moves): K =
``clipmap_levels`` levels, level k an orthographic square along the light of side
``clip_extent`` · 2^k with V² texels in (V/P)² pages, centred on the camera's eye projected into
light space (fit=scene's light space, which does not move) and snapped to whole pages of that
level; the depth range, the scene's bounds along the light, is every level's. ``clip_extent``
auto (0) = the scene's light-space side × (V/P) / 2^(K−1): the coarsest level's texel is
fit=scene's coarsest mip's (scene side / P), so pixels far away get texels as coarse as the
pyramid's, and levels finer than fit=scene's level 0 exist for K > log2(V/P) + 1 (default K = 12:
4 levels finer, 16× at level 0). The shaders see level k's uv as level 0's uv × 2^−k + an offset
of whole pages (``virtual_common.glsl``: u_level_uv); the request mask and the page table hold
K × (V/P)² entries (12 × 16384 words with the defaults); the request walks the wanted level up
to the finest level containing the point, the lookup likewise to the finest resident one
containing it. A page is rendered through its own orthographic square in light space (a matrix
that depends only on where it lies) and cached under its light-space page coordinates, so a
level shifted by whole pages keeps every page it still covers (as UE5), and a cached page is
bit-for-bit what rendering it again gives. Against fit=shadowable, clipmaps are as accurate
on pa_long_view (with fewer pages) and sun_scene and less accurate on sm_wires — clipmap texels
are square, while the fitted view's rectangle gives V texels along its short side too (finer
there); over an animated camera dolly (tm_camera_dolly) they render fewer pages than fit=scene,
and caching either renders far fewer than no cache (docs/resolution.md). Not done: UE5's first/last clipmap level in world
units (K is a count), its coarse-page marking and per-page depth ranges.

Texel footprint (:class:`~shadowlab.techniques.maps.toolkit.TexelMapping`): supported — the texel
coordinates of a point are those of the level its reference point actually uses (the wanted
level walked up the page table as the lookup does), in that level's texels.
"""
from __future__ import annotations

import hashlib

import numpy as np

from ...gpu import glstate, programs, targets
from ...geometry.bounds import box_corners
from ...geometry.frusta import LightView
from ...geometry.transforms import BIAS
from ...gpu.glstate import PassState
from ...scene.lights import DirectionalLight
from ..base import FIRST, MAX, SUM, Param, PlotStyle, Technique, TechniqueError, TuneRange
from .page_cache import PageCache
from .toolkit import (
    ATLAS_DEFINES, CLEAR_DEPTH, MAX_FACES, TexelMapping, check_texture_size, cube_face_index,
    fit_light_views, map_texel_coordinates,
)
from .contact import ContactShadows

#: Size of the per-level uniform arrays of the shaders (``MAX_LEVELS``): V / P ≤ 2^15 pages.
MAX_LEVELS = 16
#: Faces of a point light's cube (``geometry.frusta.CUBE_FACES``): six virtual maps.
CUBE = 6
#: Compute invocations per work-group side of the request pass (8 × 8 pixels a group).
LOCAL_SIZE = 8
#: Storage-buffer binding of the request mask (``virtual_request.glsl``: BINDING_REQUESTS).
BINDING_REQUESTS = 0
#: A page-table entry of a page with no physical page (``virtual_common.glsl``: NOT_RESIDENT).
NOT_RESIDENT = -1
#: Bytes per texel of each depth format (24-bit depth is stored in 4 bytes) and of a page-table entry.
DEPTH_BYTES = {16: 2, 24: 4, 32: 4}
TABLE_BYTES = 4
#: Bytes of the digests that key cached pages (BLAKE2b, RFC 7693): a collision between two
#: different page contents has probability about 2^-128 per pair.
DIGEST_BYTES = 16
#: Corners of a box, and homogeneous clip coordinates (x, y, z, w).
BOX_CORNERS, CLIP_W = 8, 3
#: fit=clipmap: levels K by default. With clip_extent auto the coarsest level's texel is fit=scene's
#: coarsest mip texel (the scene's side / page_size), so the levels above log2(V/P) + 1 from the top
#: are finer than any of fit=scene's: 4 extra levels (12 with V/P = 128) reach texels 16× finer
#: than fit=scene's level 0 near the camera, at 12 × (V/P)² mask words (196608: 768 KiB).
DEFAULT_CLIPMAP_LEVELS = 12
#: Per-level uv transform of the shaders (``virtual_common.glsl``: u_level_uv): scale, offset u, v, unused.
LEVEL_UV = 4


def digest(*parts) -> bytes:
    """A :data:`DIGEST_BYTES`-byte BLAKE2b digest of ``parts`` (bytes, or values whose repr is
    stable): what a cached page's signature is built from."""
    h = hashlib.blake2b(digest_size=DIGEST_BYTES)
    for part in parts:
        h.update(part if isinstance(part, bytes) else repr(part).encode())
    return h.digest()


def _power_of_two(value: int) -> bool:
    return value > 0 and value & (value - 1) == 0


class VirtualMap(ContactShadows, TexelMapping, Technique):
    """UE5-style virtual shadow map (module docstring): pages requested by the visible pixels,
    allocated from a fixed pool, rendered one viewport each, looked up through a page table."""

    name = "virtual_map"
    summary = ("virtual shadow map (UE5 2022; Lefohn et al. 2007): a 16384² virtual map in 128² pages over a mip "
               "pyramid or, for a sun, clipmaps around the camera; only the pages visible pixels request are "
               "allocated from a fixed pool and rendered, and kept across animation frames")
    STYLE = PlotStyle("#8c564b", "p")
    LIGHT_SAMPLED = True  # area lights: averaged over light samples like shadow_map
    PASSES = ("request", "allocate", "depth", "lookup")
    READS = frozenset({"position", "normal"})
    PROVIDES = frozenset({"texel_mapping"})
    PARAMS = {
        "virtual_resolution": Param(16384, "virtual map width and height in texels (level 0; a power of two)",
                                    min=16, max=2 ** 20, tune=TuneRange(2048, 65536, log=True)),
        "page_size": Param(128, "page width and height in texels (a power of two dividing virtual_resolution)",
                           min=8, max=4096),
        "pool_pages": Param(1024, "physical pages in the pool (a square depth texture of ceil(sqrt(n)) pages a side)",
                            min=1),
        "lod_bias": Param(0.0, "added to log2(pixel / level-0 texel) before flooring: < 0 finer pages, > 0 coarser",
                          # a level is a factor 2 in texel size; ±MAX_LEVELS pins every pixel to level 0 or
                          # M-1; tuning beyond ±2 levels trades a factor 4 in pages per step for nothing
                          min=-float(MAX_LEVELS), max=float(MAX_LEVELS), tune=TuneRange(-2.0, 2.0)),
        "bias": Param(0.0005, "constant depth bias: with bias_space=world on a perspective map a distance towards "
                              "the light, as a fraction of the scene's extent; else window-depth units [0, 1]",
                      # as cascaded_map: the slope term carries the receiver's slope
                      min=0.0, max=1.0, tune=TuneRange(1e-6, 0.05, log=True)),
        # Window depth by default: the slope term dominates here, and over the shipped perspective scenes
        # a world bias of 0.0005 x the extent lowered sm_lamp_contact's error but raised sv_open_mesh's
        # (the committed rows: docs/techniques/virtual_map.md, "Measured"; docs/tuning.md).
        "bias_space": Param("window", "what bias measures, as shadow_map's: world (a distance towards the light "
                                      "converted at each receiver on perspective maps; orthographic maps keep window "
                                      "depth, linear there) or window", choices=("world", "window")),
        "slope_scale": Param(2.0, "multiple of the receiver's depth change over one texel of the level used",
                             min=0.0, max=1e4, tune=TuneRange(0.0, 16.0)),
        "depth_bits": Param(24, "pool depth format: 16 / 24 fixed point, 32 float", choices=(16, 24, 32)),
        "projection": Param("auto", "point lights: cube (six virtual maps), frustum (one), auto (as shadow_map)",
                            choices=("auto", "cube", "frustum")),
        "fit": Param("shadowable", "the light view covers what can be shadowed in this view (shadowable, as "
                                   "shadow_map), or the whole scene (scene: fixed in light space while the camera "
                                   "moves, so pages can be kept from frame to frame); clipmap (directional lights): "
                                   "UE5's nested full-resolution levels centred on the camera, snapped to pages",
                     choices=("shadowable", "scene", "clipmap")),
        "clipmap_levels": Param(DEFAULT_CLIPMAP_LEVELS, "fit=clipmap: levels K (level k covers clip_extent·2^k)",
                                min=1, max=MAX_LEVELS),
        "clip_extent": Param(0.0, "fit=clipmap: side of level 0 in world units; 0: auto, the scene's light-space "
                                  "side × (V/P) / 2^(K−1) (the coarsest level's texel is fit=scene's coarsest mip's)",
                             min=0.0),
        "cache": Param(True, "in animations, keep rendered pages from frame to frame and re-render only those "
                             "whose view or casters changed (UE5's page caching)"),
    }
    STATS = {"resident_pages": MAX, "resident_memory_bytes": MAX, "pool_memory_bytes": MAX,
             "pages_requested": SUM, "pages_rendered": SUM, "pages_cached": SUM, "pages_dropped": SUM,
             "caster_draws": SUM,
             "levels": FIRST, "faces": FIRST, "memory_bytes": MAX, "dense_equivalent_bytes": MAX, "texel_world": FIRST}

    def __init__(self, **params):
        super().__init__(**params)
        if not _power_of_two(self.virtual_resolution):
            raise TechniqueError(f"{self.name}: virtual_resolution must be a power of two, got "
                                 f"{self.virtual_resolution}")
        if not _power_of_two(self.page_size):
            raise TechniqueError(f"{self.name}: page_size must be a power of two, got {self.page_size}")
        if self.page_size > self.virtual_resolution:
            raise TechniqueError(f"{self.name}: page_size ({self.page_size}) must divide virtual_resolution "
                                 f"({self.virtual_resolution})")
        #: Pages per side of level 0, and the levels (the coarsest is one page).
        self.pages0 = self.virtual_resolution // self.page_size
        #: fit=clipmap: every level is a full virtual map of pages0² pages (UE5's clipmap levels).
        self.clipmap = self.fit == "clipmap"
        self.levels = self.clipmap_levels if self.clipmap else self.pages0.bit_length()
        if self.levels > MAX_LEVELS:
            raise TechniqueError(f"{self.name}: virtual_resolution / page_size = {self.pages0} pages a side needs "
                                 f"{self.levels} levels, more than {MAX_LEVELS}; raise page_size")
        pages = [self.pages0 if self.clipmap else self.pages0 >> m for m in range(self.levels)]
        #: Pages per side of each level.
        self.level_pages = np.asarray(pages, int)
        #: Per level: first word of its pages in the request mask, first row in the page table.
        self.mask_offset = np.concatenate([[0], np.cumsum([n * n for n in pages])]).astype(int)
        self.table_row = np.concatenate([[0], np.cumsum(pages)]).astype(int)
        self.pool_side = int(np.ceil(np.sqrt(self.pool_pages)))

    def _bias_uniforms(self) -> dict:
        """``u_bias`` (window depth) and ``u_bias_world`` (world distance) of the lookup: with
        ``bias_space=world`` on a perspective map, ``bias`` × the scene's extent converted at
        each receiver (as shadow_map's); else ``bias`` in window depth."""
        if self.bias_space == "world" and self.faces[0].proj[3, 3] != 1.0:
            return {"u_bias": 0.0, "u_bias_world": float(self.bias) * float(self.frame.scene.extent())}
        return {"u_bias": float(self.bias), "u_bias_world": 0.0}

    # -- setup ---------------------------------------------------------------------
    def setup(self, frame, slot) -> None:
        """Fit the level-0 view, make the pool, the page table, the request mask and the programs."""
        ctx = frame.ctx
        if self.clipmap:
            faces, notes = self._clipmap_views(frame, slot)
        elif self.fit == "scene":
            # the whole scene's bounds: a view that does not follow the camera (cacheable pages)
            faces, notes = slot.light.shadow_views(box_corners(frame.scene.bounds()[None]), frame.casters(),
                                                   self.virtual_resolution, projection=self.projection)
        else:
            faces, notes = fit_light_views(frame, slot, self.virtual_resolution, self.projection)
        self.notes.extend(notes)
        #: The level-0 view of each virtual map: one, or a point light's six cube faces.
        self.faces = faces
        self.view = faces[0]
        self.perspective = self.view.proj[3, 3] != 1.0
        self.light_matrices = [BIAS @ face.view_proj for face in faces]
        if not self.clipmap:  # the mip pyramid: every level is level 0's uv, 2^m coarser
            self.level_scale = np.ones(self.levels)
            self.level_offset = np.zeros((self.levels, 2))
            self.level_origin = np.zeros((self.levels, 2), np.int64)
        self.face_words = int(self.mask_offset[-1])
        self.face_rows = int(self.table_row[-1])
        pool_size = (self.pool_side * self.page_size,) * 2
        check_texture_size(pool_size, self.name, "page pool", "lower pool_pages or page_size")
        self.table_shape = (len(faces) * self.face_rows, self.pages0)  # (rows, columns)
        check_texture_size(self.table_shape[::-1], self.name, "page table", "raise page_size")
        # The pool and what its slots hold outlive this frame only while caching in an animation
        # (Technique.keep); the cache is per light slot and starts empty when the pool is made.
        caching = self.cache and self.keep_across_frames
        if caching:
            key = ("pool", slot.index, pool_size, self.depth_bits)
            self.pool = self.keep(key, lambda: targets.DepthTexture.create(pool_size, self.depth_bits))
            self.page_cache = self.keep(("pages", slot.index), PageCache)
            if self.page_cache.pool is not self.pool:
                self.page_cache.reset(self.pool, self.pool_pages)
        else:
            self.pool = self.own(targets.DepthTexture.create(pool_size, self.depth_bits))
            self.page_cache = PageCache()
            self.page_cache.reset(self.pool, self.pool_pages)
        # Every render of this frame starts from the cache as the frame found it: repeated timed
        # renders do the frame's work each time (without caching: every page, every render).
        self.cache_at_frame_start = self.page_cache.state()
        self.table_tex = self.own(ctx.texture((self.pages0, self.table_shape[0]), 1, dtype="i4"))
        self.table_tex.filter = (ctx.NEAREST, ctx.NEAREST)
        self.mask_words = len(faces) * self.face_words
        self.requests = self.own(ctx.buffer(reserve=4 * self.mask_words))
        evaluated = frame.evaluated_image(slot)[::-1]  # GL rows run bottom-up
        self.evaluated_tex = self.own(ctx.texture((frame.width, frame.height), 1,
                                                  np.ascontiguousarray(evaluated, np.uint8).tobytes(), dtype="u1"))
        self.evaluated_tex.filter = (ctx.NEAREST, ctx.NEAREST)
        level_uv = np.zeros((MAX_LEVELS, LEVEL_UV), np.float32)
        level_uv[:self.levels, 0] = self.level_scale
        level_uv[:self.levels, 1:3] = self.level_offset
        common = {**self.light.uniforms(), "u_levels": self.levels, "u_level_uv": level_uv,
                  "u_level_pages": np.asarray(self._padded_levels(self.level_pages), np.int32),
                  "u_texel_world": float(self.view.texel_world), "u_texel_angle": float(self.view.texel_angle),
                  "u_camera_eye": tuple(map(float, frame.camera.eye)), "u_pixel_angle": self._pixel_angle(),
                  "u_lod_bias": float(self.lod_bias), "u_faces": len(faces)}
        defines = {**ATLAS_DEFINES, "MAX_LEVELS": MAX_LEVELS}
        matrices = self.light_matrices + [np.eye(4)] * (MAX_FACES - len(faces))
        self.request_prog = self.program("virtual_request.glsl",
                                         defines={**defines, "LOCAL_SIZE": LOCAL_SIZE,
                                                  "BINDING_REQUESTS": BINDING_REQUESTS})
        self.lookup_prog = self.program("virtual_lookup.glsl", defines=defines)
        for prog in (self.request_prog, self.lookup_prog):
            programs.set_uniforms(prog, common)
            prog["u_light_matrix"].write(b"".join(programs.mat_bytes(m) for m in matrices))
        programs.set_uniforms(self.request_prog, {"u_evaluated": 1,
                                            "u_mask_offset": self._padded_levels(self.mask_offset),
                                            "u_face_words": self.face_words})
        programs.set_uniforms(self.lookup_prog, {
            "u_pool": 2, "u_page_table": 3,
            "u_table_row": self._padded_levels(self.table_row), "u_face_rows": self.face_rows,
            "u_pool_side": self.pool_side,
            "u_page_size": self.page_size, "u_virtual_resolution": float(self.virtual_resolution),
            **self._bias_uniforms(), "u_slope_scale": float(self.slope_scale)})
        self.depth_prog = self.program("shadow_depth.glsl")
        self.clear_prog = self.program("page_clear.glsl")
        programs.set_uniforms(self.clear_prog, {"u_depth": CLEAR_DEPTH})
        self.clear_quad = self.fullscreen_quad(self.clear_prog)
        self.quad = self.fullscreen_quad(self.lookup_prog)
        self.vis_tex, self.vis_fbo = self.visibility_target((frame.width, frame.height))
        self._caster_clip_corners(frame)
        #: The page table (physical slot per (face, level, y, x) row/column; NOT_RESIDENT: none).
        self.table = np.full(self.table_shape, NOT_RESIDENT, np.int32)
        self.counts = {"requested": 0, "resident": 0, "rendered": 0, "cached": 0, "dropped": 0, "draws": 0}
        # What a kept page's content depends on: every face's light view and the virtual layout;
        # per page, the casters over it and their geometry (checked per page when it is reused).
        # Clipmap levels (_clipmap_views) are keyed per level on what does not move with the camera:
        # pages are cached under their absolute page coordinates, so a level shifted by whole pages
        # keeps the pages it still covers (UE5's clipmap page caching).
        layout = (self.virtual_resolution, self.page_size, self.depth_bits)
        if not self.clipmap:
            self.level_keys = [digest(*(f.view_proj.tobytes() for f in faces), *layout)] * self.levels
        self.caster_keys = np.array([digest(np.asarray(o.vertices).tobytes()) for o in frame.scene.objects
                                     if o.casts], f"S{DIGEST_BYTES}")

    def _clipmap_views(self, frame, slot):
        """fit=clipmap: the level-0 view, and per level its uv transform from level 0's uv, its
        page origin and its cache key (UE5's directional-light clipmap, Epic Games 2022, "Virtual
        Shadow Maps": levels centred on the camera, each twice the previous one's side, origins
        snapped to whole pages so that pages stay put while the camera moves).

        Light space is fit=scene's view (along the light from the scene's centre: it does not
        move with the camera), and its depth range, the scene's bounds along the light, is every
        level's. Level k is the square of side ``clip_extent`` · 2^k whose lower-left corner is
        o_k pages of that level, o_k = round(eye / page side) − (V/P)/2: the camera's eye projected
        into light space, snapped to the level's pages. A point's level-k uv is level 0's uv
        · 2^−k + (o_0 · 2^−k − o_k) / (V/P) (exact: powers of two and whole pages)."""
        if not isinstance(slot.light, DirectionalLight):
            raise TechniqueError(f"{self.name}: fit=clipmap is for directional lights (UE5's clipmap); this "
                                 f"{type(slot.light).__name__} needs fit=shadowable or fit=scene")
        faces, notes = slot.light.shadow_views(box_corners(frame.scene.bounds()[None]), frame.casters(),
                                               self.virtual_resolution)
        scene = faces[0]
        #: fit=scene's view: the light space every level lives in, and its depth rows.
        self.scene_view = scene
        scene_side = scene.texel_world * self.virtual_resolution
        extent0 = self.clip_extent or scene_side * self.pages0 / 2.0 ** (self.levels - 1)
        #: Per level: side (world units), page side, page origin (whole pages, light space).
        self.level_side = extent0 * np.exp2(np.arange(self.levels))
        self.level_page_side = self.level_side / self.pages0
        eye = (scene.view @ np.append(np.asarray(frame.camera.eye, np.float64), 1.0))[:2]
        self.level_origin = (np.floor(eye[None] / self.level_page_side[:, None] + 0.5).astype(np.int64)
                             - self.pages0 // 2)
        self.level_scale = np.exp2(-np.arange(self.levels, dtype=np.float64))
        self.level_offset = (self.level_origin[0][None] * self.level_scale[:, None] - self.level_origin) / self.pages0
        coarsest = self.level_side[-1]
        if coarsest < 2.0 * scene_side:  # a camera inside the scene can then leave part of it uncovered
            notes = notes + [f"fit=clipmap: the coarsest level ({coarsest:.3g} world units a side) may not cover the "
                             f"scene ({scene_side:.3g}) around the camera; raise clip_extent or clipmap_levels"]
        lo = self.level_origin[0] * self.level_page_side[0]
        level0 = LightView(scene.view, self._ortho(scene.proj, lo, self.level_side[0]),
                           texel_world=float(self.level_side[0]) / self.virtual_resolution)
        self.level_keys = [digest(scene.view.tobytes(), scene.proj[2].tobytes(), float(side), self.virtual_resolution,
                                  self.page_size, self.depth_bits) for side in self.level_side]
        return [level0], notes

    @staticmethod
    def _ortho(depth_proj: np.ndarray, lower_left: np.ndarray, side: float) -> np.ndarray:
        """An orthographic projection of the light-space square [lower_left, lower_left + side]²
        with ``depth_proj``'s depth rows (GL's glOrtho matrix: x_ndc = 2(x − l)/(r − l) − 1)."""
        proj = depth_proj.copy()
        proj[0] = [2.0 / side, 0.0, 0.0, -(2.0 * lower_left[0] + side) / side]
        proj[1] = [0.0, 2.0 / side, 0.0, -(2.0 * lower_left[1] + side) / side]
        return proj

    def _pixel_angle(self) -> float:
        """World size of a screen pixel per unit distance from the eye (as Frame.pixel_footprint)."""
        return float(2.0 * np.tan(np.radians(self.frame.camera.fov_y) / 2.0) / self.frame.height)

    @staticmethod
    def _padded_levels(values) -> list[int]:
        """Per-level ints padded to :data:`MAX_LEVELS` (the shaders' array size)."""
        out = [int(v) for v in values[:MAX_LEVELS]]
        return out + [0] * (MAX_LEVELS - len(out))

    def _caster_clip_corners(self, frame) -> None:
        """Per caster object its draw range, and its bounding box's corners in each face's
        level-0 clip space (F, K, 8, 4): a page's culling test is then four comparisons per corner."""
        self.caster_ranges, boxes = [], []
        for obj, rng in zip(frame.scene.objects, frame.object_ranges):
            if obj.casts:
                self.caster_ranges.append(rng)
                boxes.append(obj.bounds())
        if not boxes:
            self.caster_clip = np.zeros((len(self.faces), 0, BOX_CORNERS, 4))
            return
        corners = box_corners(np.stack(boxes)).reshape(-1, BOX_CORNERS, 3)
        homogeneous = np.concatenate([corners, np.ones(corners.shape[:2] + (1,))], axis=2)
        self.caster_clip = np.stack([homogeneous @ face.view_proj.T for face in self.faces])

    # -- rendering -----------------------------------------------------------------
    def render(self) -> None:
        """Request, allocate, render the resident pages, look up."""
        frame, ctx = self.frame, self.frame.ctx
        self.page_cache.restore(self.cache_at_frame_start)
        with self.timed_pass("request"):
            self.requests.clear()
            self.requests.bind_to_storage_buffer(BINDING_REQUESTS)
            glstate.apply(PassState())  # no framebuffer, but no inherited sampler objects on its units
            self.bind_gbuffer(self.request_prog)
            self.evaluated_tex.use(1)
            self.request_prog.run(-(-frame.width // LOCAL_SIZE), -(-frame.height // LOCAL_SIZE))
            ctx.memory_barrier()
        with self.timed_pass("allocate", cpu=True):
            mask = np.frombuffer(self.requests.read(), np.uint32)
            self._allocate(np.flatnonzero(mask))
            self.table_tex.write(self.table.tobytes())
        with self.timed_pass("depth"):
            self._render_pages()
        with self.timed_pass("lookup"):
            self.vis_fbo.use()
            ctx.viewport = (0, 0, frame.width, frame.height)
            glstate.apply(PassState())
            self.bind_gbuffer(self.lookup_prog)
            self.pool.texture.use(2)
            self.table_tex.use(3)
            self.quad.render()

    def _allocate(self, requested: np.ndarray) -> None:
        """Physical slots for the requested pages (indices into the request mask), coarsest
        level first; the excess fine pages are dropped (noted). Pages the cache still holds,
        with the same view and the same casters over them, keep their slot and are not rendered
        again; the others take a free slot or the least recently used one. Fills
        :attr:`table` and :attr:`to_render` (the (slot, face, level, x, y) rows to draw)."""
        face, word = np.divmod(requested, self.face_words)
        level = np.searchsorted(self.mask_offset, word, side="right") - 1
        order = np.lexsort((requested, -level))  # coarsest level first, then face and page order
        coarsest = int(np.sum(level == level.max())) if len(level) else 0
        if coarsest > self.pool_pages:  # some pixels would have no page at all: lit, silently
            raise TechniqueError(f"{self.name}: pool_pages={self.pool_pages} cannot hold the {coarsest} pages of the "
                                 f"coarsest level that every pixel falls back to; raise pool_pages")
        kept = order[:self.pool_pages]
        dropped = len(requested) - len(kept)
        face, level = face[kept], level[kept]
        y, x = np.divmod(word[kept] - self.mask_offset[level], self.level_pages[level])
        pages = np.stack([face, level, x, y], axis=1).astype(np.int64)
        visible = self._visible_casters(pages)
        # a page's signature: its level's view, which casters are over it and their geometry
        signatures = [(self.level_keys[m], np.flatnonzero(v).tobytes(), self.caster_keys[v].tobytes())
                      for m, v in zip(level, visible)]
        absolute = pages.copy()  # cache keys: page coordinates in light space (clipmaps shift by whole pages)
        absolute[:, 2:] += self.level_origin[level]
        slots, fresh = self.page_cache.assign([tuple(p) for p in absolute.tolist()], signatures)
        self.table[:] = NOT_RESIDENT
        self.table[face * self.face_rows + self.table_row[level] + y, x] = np.asarray(slots, np.int32)
        self.to_render = [(slots[i], *absolute[i]) for i in fresh]
        self.to_render_visible = visible[fresh] if len(fresh) else visible[:0]
        if dropped and not self.counts["dropped"]:
            finest = int(level.min()) if len(level) else self.levels - 1
            self.notes.append(f"page pool of {self.pool_pages} pages full: {dropped} of {len(requested)} requested "
                              f"pages dropped (finest level kept: {finest}); their pixels use a coarser resident level")
        self.counts.update(requested=len(requested), resident=len(kept), rendered=len(fresh),
                           cached=len(kept) - len(fresh), dropped=dropped)

    def _page_view_proj(self, face: int, level: int, x: int, y: int) -> np.ndarray:
        """Projection · view that renders page (x, y) of ``level`` — absolute page coordinates
        (level origin + table coordinates): the mip pyramid's crop after the face's projection;
        a clipmap page's own orthographic square in light space, a matrix that depends only on
        where the page lies, so a page cached in an earlier frame is what rendering it now gives."""
        if not self.clipmap:
            return self._page_matrix(level, x, y) @ self.faces[face].view_proj
        side = self.level_page_side[level]
        proj = self._ortho(self.scene_view.proj, np.array([x, y], np.float64) * side, side)
        return proj @ self.scene_view.view

    def _page_matrix(self, level: int, x: int, y: int) -> np.ndarray:
        """The page's sub-projection after the level-0 projection: NDC scaled by 1/s and
        translated so the page's uv square [x·s, (x+1)·s] × [y·s, (y+1)·s] fills [−1, 1]²
        (s = the page's uv size), in homogeneous clip coordinates."""
        s = (self.page_size << level) / self.virtual_resolution
        cx, cy = 2.0 * x * s + s - 1.0, 2.0 * y * s + s - 1.0  # the page's centre in level-0 NDC
        crop = np.eye(4)
        crop[0, 0] = crop[1, 1] = 1.0 / s
        crop[0, 3], crop[1, 3] = -cx / s, -cy / s
        return crop

    def _visible_casters(self, pages: np.ndarray) -> np.ndarray:
        """Bool (R, K): per page (rows of (face, level, x, y)) the casters whose bounding box is not
        wholly outside one side plane of the page's sub-frustum — the homogeneous clip test of
        its 8 corners, linear in them, so valid for corners behind a perspective light too."""
        c = self.caster_clip[pages[:, 0]]                             # (R, K, 8, 4)
        level = pages[:, 1]
        x, y = (pages[:, i].astype(np.float64) for i in (2, 3))
        n, scale = self.level_pages[level], self.level_scale[level]
        s = 1.0 / (n * scale)                                          # the pages' size in level-0 uv
        u0 = 2.0 * (x / n - self.level_offset[level, 0]) / scale - 1.0  # their NDC rectangles in level 0
        v0 = 2.0 * (y / n - self.level_offset[level, 1]) / scale - 1.0
        u1, v1 = u0 + 2.0 * s, v0 + 2.0 * s
        u0, v0, u1, v1 = (v[:, None, None] for v in (u0, v0, u1, v1))
        w = c[..., CLIP_W]
        outside = ((c[..., 0] < u0 * w).all(2) | (c[..., 0] > u1 * w).all(2)
                   | (c[..., 1] < v0 * w).all(2) | (c[..., 1] > v1 * w).all(2))
        return ~outside

    def _slot_viewport(self, slot_index: int) -> tuple[int, int, int, int]:
        """The viewport (x, y, width, height) of physical slot ``slot_index`` in the pool."""
        sy, sx = divmod(slot_index, self.pool_side)
        return sx * self.page_size, sy * self.page_size, self.page_size, self.page_size

    def _render_pages(self) -> None:
        """Clear the slot of each page to render (only those: UE5 clears the pages it renders;
        kept pages keep their depth), then render its casters into it through its
        sub-projection."""
        frame = self.frame
        self.pool.fbo.use()
        glstate.apply(PassState(depth_test=True, depth_func="always", depth_write=True, color_write=False))
        for slot_index, *_ in self.to_render:
            frame.ctx.viewport = self._slot_viewport(slot_index)
            self.clear_quad.render()
        glstate.apply(PassState(depth_test=True, depth_func="<", depth_write=True, color_write=False))
        vao = frame.vertex_array(self.depth_prog)
        draws = 0
        for (slot_index, face, level, x, y), visible in zip(self.to_render, self.to_render_visible):
            if not visible.any():
                continue
            frame.ctx.viewport = self._slot_viewport(slot_index)
            matrix = self._page_view_proj(int(face), int(level), int(x), int(y))
            self.depth_prog["u_light_view_proj"].write(programs.mat_bytes(matrix))
            for k in np.flatnonzero(visible):
                r = self.caster_ranges[k]
                vao.render(vertices=r.count, first=r.first)
                draws += 1
        self.counts["draws"] = draws

    # -- texel mapping -------------------------------------------------------------
    def face_index(self, points: np.ndarray) -> np.ndarray:
        """Int (M,): the virtual map (0, or a cube face as ``cube_face.glsl`` picks it) of each point."""
        return cube_face_index(points, getattr(self.light, "position", None), len(self.faces))

    def used_level(self, points: np.ndarray) -> np.ndarray:
        """Int (M,): the level the lookup uses at world ``points`` (M, 3): the wanted level
        (as ``virtual_common.glsl``'s wanted_level, in float64) walked up to the finest resident
        one; −1 off the map. Valid after :meth:`render`."""
        points = np.asarray(points, np.float64)
        eye = np.asarray(self.frame.camera.eye, np.float64)
        footprint = np.linalg.norm(points - eye, axis=1) * self._pixel_angle()
        if self.perspective:
            texel = self.view.texel_angle * np.linalg.norm(points - self.light.position, axis=1)
        else:
            texel = np.full(len(points), self.view.texel_world)
        with np.errstate(divide="ignore", invalid="ignore"):
            wanted = np.floor(np.log2(footprint / texel) + self.lod_bias)
        level = np.clip(np.nan_to_num(wanted, nan=0.0), 0, self.levels - 1).astype(int)
        face = self.face_index(points)
        homogeneous = np.concatenate([points, np.ones((len(points), 1))], axis=1)
        s = np.einsum("nij,nj->ni", np.stack(self.light_matrices)[face], homogeneous)
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = s[:, :2] / s[:, 3:4]
            depth = s[:, 2] / s[:, 3]
        coarsest = self._level_uv(self.levels - 1, uv)
        inside = (s[:, 3] > 0) & np.all((coarsest >= 0) & (coarsest < 1), axis=1) & (depth >= 0) & (depth <= 1)
        out = np.full(len(points), -1)
        todo = inside.copy()
        for m in range(self.levels):
            n = self.level_pages[m]
            luv = self._level_uv(m, uv)
            page = np.clip(np.floor(luv * n), 0, n - 1).astype(int)
            contained = np.all((luv >= 0) & (luv < 1), axis=1)  # clipmaps: a coarser level beyond its square
            here = todo & (level <= m) & contained
            idx = np.flatnonzero(here)
            row = face[idx] * self.face_rows + self.table_row[m] + page[idx, 1]
            resident = self.table[row, page[idx, 0]] != NOT_RESIDENT
            out[idx[resident]] = m
            todo[idx[resident]] = False
        return out

    def _level_uv(self, m: int, uv: np.ndarray) -> np.ndarray:
        """Level m's uv of level-0 uv (``virtual_common.glsl``: level_uv)."""
        return uv * self.level_scale[m] + self.level_offset[m]

    def texel_coordinates(self, points: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """Float64 (M, 2): texel coordinates of ``points`` in the level each ``reference`` point
        uses (level-0 texel coordinates / 2^m; a clipmap level's: its uv × its V texels); NaN where
        the reference is off the map."""
        level = self.used_level(reference)
        rects = [(0, 0, self.virtual_resolution, self.virtual_resolution)] * len(self.faces)
        t = map_texel_coordinates(self.faces, rects, self.face_index, points, reference)
        m = np.maximum(level, 0)
        texels = (self.level_pages[m] * self.page_size).astype(np.float64)[:, None]  # the level's texels a side
        t = (t / self.virtual_resolution * self.level_scale[m][:, None] + self.level_offset[m]) * texels
        t[level < 0] = np.nan
        return t

    # -- results -------------------------------------------------------------------
    def work(self, counted: dict, stats: dict) -> dict:
        """Texture taps: the request pass reads the G-buffer position and the evaluated mask per
        invocation; each lookup fragment the position and normal, the page table, then one
        texel of the page."""
        return self.taps_work(counted, {"request": 2, "lookup": 4})

    def stats(self) -> dict:
        """Pages requested / resident / rendered / dropped, pool and resident memory against a
        dense map of the virtual resolution, levels, the level-0 texel."""
        depth = DEPTH_BYTES[self.depth_bits]
        page_bytes = self.page_size ** 2 * depth
        pool_bytes = self.pool.nbytes
        return {"resident_pages": int(self.counts["resident"]),
                "resident_memory_bytes": int(self.counts["resident"] * page_bytes),
                "pool_memory_bytes": int(pool_bytes),
                "pages_requested": int(self.counts["requested"]),
                "pages_rendered": int(self.counts["rendered"]),
                "pages_cached": int(self.counts["cached"]),
                "pages_dropped": int(self.counts["dropped"]),
                "caster_draws": int(self.counts["draws"]),
                "levels": int(self.levels),
                "memory_bytes": int(pool_bytes + self.table.size * TABLE_BYTES),
                # a dense clipmap is K full maps
                "dense_equivalent_bytes": int(len(self.faces) * (self.levels if self.clipmap else 1)
                                              * self.virtual_resolution ** 2 * depth),
                "faces": len(self.faces),
                "texel_world": float(self.view.texel_world) or None}
