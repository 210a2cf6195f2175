"""Cascaded shadow maps (CSM) and sample distribution shadow maps (SDSM) for directional lights.

Perspective aliasing: one orthographic map fitted to a long view spends as many texels on the
far end as near the camera, where a texel covers many pixels. Cascades split the camera's view
depth into ``cascades`` slices, each with its own orthographic map of ``resolution``², so the
texels near the camera are small (Engel 2006, "Cascaded shadow maps", ShaderX5; Dimitrov 2007,
"Cascaded shadow maps", NVIDIA).

- Splits (``split_lambda`` = λ): the practical split scheme of Zhang et al. 2006, "Parallel-split
  shadow maps for large-scale virtual environments" (§3.2),
  z_i = λ·n·(f/n)^(i/N) + (1 − λ)·(n + (f − n)·i/N), a mix of the logarithmic (λ = 1) and uniform
  (λ = 0) schemes (:func:`practical_splits`).
- ``fit=frustum`` (the classic CSM): n, f = the camera's near and far planes; each cascade
  covers its slice of the view frustum. With ``stabilize`` (Valient 2008, "Stable rendering of
  cascaded shadow maps", ShaderX6) the cascade's square box is the bounding sphere of its slice
  (a size that does not change with the camera's or the light's orientation) and its origin is
  snapped to whole texels in light space, so a moving camera does not make its shadow edges
  shimmer; the box is widened by one texel so the snapped square still holds the sphere.
  Stabilisation holds while the splits do: fix the camera's ``near``/``far`` in the scene (the
  fitted ones follow the scene's bounds and move with the camera).
- ``fit=sdsm`` (Lauritzen, Salvi & Lefohn 2011, "Sample distribution shadow maps", I3D; Lauritzen
  2010, SIGGRAPH course): n, f = the smallest and largest view depth of the evaluated G-buffer
  points, and each cascade's light-space x/y box fitted tightly to the evaluated points in its
  depth slice. ``stabilize`` does not apply (the boxes follow the samples): it is ignored with a
  note.

- ``focus=scene`` (the default; issue 26): "fit to scene" (Dimitrov 2007; Microsoft, "Common
  techniques to improve shadow depth maps", 2012): each cascade's box above is intersected
  with the bounding rectangle of the receivers in its slice that can be shadowed at all
  (:func:`~shadowlab.techniques.maps.toolkit.shadowable_mask`, what shadow_map's ``fit=shadowable``
  covers), and its depth runs from the casters over the box to the farthest of those points:
  a cascade spends no texels on empty ground. Under ``stabilize`` the focused box keeps a
  world-fixed grid (:func:`snap_focus`: its texel is the sphere box's × 2^(−k/4), its corner
  snapped to whole texels of that size), so shimmer returns only when the focused extent
  crosses a quarter octave (or the splits move). A slice with no shadowable point keeps its
  unfocused box (nothing there can be shadowed; keeping it keeps the grid). Under ``fit=sdsm``
  only the shadowable points of a cascade's slice count (all of them in a slice that holds
  none). ``focus=none``: the classic fits, bit for bit.

Every cascade's light-space depth range runs from the nearest caster to the farthest point it
covers, clamped to the scene's bounds (as in shadow_map's fitting). The atlas holds the cascades
side by side (tile i at x = i·resolution; the map toolkit's :class:`~shadowlab.techniques.maps.toolkit.Atlas`
row, at most :data:`~shadowlab.techniques.maps.toolkit.MAX_FACES` cascades); the depth pass is the
toolkit's; the lookup is ``shadow_lookup.glsl`` with ``CASCADES`` defined (the cascade chosen by the point's
camera view depth against the splits) and shadow_map's constant and shader-side slope bias (not
its other variants: no normal offset, and no receiver-plane or adaptive per-tap comparison —
the lookup's ``u_depth_comparison`` stays at the point's own depth here). With
``blend`` the visibility blends linearly into the next cascade over the last ``blend_width`` of a
cascade's depth range (the nearer cascade is the one :meth:`face_index` reports there).
"""
from __future__ import annotations

import numpy as np

