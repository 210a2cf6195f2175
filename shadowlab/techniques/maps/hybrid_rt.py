"""Hybrid ray-traced shadows: a shadow map classifies every pixel as surely lit, surely shadowed or
uncertain, and Embree shadow rays are traced for the uncertain ones only.

The idea is that of AMD FidelityFX Hybrid Shadows (GPUOpen, FidelityFX SDK: a shadow map marks
what it is sure of, tiles with too few uncertain pixels are left to the map, rays resolve the
rest), and in spirit of NVIDIA's HFTS (Story & Wyman, "HFTS: Hybrid Frustum-Traced Shadows in
The Division", SIGGRAPH 2016 talk: exact, traced hard shadows only where they matter, a
filtered map elsewhere). Here the rays are the truth's own, so wherever a full-length ray is
traced the answer is the truth's bit for bit, and the only errors are the classifier's (a pixel
called sure wrongly), the dropped tiles' and — with ``shorten`` — a shortened ray's (below).

Passes, hard lights (point, spot, directional, target-direct):

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

Area lights (rect, disc, sphere): the same three passes, in PCSS's geometry (Fernando 2005; the map
toolkit's :func:`~shadowlab.techniques.maps.toolkit.light_extents`,
:func:`~shadowlab.techniques.maps.toolkit.height_axis`). One perspective depth map is rendered from the
light's centre C, fitted to every evaluated receiver (pcss's fit). Heights h are measured from C
along the height axis (a one-sided light's normal; a sphere's: the map's axis).

- ``classify`` (CPU, numpy): the receiver P at height h_r, K the light's bounding polytope (rect:
  its corners; disc: the square around it; sphere: the cube around it, with faces across the
  height axis) and h_s the casters' lowest height (the nearest corner of their bounding boxes
  to the light's plane). Every point of a segment from P to the light lies in the convex hull of
  P and K, at a height below h_r (heights are affine along the segment and K lies below h_s <
  h_r); a caster point on it lies at a height >= h_s, so in the hull cut at h_s: the convex
  polygon with vertices P and P + t_i (K_i - P), t_i = (h_r - h_s) / (h_r - h(K_i)) (PCSS's
  search region: the light seen from P, through the casters' lowest height). Projected from C
  it stays convex (every vertex is in front of C), so the box of its vertices' texels, one texel
  wider each side (the texel holding a region's edge), holds every map texel a blocker can be
  stored in. Heights are affine along rays from C, so what the map stored in front of a blocker
  is lower still. The heights from h_s up to h_r - bias (``bias`` x the scene's extent, a
  height) are cut into :data:`BANDS` bands [b_j, b_j+1); the region shrinks towards P as the
  height rises (the slices are nested), so a caster in band j lies in the region at b_j, and if
  no texel of that region's box stores a height below b_j+1, for every band, nothing between P
  and the light covers a texel centre (a lower texel in a higher band's box is in its own
  band's box too). P is then surely lit — when also the whole of K faces P and lies strictly
  above P's tangent plane (the truth counts samples below it as occluded). Per render: the
  depth map read back, turned into stored heights (empty texels: none), and a min pyramid of
  them (padded to a power of two); each box is answered at the pyramid level where it spans at
  most :data:`BOX_TAPS` texels a side — the level's texels cover the box and a little more, so
  the answer is conservative. Everything else is uncertain: a box reaching past the map, a
  receiver behind a one-sided light or below part of the light's hull, and every pixel of a
  frame whose casters reach the light's hull or in front of the map's near plane (a note says
  so). There is no surely-shadowed class: a region full of blockers in a map from the centre
  does not show that every segment from P to the light is blocked (the map stores one surface
  per ray from the centre; whether the segments to the light's other points cross it or pass
  behind it, it cannot tell).
- ``trace`` (CPU): the uncertain pixels get the truth's estimator
  (:func:`shadowlab.truth.area.area_visibility`: ``samples`` stratified light samples each, from the
  same offset origins, against the same Embree scene; seed 0, a fresh jitter per chunk of
  pixels), the surely-lit ones V = 1 and no rays. The pixels the map misses are the
  classifier's (a caster covering no texel centre of the box), measured by the classifier image.
  ``spread``, ``cutoff``, ``shorten`` and ``margin`` are the hard path's and ignored here.

Stats: ``rays`` traced per render, ``rays_per_pixel`` (rays / evaluated pixels: the truth traces
1 per pixel for a hard light, up to its ``samples`` for an area light), ``uncertain_pixels``
(evaluated pixels the map was unsure of), ``traced_pixels`` (those in traced tiles) and
``dropped_pixels`` (those left to the nearest tap), ``memory_bytes`` (the depth atlas and the
class image; area lights: the depth map and the height pyramid), ``passes``.
:meth:`HybridRT.component_images` gives the classifier's answer per pixel, so that its own
error can be measured against the truth.
"""
from __future__ import annotations