from ...geometry import transforms as tf
from ...geometry.bounds import box_corners
from ...geometry.frusta import MIN_EXTENT, PAD, LightView
from ..base import FIRST, Param, PlotStyle, TechniqueError, TuneRange
from .toolkit import DEPTH_MAP_STATS, FILTERS, MAX_FACES, DepthMapTechnique, shadowable_mask
from .contact import ContactShadows
from .presets import PRESET_NAMES, PresetMixin

#: Most cascades: one per face of the map toolkit's atlas.
MAX_CASCADES = MAX_FACES
#: Each cascade also covers this fraction of its depth range beyond its splits, so a point whose
#: float32 view depth in the shader falls on the other side of a split than its float64 depth
#: here still lies inside the cascade the shader picks.
SPLIT_OVERLAP = 1e-3
#: focus=scene with stabilize: a focused cascade's texel size is the sphere box's times
#: 2^(−k / this) for a whole k (:func:`snap_focus`). More levels fit tighter (at most 2^(1/this)
#: coarser than the focused extent needs: 19 % at 4) but change the texel size, and so move
#: the grid, more often as the focused extent drifts; 4 is a quarter octave.
FOCUS_LEVELS_PER_OCTAVE = 4


def practical_splits(near: float, far: float, cascades: int, lam: float) -> np.ndarray:
    """The N + 1 split depths z_0 = near … z_N = far of Zhang et al. 2006's practical scheme:
    z_i = λ·n·(f/n)^(i/N) + (1 − λ)·(n + (f − n)·i/N) (float64 (N + 1,), increasing)."""
    if not 0 < near < far:
        raise TechniqueError(f"cascaded_map: split range needs 0 < near < far, got {near}, {far}")
    i = np.arange(cascades + 1) / cascades
    z = lam * near * (far / near) ** i + (1.0 - lam) * (near + (far - near) * i)
    z[0], z[-1] = near, far  # exact ends whatever the rounding
    return z


def slice_corners(view: np.ndarray, tan_x: float, tan_y: float, z0: float, z1: float) -> np.ndarray:
    """World corners (8, 3) of the slice of a camera's view frustum between view depths z0 and
    z1; ``view`` is the camera's world → view matrix, ``tan_x``/``tan_y`` its half-angle tangents."""
    sx, sy = np.meshgrid([-1.0, 1.0], [-1.0, 1.0])
    local = np.concatenate([np.stack([sx.ravel() * tan_x * z, sy.ravel() * tan_y * z, np.full(4, -z)], axis=1)
                            for z in (z0, z1)])
    inv = np.linalg.inv(view)
    return local @ inv[:3, :3].T + inv[:3, 3]


def slice_sphere(tan_x: float, tan_y: float, z0: float, z1: float) -> tuple[float, float]:
    """The smallest sphere around a frustum slice between view depths z0 < z1: (view depth of its
    centre on the axis, radius). Equidistant from the near and far corners,
    c = (z0 + z1)(1 + a²)/2 with a² = tan_x² + tan_y², unless that lies beyond z1, where the far
    rectangle's circumcircle holds the slice. Depends only on the slice's shape, not on where
    the camera is or looks (Valient 2008)."""
    a2 = tan_x ** 2 + tan_y ** 2
    c = min(0.5 * (z0 + z1) * (1.0 + a2), z1)
    radius = max(np.sqrt((c - z0) ** 2 + a2 * z0 ** 2), np.sqrt((z1 - c) ** 2 + a2 * z1 ** 2))
    return float(c), float(radius)


def light_rotation(direction: np.ndarray) -> np.ndarray:
    """World → light-space rotation (4x4) looking along ``direction``, about the world origin:
    fixed while the light is, so texel snapping in light space means a fixed world grid."""
    return tf.look_along(np.zeros(3), direction)


def cascade_view(rotation: np.ndarray, lo: np.ndarray, hi: np.ndarray, points: np.ndarray,
                 caster_bounds: np.ndarray, scene_bounds: np.ndarray, resolution: int) -> LightView:
    """The orthographic view of one cascade: light-space x/y box [lo, hi] (2,) each; depth from
    the nearest caster (or covered point) to the farthest covered point ``points`` (N, 3), both
    clamped to the scene's bounds (2, 3), padded by :data:`PAD`."""
    def depth(p):
        return -tf.transform_points(rotation, p)[:, 2]
    scene = depth(box_corners(scene_bounds[None]))
    pts = np.clip(depth(points), scene.min(), scene.max())
    near = float(pts.min())
    if len(caster_bounds):
        near = min(near, float(depth(box_corners(caster_bounds)).min()))
    far = float(pts.max())
    span = max(far - near, MIN_EXTENT)
    near, far = near - PAD * span, far + PAD * span
    proj = tf.orthographic(lo[0], hi[0], lo[1], hi[1], near, far)
    return LightView(rotation, proj, texel_world=float(np.max(hi - lo)) / resolution)


def focus_rect(lo: np.ndarray, hi: np.ndarray, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The light-space box [lo, hi] (2,) each intersected with the bounding rectangle of the
    points ``xy`` (M ≥ 1, 2), padded by :data:`PAD` of its extent like every other fit ("fit to
    scene": Dimitrov 2007 §"Tight frustum"; Microsoft, "Common techniques to improve shadow depth
    maps", 2012, "Fit to scene"). The points lie in the slice, hence in the box, so the result is
    never empty; it is clamped so that lo ≤ hi all the same."""
    plo, phi = xy.min(0), xy.max(0)
    pad = PAD * max(float(np.max(phi - plo)), MIN_EXTENT)
    flo, fhi = np.maximum(lo, plo - pad), np.minimum(hi, phi + pad)
    return flo, np.maximum(fhi, flo + MIN_EXTENT)


def snap_focus(lo: np.ndarray, hi: np.ndarray, sphere_lo: np.ndarray, texel: float,
               resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """A stabilised focused box: per axis the finest texel t = ``texel`` · 2^(−k / L) (k ≥ 0,
    L = :data:`FOCUS_LEVELS_PER_OCTAVE`; ``texel``: the stabilised sphere box's) whose box
    [floor(lo / t) · t, that + resolution · t] still holds [lo, hi]; k = 0 keeps the sphere box
    (``sphere_lo`` + resolution · texel). The box's corner is snapped to whole texels of its own
    size t, so its texel grid is the world-fixed lattice t·ℤ in light space (Valient 2008's
    snapping): it stays put while the camera moves unless k changes (the focused extent crosses
    a level) or the splits do. Snapping the corners to whole sphere texels with any width would
    not hold the grid: the texel, width / resolution, would change with every width."""
    out_lo = np.array(sphere_lo, np.float64)
    out_hi = out_lo + resolution * texel
    for axis in range(2):
        extent = max(float(hi[axis] - lo[axis]), MIN_EXTENT)
        k = max(int(np.floor(FOCUS_LEVELS_PER_OCTAVE * np.log2(resolution * texel / extent))), 0)
        while k > 0:  # the snap of lo can cost up to a texel: fall back a level until the box holds
            t = texel * 2.0 ** (-k / FOCUS_LEVELS_PER_OCTAVE)
            start = np.floor(lo[axis] / t) * t
            if start + resolution * t >= hi[axis]:
                out_lo[axis], out_hi[axis] = start, start + resolution * t
                break
            k -= 1
    return out_lo, out_hi


def focus_casters(rotation: np.ndarray, caster_bounds: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The caster boxes (K', 2, 3) whose light-space rectangle overlaps [lo, hi]: the only casters
    that can shadow a point of the box (a directional light's rays run along light-space z)."""
    if not len(caster_bounds):
        return caster_bounds
    xy = tf.transform_points(rotation, box_corners(caster_bounds))[:, :2].reshape(-1, 8, 2)
    overlap = np.all(xy.min(1) <= hi, axis=1) & np.all(xy.max(1) >= lo, axis=1)
    return caster_bounds[overlap]


def fit_frustum_cascades(view: np.ndarray, tan_x: float, tan_y: float, intervals: np.ndarray,
                         direction: np.ndarray, caster_bounds: np.ndarray, scene_bounds: np.ndarray,
                         resolution: int, stabilize: bool, focus_points: np.ndarray | None = None) -> list[LightView]:
    """Classic CSM: one view per cascade covering the camera frustum's slice between the view
    depths ``intervals[i]`` = (z0, z1) ((N, 2)). ``stabilize``: a square box the size of the
    slice's bounding sphere (plus one texel), its corner snapped to whole texels in light space
    (Valient 2008); else the slice corners' light-space bounding rectangle.

    ``focus_points`` (M, 3; None: no focus, the classic fit bit for bit): the receivers that can
    be shadowed. Each cascade's box shrinks to those of them in its slice (:func:`focus_rect`;
    stabilised: :func:`snap_focus`), its depth runs from the casters over the box
    (:func:`focus_casters`) to the farthest of them; a slice without one keeps its box (nothing
    in it can be shadowed, so any box answers; keeping it keeps the stabilised grid)."""
    rot = light_rotation(direction)
    inv = np.linalg.inv(view)
    if focus_points is not None:
        focus_depth = -tf.transform_points(view, focus_points)[:, 2]
        focus_xy = tf.transform_points(rot, focus_points)[:, :2]
    views = []
    for z0, z1 in intervals:
        corners = slice_corners(view, tan_x, tan_y, z0, z1)
        if stabilize:
            c, radius = slice_sphere(tan_x, tan_y, z0, z1)
            centre = tf.transform_points(rot, (inv @ np.array([0.0, 0.0, -c, 1.0]))[None, :3])[0, :2]
            width = 2.0 * radius * resolution / (resolution - 1)  # one texel spare for the snap
            texel = width / resolution
            lo = np.floor((centre - radius) / texel) * texel
            hi = lo + width
        else:
            xy = tf.transform_points(rot, corners)[:, :2]
            lo, hi = xy.min(0), xy.max(0)
            pad = PAD * max(float(np.max(hi - lo)), MIN_EXTENT)
            lo, hi = lo - pad, hi + pad
        cover, casters = corners, caster_bounds
        if focus_points is not None:
            inside = (focus_depth >= z0) & (focus_depth <= z1)
            if inside.any():
                flo, fhi = focus_rect(lo, hi, focus_xy[inside])
                lo, hi = snap_focus(flo, fhi, lo, texel, resolution) if stabilize else (flo, fhi)
                cover, casters = focus_points[inside], focus_casters(rot, caster_bounds, lo, hi)
        views.append(cascade_view(rot, lo, hi, cover, casters, scene_bounds, resolution))
    return views


def fit_sdsm_cascades(view: np.ndarray, tan_x: float, tan_y: float, points: np.ndarray, intervals: np.ndarray,
                      direction: np.ndarray, caster_bounds: np.ndarray, scene_bounds: np.ndarray,
                      resolution: int, focus: np.ndarray | None = None) -> tuple[list[LightView], list[str]]:
    """SDSM (Lauritzen et al. 2011): each cascade's light-space x/y box fitted tightly to the
    ``points`` (M, 3) whose view depth lies in its interval ((N, 2)); a cascade without points
    covers its frustum slice instead (with a note). ``focus`` (bool (M,), or None): only the
    points it marks (those that can be shadowed) count, in a cascade that holds any of them."""
    rot = light_rotation(direction)
    depth = -tf.transform_points(view, points)[:, 2]
    xy = tf.transform_points(rot, points)[:, :2]
    views, notes = [], []
    for i, (z0, z1) in enumerate(intervals):
        inside = (depth >= z0) & (depth <= z1)
        if focus is not None and np.any(inside & focus):
            inside &= focus
        if not inside.any():
            notes.append(f"cascaded_map: sdsm cascade {i} holds no evaluated point; it covers its frustum slice")
            cover = slice_corners(view, tan_x, tan_y, z0, z1)
            cxy = tf.transform_points(rot, cover)[:, :2]
        else:
            cover, cxy = points[inside], xy[inside]
        lo, hi = cxy.min(0), cxy.max(0)
        pad = PAD * max(float(np.max(hi - lo)), MIN_EXTENT)
        views.append(cascade_view(rot, lo - pad, hi + pad, cover, caster_bounds, scene_bounds, resolution))
    return views, notes


def cover_intervals(splits: np.ndarray, blend_start: np.ndarray) -> np.ndarray:
    """(N, 2) view-depth intervals each cascade's map must cover: its own slice, from where the
    previous cascade starts blending into it, widened by :data:`SPLIT_OVERLAP` of its range."""
    z0 = np.concatenate([[splits[0]], blend_start[:-1]])
    z1 = splits[1:].copy()
    margin = SPLIT_OVERLAP * (z1 - z0)
    return np.stack([np.maximum(z0 - margin, 0.0), z1 + margin], axis=1)


class CascadedShadowMap(PresetMixin, ContactShadows, DepthMapTechnique):
    """Cascaded shadow maps (Engel 2006) with Zhang et al.'s split scheme, optional blending,
    Valient's stabilisation, and SDSM fitting (Lauritzen et al. 2011); directional lights only."""

    name = "cascaded_map"
    summary = "cascaded shadow maps (PSSM splits, blending, stabilisation) and SDSM, directional lights"
    STYLE = PlotStyle("#17becf", ">")
    PASSES = ("depth", "lookup")
    #: The cascades follow the camera's view along a light at infinity (suites and tests give it
    #: scenes with a directional light; planning a compare, study or animation elsewhere is an error).
    LIGHTS = frozenset({"directional"})
    ATLAS_LAYOUT = "row"
    STATS = {**DEPTH_MAP_STATS, "cascades": FIRST, "splits": FIRST, "cascade_texel_world": FIRST}
    PARAMS = {
        "cascades": Param(4, "number of cascades (view-depth slices, one map each)", min=1, max=MAX_CASCADES),
        "resolution": Param(1024, "width and height of each cascade's map in texels", min=16, max=16384,
                            # powers of two; four 4096 cascades side by side fill a 16384-wide atlas
                            tune=TuneRange(256, 4096, log=True)),
        "split_lambda": Param(0.5, "split scheme: 0 uniform, 1 logarithmic, between a mix (Zhang et al. 2006)",
                              # the whole scheme: every mix from uniform to logarithmic
                              min=0.0, max=1.0, tune=TuneRange(0.0, 1.0)),
        "fit": Param("frustum", "frustum: splits over the camera's near..far, boxes around the frustum slices; "
                                "sdsm: splits and boxes fitted to the evaluated G-buffer points",
                     choices=("frustum", "sdsm")),
        "blend": Param(False, "blend linearly into the next cascade at the end of each cascade"),
        "blend_width": Param(0.1, "blend: fraction of a cascade's depth range over which it blends", min=0.0,
                             # below 2 % the seam stays visible; past half a cascade two maps blur most of it
                             max=1.0, min_open=True, tune=TuneRange(0.02, 0.5)),
        "stabilize": Param(True, "fit=frustum: bounding-sphere boxes snapped to whole texels (Valient 2008); "
                                 "ignored with a note under sdsm"),
        "focus": Param("scene", "scene: each cascade's box shrunk to the receivers in its slice that can be "
                                "shadowed and its depth to the casters over them ('fit to scene'); "
                                "none: the whole slice (fit=frustum) or every evaluated point (fit=sdsm)",
                       choices=("scene", "none")),
        "bias": Param(0.0005, "constant depth bias in window-depth units [0, 1] of each cascade", min=0.0, max=1.0,
                      # orders of magnitude from acne to detached contacts, as shadow_map's bias
                      tune=TuneRange(1e-5, 0.05, log=True)),
        "slope_scale": Param(2.0, "multiple of the receiver's depth change over one texel added to the bias "
                                  "(shader-side slope-scaled bias; 0: constant only)", min=0.0, max=1e4,
                             # 1-2 texels' slope is usual; 8 already pushes grazing shadows off
                             tune=TuneRange(0.0, 8.0)),
        "depth_bits": Param(24, "depth format: 16 / 24 fixed point, 32 float", choices=(16, 24, 32)),
        "filter": Param("nearest", "nearest, pcf3, pcf5 (texel-exact percentage-closer filtering)",
                        choices=("nearest", "pcf3", "pcf5")),
        "preset": Param("none", "start from an engine's default cascade settings (count, resolution, splits, "
                                "blending, filter; keys given in the spec override them; "
                                "shadowlab/techniques/maps/presets.py)", choices=PRESET_NAMES),
    }

    # ------------------------------------------------------------------ fitting
    def fit_views(self, frame, slot) -> tuple[list[LightView], list[str]]:
        """Splits and blend starts (``self.splits``, ``self.blend_start``) and one LightView per
        cascade, with notes for the run."""
        light = slot.light
        cam = frame.camera
        tan_y = float(np.tan(np.radians(cam.fov_y) / 2.0))
        tan_x = tan_y * frame.width / frame.height
        n = self.cascades
        points = frame.compact_position[slot.evaluated]
        notes: list[str] = []
        casters, scene_bounds = frame.caster_bounds(), frame.scene.bounds()
        sdsm = self._params["fit"] == "sdsm"
        if sdsm and len(points):
            depth = -tf.transform_points(frame.view, points)[:, 2]
            near, far = float(depth.min()), float(depth.max())
            far = max(far, near * (1.0 + PAD), near + MIN_EXTENT)
            if self.stabilize:
                notes.append("cascaded_map: stabilize is ignored with fit=sdsm (the boxes follow the samples)")
        else:
            if sdsm:
                notes.append("cascaded_map: sdsm found no evaluated point; splits over the camera's range")
            near, far = float(cam.near), float(cam.far)
        self.splits = practical_splits(near, far, n, self.split_lambda)
        ranges = np.diff(self.splits)
        self.blend_start = self.splits[1:] - (self.blend_width * ranges if self.blend else 0.0)
        intervals = cover_intervals(self.splits, self.blend_start)
        focus = shadowable_mask(frame, slot) if self.focus == "scene" else None
        if sdsm and len(points):
            faces, sdsm_notes = fit_sdsm_cascades(frame.view, tan_x, tan_y, points, intervals, light.direction,
                                                  casters, scene_bounds, self.resolution, focus=focus)
            return faces, notes + sdsm_notes
        return fit_frustum_cascades(frame.view, tan_x, tan_y, intervals, light.direction, casters,
                                    scene_bounds, self.resolution, self.stabilize and not sdsm,
                                    focus_points=None if focus is None else points[focus]), notes

    # ------------------------------------------------------------------ lookup
    def lookup_defines(self) -> dict:
        """The lookup picks the cascade by the point's view depth."""
        return {"CASCADES": 1}

    def comparison_uniforms(self) -> dict:
        """Constant and shader-side slope bias, PCF radius, the camera's view-depth row, the far
        split, blend start and texel size of each cascade (padded to the atlas's MAX_FACES)."""
        return {
            "u_bias": float(self.bias), "u_slope_scale": float(self.slope_scale), "u_normal_offset": 0.0,
            "u_texel_world": float(self.atlas.faces[0].texel_world), "u_texel_angle": 0.0,
            "u_kernel_radius": FILTERS[self.filter],
            "u_view_depth": tuple(float(v) for v in -self.frame.view[2]),
            "u_cascade_far": self.atlas.padded(self.splits[1:]),
            "u_blend_start": self.atlas.padded(self.blend_start),
            "u_cascade_texel": self.atlas.padded([f.texel_world for f in self.atlas.faces]),
        }

    # ------------------------------------------------------------------ texel mapping
    def face_index(self, points: np.ndarray) -> np.ndarray:
        """The cascade (int (M,)) the lookup uses for each world point (M, 3): the first whose far
        split lies at or beyond the point's camera view depth (the last past the far split);
        in a blend region that is the nearer cascade."""
        depth = -tf.transform_points(self.frame.view, np.asarray(points, np.float64))[:, 2]
        return np.searchsorted(self.splits[1:-1], depth, side="left").astype(int)

    def bias_window_world(self) -> tuple[float, float]:
        """The constant bias, window depth of each cascade."""
        return float(self.bias), 0.0

    def stats(self) -> dict:
        """Atlas memory, cascades, passes (one depth pass per cascade + the lookup), the split
        depths and each cascade's world texel size (strings), and cascade 0's texel size."""
        faces = self.atlas.faces
        median, largest = self.bias_at_receivers()
        return {"memory_bytes": self.map.nbytes, "cascades": len(faces), "faces": len(faces),
                "bias_world_median": median, "bias_world_max": largest,
                "passes": len(faces) + 1, "depth_range": faces[0].depth_range,
                "splits": " ".join(f"{z:.6g}" for z in self.splits),
                "cascade_texel_world": " ".join(f"{f.texel_world:.6g}" for f in faces),
                "texel_world": float(faces[0].texel_world)}