import numpy as np

from ...geometry.caster_depth import nearest_depths
from ...gpu import glstate, programs, targets
from ...gpu.glstate import PassState
from ...scene.area_lights import AreaLight, DiscLight, RectLight, SphereLight, basis
from ...truth.area import area_visibility
from ...truth.tracing import caster_scene, occluded, offset_origins
from ..base import FIRST, MAX, SUM, Param, PlotStyle, Technique, TechniqueError, TuneRange
from .toolkit import (
    ATLAS_DEFINES, CLEAR_DEPTH, Atlas, centre_map_atlas, depth_defines, depth_pass, fit_light_views, height_axis,
)
from .contact import ContactShadows

#: Screen tiles the cut-off counts uncertain pixels in (AMD's 8x8 tiles), pixels on a side.
TILE = 8
#: The class image's values (hybrid_rt_classify.glsl's CLASS_*).
CLASS_LIT, CLASS_SHADOWED, CLASS_UNCERTAIN = 1.0, 0.0, 0.5
#: Area lights: a search box is answered at the min pyramid's level where it spans at most
#: BOX_TAPS texels a side (BOX_TAPS² taps), and widened by BOX_MARGIN texels each side; the
#: heights between the casters' lowest and the receiver's are cut into BANDS bands, each
#: searched over the region at its lowest height (the largest of the band's).
BOX_TAPS, BOX_MARGIN, BANDS = 8, 1, 8


def light_hull(light: AreaLight, view: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """A convex polytope holding the whole area light, as its vertices (K, 3) world float64:
    rect — its 4 corners; disc — the 4 corners of the square around it in its plane; sphere —
    the 8 corners of the cube around it with faces across ``axis`` and along the map's x, y
    (rows 0, 1 of the world → view matrix ``view``). Another shape: a TechniqueError."""
    c = np.asarray(light.position, np.float64)
    if isinstance(light, RectLight):
        return np.asarray(light.corners(), np.float64)
    if isinstance(light, DiscLight):
        t1, t2 = basis(np.asarray(light.normal, np.float64))
        r = light.radius
        return np.array([c + r * (a * t1 + b * t2) for a in (-1, 1) for b in (-1, 1)])
    if isinstance(light, SphereLight):
        a1, a2 = np.asarray(view[0, :3], np.float64), np.asarray(view[1, :3], np.float64)
        r = light.radius
        return np.array([c + r * (a * a1 + b * a2 + e * axis) for a in (-1, 1) for b in (-1, 1) for e in (-1, 1)])
    raise TechniqueError(f"hybrid_rt: no hull for area light shape {light.shape!r}")


def below_light(light: AreaLight, points: np.ndarray, normals: np.ndarray, hull: np.ndarray) -> np.ndarray:
    """Bool (M,): the whole light faces the point and lies strictly above its tangent plane (the
    camera-facing unit ``normals``), so that every one of the truth's samples is live: a
    one-sided light's emitting side holds the point and every hull vertex is above the plane
    (rect: its corners; disc: its rim's lowest point; sphere: its lowest point, the point outside)."""
    c = np.asarray(light.position, np.float64)
    up = np.einsum("ij,ij->i", c - points, normals)  # N·(C − P)
    if isinstance(light, DiscLight):
        n = np.asarray(light.normal, np.float64)
        across = np.sqrt(np.maximum(0.0, 1.0 - (normals @ n) ** 2))  # |N's part in the disc's plane|
        ok = up - light.radius * across > 0
    elif isinstance(light, SphereLight):
        ok = (up - light.radius > 0) & light.emits_towards(points)
    else:
        ok = np.all(np.einsum("mkj,mj->mk", hull[None, :, :] - points[:, None, :], normals) > 0, axis=1)
    if light.one_sided:
        ok &= light.emits_towards(points)
    return ok


def min_pyramid(heights: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """The min pyramid of a square (R, R) array: padded with +inf to a power of two P, level k
    holds the minimum of each 2^k x 2^k block. Returns every level flattened into one float32
    array and per level (offset into it, side)."""
    side = 1 << max(0, int(np.ceil(np.log2(max(heights.shape)))))
    level = np.full((side, side), np.inf, np.float32)
    level[:heights.shape[0], :heights.shape[1]] = heights
    levels, layout, offset = [], [], 0
    while True:
        levels.append(level.ravel())
        layout.append((offset, level.shape[0]))
        offset += level.size
        if level.shape[0] == 1:
            break
        level = np.minimum(np.minimum(level[0::2, 0::2], level[1::2, 0::2]),
                           np.minimum(level[0::2, 1::2], level[1::2, 1::2]))
    return np.concatenate(levels), layout


def box_minimum(flat: np.ndarray, layout: list[tuple[int, int]], x0, x1, y0, y1) -> np.ndarray:
    """A lower bound of the minimum over each texel box [x0, x1] x [y0, y1] (inclusive level-0
    indices, int arrays (M,)) of a :func:`min_pyramid`: the minimum of the texels of the lowest
    level at which the box spans at most :data:`BOX_TAPS` texels a side — those cover the box
    (and up to one such texel more each side)."""
    x0, x1, y0, y1 = (np.asarray(a, np.int64) for a in (x0, x1, y0, y1))
    level = np.zeros(len(x0), np.int64)
    for k in range(len(layout)):  # the first level at which the box fits BOX_TAPS texels a side
        wide = (((x1 >> level) - (x0 >> level)) >= BOX_TAPS) | (((y1 >> level) - (y0 >> level)) >= BOX_TAPS)
        if not wide.any():
            break
        level = np.where(wide, k + 1, level)
    offsets = np.array([o for o, _ in layout], np.int64)[level]
    sides = np.array([n for _, n in layout], np.int64)[level]
    lx0, lx1, ly0, ly1 = x0 >> level, x1 >> level, y0 >> level, y1 >> level
    out = np.full(len(x0), np.inf, np.float32)
    for dy in range(BOX_TAPS):
        for dx in range(BOX_TAPS):
            x, y = lx0 + dx, ly0 + dy
            ok = (x <= lx1) & (y <= ly1)
            idx = offsets + np.where(ok, y * sides + x, 0)
            out = np.minimum(out, np.where(ok, flat[idx], np.inf))
    return out



class HybridRT(ContactShadows, Technique):
    """Hybrid ray-traced shadows (module docstring): a shadow map's (2r+1)² kernel classifies
    each pixel as surely lit, surely shadowed or uncertain; uncertain pixels of tiles that pass
    the cut-off get the truth's own shadow ray, optionally shortened by the map's depth. Area
    lights: a blocker search region over a min pyramid of the map's heights classifies pixels
    as surely lit or uncertain; uncertain ones get the truth's stratified light samples."""

    name = "hybrid_rt"
    summary = ("hybrid ray-traced shadows (AMD FidelityFX Hybrid Shadows): a shadow map classifies pixels, "
               "Embree rays only for the uncertain ones (area lights: a blocker-search region, stratified rays)")
    PARAMS = {
        "resolution": Param(2048, "shadow map width and height in texels (per cube face)", min=16, max=16384,
                            # a coarse map leaves more pixels uncertain (more rays); 8192 is a cube atlas's limit
                            tune=TuneRange(128, 8192, log=True)),
        "spread": Param(1, "hard lights: classification kernel radius r in texels: (2r+1)^2 taps must "
                           "agree for a pixel to be called sure (0: the nearest tap alone, never uncertain: "
                           "a plain shadow map)",
                        min=0, max=8,
                        # 1-2 texels cover the map's aliasing; past 3 most of the penumbra-free image is traced
                        tune=TuneRange(0, 3)),
        "cutoff": Param(0, "hard lights: tiles of 8x8 pixels with fewer uncertain pixels than this take "
                           "the nearest tap's answer instead of rays (0: trace every uncertain pixel; 65: trace none)",
                        min=0, max=TILE * TILE + 1,
                        # AMD's cut-off drops tiles with a handful of uncertain pixels; 16 already drops edges
                        tune=TuneRange(0, 16)),
        "shorten": Param(True, "hard lights: shorten each ray to the distance (from the point towards the "
                               "light) of the kernel's smallest stored depth plus a margin: nearer casters "
                               "would be in the map"),
        "margin": Param(64.0, "hard lights, shorten: how far past the kernel's smallest stored depth each ray "
                               "still looks, in world texels at that depth (plus the bias's world size)",
                        min=0.0, max=1e6,
                        # 4 texels already misses tilted sub-texel triangles (sv_soup); past a few hundred
                        # texels the rays are hardly shortened at all
                        tune=TuneRange(1.0, 512.0, log=True)),
        "bias": Param(0.002, "constant depth bias of the classifier: on perspective maps a distance towards the "
                             "light, as a fraction of the scene's extent; on orthographic maps window depth "
                             "(a fraction of the depth range): shadow_map's bias_space=world; area lights: a "
                             "height below the receiver's, as a fraction of the scene's extent",
                      # as shadow_map's: acne below ~1e-6, 0.05 detaches every contact
                      min=0.0, max=1.0, tune=TuneRange(1e-6, 0.05, log=True)),
        "depth_bits": Param(24, "depth format: 16 / 24 fixed point, 32 float", choices=(16, 24, 32)),
        "samples": Param(64, "area lights: stratified light samples (shadow rays) traced per uncertain pixel, "
                             "as the truth's estimator (standard error <= 0.5/sqrt(samples))", min=1, max=65536,
                         # 16 is visibly noisy in the penumbrae; past 1024 it costs the truth's rays there
                         tune=TuneRange(16, 1024, log=True)),
    }
    PASSES = ("depth", "classify", "trace")
    LIGHTS = frozenset({"point", "spot", "directional", "target_direct", "area"})
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
        self.is_area = isinstance(self.light, AreaLight)
        if self.is_area:
            self._setup_area(frame, slot)
            return
        faces, notes = fit_light_views(frame, slot, self.resolution)
        self.notes.extend(notes)
        self.atlas = Atlas.grid(faces, self.resolution, self.name)
        self.map = self.own(targets.DepthTexture.create(self.atlas.size, self.depth_bits))
        self.depth_prog = self.program("shadow_depth.glsl", defines=depth_defines())
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


    # ------------------------------------------------------------------ area lights
    def _setup_area(self, frame, slot) -> None:
        """Area lights: pcss's map (one perspective face from the centre, fitted to every
        evaluated receiver), the per-texel height slope of the map's rays, the casters' lowest
        height, the truth's Embree scene, offset origins, points and normals."""
        light = self.light
        self.atlas, notes = centre_map_atlas(frame, slot, self.resolution, self.name)
        self.notes.extend(notes)
        face = self.atlas.faces[0]
        proj, view = np.asarray(face.proj, np.float64), np.asarray(face.view, np.float64)
        if not np.allclose(proj[3], (0.0, 0.0, -1.0, 0.0)):
            raise TechniqueError(f"{self.name}: the area light's map is not a perspective projection")
        self.map = self.own(targets.DepthTexture.create(self.atlas.size, self.depth_bits))
        self.depth_prog = self.program("shadow_depth.glsl", defines=depth_defines())
        self.view_proj = proj @ view
        self.centre = np.asarray(light.position, np.float64)
        self.axis = height_axis(light, view)
        self.hull = light_hull(light, view, self.axis)
        self.hull_heights = (self.hull - self.centre) @ self.axis
        # A point at linear depth z on the map's ray through NDC (x, y) is O + z·D(x, y), with D
        # affine in (x, y) (normalised to view z = −1); its height is dot(O − C, axis) + z·slope.
        inv_view = np.linalg.inv(view)
        origin = inv_view[:3, 3]
        self.origin_height = float((origin - self.centre) @ self.axis)

        def slope(x, y):
            q = np.linalg.solve(proj, np.array([x, y, 0.0, 1.0]))
            d = q[:3] / -q[2]
            return float((inv_view[:3, :3] @ d) @ self.axis)

        s0, sx, sy = slope(0.0, 0.0), slope(1.0, 0.0), slope(0.0, 1.0)
        size = self.resolution
        ndc = (np.arange(size) + 0.5) / size * 2.0 - 1.0  # texel centres
        self.texel_slope = (s0 + (sx - s0) * ndc[None, :] + (sy - s0) * ndc[:, None]).astype(np.float32)
        self.depth_terms = (float(proj[2, 2]), float(proj[2, 3]))  # z = p23 / (z_ndc + p22)
        # the casters' lowest height: the nearest corner of their bounding boxes to the light's plane
        bounds = np.asarray(frame.caster_bounds(), np.float64).reshape(-1, 2, 3)
        corners = np.stack(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij"), -1).reshape(-1, 3)
        pts = bounds[:, corners, [0, 1, 2]].reshape(-1, 3)
        self.lowest = float(((pts - self.centre) @ self.axis).min()) if len(pts) else np.inf
        # the fit's near plane lies in front of every caster inside the frustum unless it had to
        # clip some (its note): those cannot be in the map, so nothing can be called sure
        near, far = face.near_far()
        tris = frame.casters().triangles
        nearest = float(nearest_depths(tris, view, 1.0 / float(proj[1, 1]), far).min()) if len(tris) else np.inf
        self.unsure = ""
        if len(pts) and self.lowest <= float(self.hull_heights.max()):
            self.unsure = "the casters reach the light's hull"
        elif nearest < near:
            self.unsure = "casters reach in front of the map's near plane"
        if self.unsure:
            self.notes.append(f"{self.name}: {self.unsure}: no pixel is called sure, every one is traced")
        self.bias_height = float(self.bias) * float(frame.scene.extent())
        self.scene = caster_scene(frame) if frame.has_casters else None
        self.evaluated = slot.evaluated
        self.eval_index = np.flatnonzero(slot.evaluated)
        self.eval_origins = np.ascontiguousarray(offset_origins(frame)[self.eval_index])
        self.eval_points = frame.compact_position[self.eval_index]
        self.eval_normals = frame.compact_normal[self.eval_index]
        self.cls = np.full(len(self.eval_index), CLASS_LIT, np.float32)
        self.result = np.ones(len(self.eval_index), np.float32)
        self.pyramid_bytes = 0
        self.counts = {"rays": 0, "uncertain": 0, "traced": 0, "dropped": 0}

    def search_boxes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per evaluated pixel: whether a sure answer is possible at all (the light faces the
        point and lies above its horizon, every band's region is in the map and in front of the
        centre), whether no caster can lie between the point and the light (the point no more
        than the bias above the casters' lowest height), the band limits (M, BANDS + 1) and the
        texel box of each band's search region (M, BANDS, 4) int64 x0, x1, y0, y1 (module
        docstring)."""
        points = self.eval_points
        m = len(points)
        h_r = (points - self.centre) @ self.axis
        top = h_r - self.bias_height
        possible = below_light(self.light, points, self.eval_normals, self.hull) & (not self.unsure)
        free = top <= self.lowest  # every caster at least as high as the point (less the bias)
        # band limits b_0 = h_s < b_1 < ... < b_BANDS = h_r - bias
        limits = self.lowest + (top - self.lowest)[:, None] * (np.arange(BANDS + 1) / BANDS)[None, :]
        boxes = np.zeros((m, BANDS, 4), np.int64)
        size = self.resolution
        vp = self.view_proj

        def project(x):
            """uv (M, 2) of points (M, 3) and whether they are in front of the centre (plain
            (M,) columns: numpy's stacked small products and reductions are slow)."""
            w = x @ vp[3, :3] + vp[3, 3]
            front = w > 0
            w = np.where(front, w, 1.0)
            return np.stack([x @ vp[0, :3] + vp[0, 3], x @ vp[1, :3] + vp[1, 3]], axis=1) / w[:, None] * 0.5 + 0.5, front

        uv_p, front_p = project(points)
        for j in range(BANDS):
            # the region at height b_j: P and P + t_i (K_i − P), t_i = (h_r − b_j) / (h_r − h(K_i))
            lo_uv, hi_uv, front = uv_p.copy(), uv_p.copy(), front_p.copy()
            for vertex, height in zip(self.hull, self.hull_heights):
                t = np.clip((h_r - limits[:, j]) / np.maximum(h_r - height, 1e-300), 0.0, 1.0)
                uv, ahead = project(points + t[:, None] * (vertex - points))
                np.minimum(lo_uv, uv, out=lo_uv)
                np.maximum(hi_uv, uv, out=hi_uv)
                front &= ahead
            lo = np.floor(np.clip(lo_uv, -1.0, 2.0) * size).astype(np.int64) - BOX_MARGIN
            hi = np.floor(np.clip(hi_uv, -1.0, 2.0) * size).astype(np.int64) + BOX_MARGIN
            inside = (lo[:, 0] >= 0) & (lo[:, 1] >= 0) & (hi[:, 0] <= size - 1) & (hi[:, 1] <= size - 1)
            possible &= free | (front & inside)
            boxes[:, j] = np.stack([lo[:, 0], hi[:, 0], lo[:, 1], hi[:, 1]], axis=1)
        return possible, free, limits, boxes

    def stored_heights(self) -> np.ndarray:
        """Float32 (R, R), row = the map's texel row from the bottom: the height above the light
        of the surface each texel stored (+inf where nothing was: the clear depth)."""
        depth = self.map.read()[::-1]  # read() is row 0 = top; the map's v grows upwards
        p22, p23 = self.depth_terms
        z = p23 / (2.0 * depth.astype(np.float64) - 1.0 + p22)
        heights = (self.origin_height + z * self.texel_slope).astype(np.float32)
        heights[depth >= CLEAR_DEPTH] = np.inf
        return heights

    def _classify_area(self) -> None:
        """Surely lit (no stored height in the search box below the receiver's minus the bias,
        the whole light above its horizon) or uncertain: fills :attr:`cls`."""
        possible, free, limits, boxes = self.search_boxes()
        lit = possible & free
        test = np.flatnonzero(possible & ~free)  # the pixels still clear, band after band
        if len(test):
            flat, layout = min_pyramid(self.stored_heights())
            self.pyramid_bytes = int(flat.nbytes)
            for j in range(BANDS):  # band j: nothing stored in its box lower than its upper limit
                test = test[box_minimum(flat, layout, *boxes[test, j].T) >= limits[test, j + 1]]
            lit[test] = True  # clear in every band
        self.cls = np.where(lit, CLASS_LIT, CLASS_UNCERTAIN).astype(np.float32)

    def _trace_area(self) -> None:
        """The truth's stratified estimator on the uncertain pixels (seed 0), V = 1 elsewhere."""
        idx = np.flatnonzero(self.cls == CLASS_UNCERTAIN)
        result = np.ones(len(self.eval_index), np.float32)
        rays = 0
        if len(idx):
            fraction, rays = area_visibility(self.scene, self.light, self.eval_points[idx], self.eval_normals[idx],
                                             self.eval_origins[idx], self.samples)
            result[idx] = fraction
        self.result = result
        self.counts = {"rays": int(rays) if self.scene is not None else 0, "uncertain": int(len(idx)),
                       "traced": int(len(idx)), "dropped": 0}

    def render(self) -> None:
        """Depth from the light, the classification pass, then (CPU) the tile cut-off and the
        shadow rays of the uncertain pixels of the traced tiles. Area lights: depth from the
        centre, the classification on the CPU (the map read back), the stratified rays."""
        with self.timed_pass("depth"):
            depth_pass(self.frame, self.map, self.depth_prog, self.atlas)
        if self.is_area:
            with self.timed_pass("classify", cpu=True):
                self._classify_area()
            with self.timed_pass("trace", cpu=True):
                self._trace_area()
            return
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
        lit, 0 surely shadowed (hard lights only), NaN where it was uncertain (traced or in a
        dropped tile) and where the pixel is not evaluated — what the classifier's own error is
        measured on."""
        answer = np.where(self.cls == CLASS_UNCERTAIN, np.nan, self.cls).astype(np.float32)
        out = np.full(len(self.evaluated), np.nan, np.float32)
        out[self.eval_index] = answer
        return {"classifier": self.frame.to_image(out, fill=np.nan)}

    def work(self, counted: dict, stats: dict) -> dict:
        """Texture taps of the classification (the G-buffer's position, the kernel's (2r+1)²
        texels and the nearest one again) and the shadow rays traced; area lights: the rays only
        (the classification runs on the CPU)."""
        if self.is_area:
            return {"trace": {"rays": stats["rays"]}}
        taps = self.taps_work(counted, {"classify": 1 + (2 * self.spread + 1) ** 2 + 1})
        return {**taps, "trace": {"rays": stats["rays"]}}

    def stats(self) -> dict:
        """Rays, rays per evaluated pixel, uncertain / traced / dropped pixels, memory (depth
        atlas and class image; area lights: the depth map and the height pyramid) and passes
        (one depth pass per face, the classification, the trace)."""
        evaluated = max(1, len(self.eval_index))
        if self.is_area:
            return {"rays": self.counts["rays"], "rays_per_pixel": self.counts["rays"] / evaluated,
                    "uncertain_pixels": self.counts["uncertain"], "traced_pixels": self.counts["traced"],
                    "dropped_pixels": 0, "memory_bytes": int(self.map.nbytes + self.pyramid_bytes), "passes": 3}
        return {"rays": self.counts["rays"], "rays_per_pixel": self.counts["rays"] / evaluated,
                "uncertain_pixels": self.counts["uncertain"], "traced_pixels": self.counts["traced"],
                "dropped_pixels": self.counts["dropped"],
                "memory_bytes": int(self.map.nbytes + self.frame.width * self.frame.height * 16),
                "passes": len(self.atlas.faces) + 2}
