"""Shadow-map ray tracing (SMRT) from one depth map of an area light, as Unreal Engine 5 traces its
virtual shadow maps (``r.Shadow.Virtual.SMRT.*``; Epic's "Virtual Shadow Maps" documentation) and
Blender EEVEE-Next's "shadow map raytracing" does.

One depth map is rendered from the light's centre, fitted as pcss fits its map
(:func:`shadowlab.techniques.maps.toolkit.fit_light_views`, ``fit=receivers``: the outer penumbra
lies off the segments to the centre). One full-screen pass over the G-buffer then casts, per
evaluated pixel P, ``rays`` rays to points X_k on the light and marches each through the map:

**Light points.** Stratified: X_k lies in the k-th of ``rays`` equal-area strata of the unit square
(:func:`shadowlab.scene.area_lights.strata`), mapped onto the light — rect: centre + u·(s−½) +
v·(s−½); disc: Shirley & Chiu's concentric map onto the disc; sphere: the cap P sees, uniform by
area (as :meth:`SphereLight.sample_for`). With ``jitter`` (default, as UE, which draws per-pixel
random samples) the point within each stratum and the march's step offset come from an integer
hash of the pixel and the ray: per-pixel noise instead of ``rays`` overlapping hard shadows;
``jitter=false`` takes every stratum's centre and step offset ½, one pattern for every pixel.
A ray to a point on or below P's tangent plane counts as occluded, as the truth counts it
(:mod:`shadowlab.techniques.rays.raytrace`); a point behind a one-sided light sees V = 0.

**The march** (UE's SMRTRayCast, as read in Epic's shader and described here in our terms). The
ray R(t) = P + t (X − P), t = 0 at the receiver, 1 at the light point; window depth d of the map
grows away from the light (UE's reversed depth, sign flipped). The march runs from the light's
end towards the receiver at n + 1 points, n = ``samples``:

    t_i = t_s + (t_e − t_s) · ((n − 1 − i + o) / n)²  (i = 0 … n−1),   t_n = t_s,

UE's quadratic spacing, dense near the receiver (o: the step offset), t_e where the segment reaches
the map's near plane (points nearer the light are in no texel), t_s = 0 or the end of the screen
trace. Each point projects from the centre into the map: stored depth s_i at its texel and the
ray's own depth r_i (moved to that texel's centre along the receiver's plane — receiver plane
depth bias, Isidoro 2006, as pcss — minus ``bias``). Points off the map are skipped. Then:

- the first point is a plain depth test: blocked if s_0 < r_0; it starts the history
  (h = s_0 at t_h = t_0, slope g = 0);
- at each later point, with the tolerance τ_i = 1.05 · |r_i − r_{i−1}| (one step's change of the
  ray's depth): if r_i − s_i > τ_i the ray is behind the stored surface by more than one step
  can explain — it entered the centre's shadow of an occluder through its side, not through its
  front surface — and is compared with the extrapolated occluder c_i = h + g · (t_i − t_h),
  the last surface it passed in front of, continued along the ray. Otherwise c_i = s_i, and when
  s_i ≠ h the history moves on: g = clamp((s_i − h) / (t_i − t_h), −``slope``, ``slope``),
  h = s_i, t_h = t_i;
- the ray is blocked when 0 < r_i − c_i < τ_i: it crossed the (stored or extrapolated) surface
  within this step.

A ray that is never blocked reaches the light; V = the fraction of the ``rays`` rays that do.
The map holds only the surface nearest the centre, so everything behind it is guessed by the
extrapolation: a ray that slips behind an occluder's silhouette keeps following the surface it
saw before, and counts as blocked only if it crosses that surface's continuation — which also
darkens the inner penumbra under two casters at different heights, where a ray behind the upper
one crosses the lower one's continuation beyond that caster's real edge. A large
``slope`` lets a continuation that starts at a depth jump run away from the ray (softer penumbra
edges, as UE's cvar help says, but a ray passing behind a second occluder can then escape: light
leaks); a small one keeps the continuation nearly flat, so the ray soon crosses it. UE ships
``ExtrapolateMaxSlopeLocal`` = 0.05 (local lights; our area lights are local, so the default) and
``ExtrapolateMaxSlopeDirectional`` = 5.0, both per unit of its ray parameter in its device depth —
here per unit t in window depth, of the same scale for a perspective map whose far plane is far
beyond its near one. ``samples`` sets the tolerance too: fewer, longer steps give a larger τ,
so a ray that enters an occluder's shadow from its side is more often within one step of the
stored surface and counted as crossing it instead of being handed to the extrapolation — fewer
leaks (EEVEE's docs: leaking "mitigated by using lower step count"), at the price of coarser
penumbrae (tests/techniques/maps/test_smrt.py measures both).

**Screen trace** (UE's ``r.Shadow.Virtual.ScreenRayLength`` = 0.015): before the map's march, each
ray first walks :data:`SCREEN_STEPS` points of its first L = ``screen_ray`` × (the receiver's
distance from the camera) in world units through the G-buffer's position channel; a point behind
the surface the camera sees there (by more than :data:`SCREEN_TOLERANCE` pixels' footprint, less
than L) blocks the ray — contacts finer than a map texel. The map's march then starts at the
trace's end (t_s = L / |X − P|). ``screen_ray=0`` turns it off.
"""
from __future__ import annotations

import numpy as np

from ...gpu import programs, targets
from ...geometry.transforms import BIAS
from ...scene.area_lights import DiscLight, RectLight, strata
from ..base import FIRST, MAX, SUM, Param, PlotStyle, Technique, TuneRange
from .contact import ContactShadows
from .toolkit import (
    BASIS_HELPERS, BASIS_SWITCH, GBUFFER_TAPS, TexelMapping, centre_map_atlas, depth_defines, depth_pass, light_extents,
    lookup_pass, near_far,
)

#: Depth format of the map (24-bit fixed point, as pcss's).
DEPTH_BITS = 24
#: Points of each ray's screen-space trace (G-buffer taps per ray when ``screen_ray`` > 0).
SCREEN_STEPS = 8
#: The screen trace ignores surfaces less than this many pixels' footprint in front of its point
#: (the receiver's own surface, read at a neighbouring pixel's centre).
SCREEN_TOLERANCE = 2.0
#: Light shapes, as the shader's SHAPE_* numbers.
SHAPES = {"rect": 0, "disc": 1, "sphere": 2}
#: UE 5's ExtrapolateMaxSlopeDirectional (the ``slope`` of its directional lights).
UE_SLOPE_DIRECTIONAL = 5.0


class SMRT(ContactShadows, TexelMapping, Technique):
    """Shadow-map ray tracing (UE 5's virtual shadow maps): rays to the area light marched through
    one depth map from its centre, occluders behind silhouettes extrapolated with a clamped slope."""

    name = "smrt"
    summary = "shadow-map ray tracing (UE 5 virtual shadow maps): rays marched through one map, slope extrapolation"
    PASSES = ("depth", "lookup")
    STYLE = PlotStyle("#6b6ecf", "v")
    #: The rays go to points of the light's area: soft-shadow scenes only.
    LIGHTS = frozenset({"area"})
    STATS = {"memory_bytes": MAX, "passes": SUM, "rays": SUM, "samples": FIRST, "texel_world": FIRST}
    READS = frozenset({"position", "normal"})
    PROVIDES = frozenset({"texel_mapping"})
    PARAMS = {
        "rays": Param(7, "rays per pixel to stratified points of the light (UE: SMRT.RayCountLocal = 7)",
                      min=1, max=64,
                      # visibility steps of 1/rays: from a hard-ish 1 ray to a smooth 32
                      tune=TuneRange(1, 32, log=True)),
        "samples": Param(8, "map samples marched per ray, plus one at the ray's start (UE: "
                            "SMRT.SamplesPerRayLocal = 8)", min=1, max=64,
                         # UE's range: 2 (cheap, misses thin casters) to 32
                         tune=TuneRange(2, 32, log=True)),
        "slope": Param(0.05, "largest |d window depth / dt| of an extrapolated occluder behind a "
                             "silhouette (UE: ExtrapolateMaxSlopeLocal = 0.05; Directional = 5.0): larger "
                             "is softer and leaks behind second occluders", min=0.0, max=1000.0,
                       # UE's local to beyond its directional value
                       tune=TuneRange(0.005, 10.0, log=True)),
        "resolution": Param(2048, "shadow map width and height in texels", min=16, max=16384,
                            # powers of two; the march's cost does not grow with it, the map's memory does
                            tune=TuneRange(256, 4096, log=True)),
        "bias": Param(0.002, "constant depth bias in window-depth units [0, 1], subtracted from the ray's "
                             "depth at every sample (as pcss)", min=0.0, max=1.0,
                      # orders of magnitude from acne to detached contacts, as pcss's bias
                      tune=TuneRange(1e-5, 0.05, log=True)),
        "screen_ray": Param(0.015, "length of each ray's screen-space trace through the G-buffer before "
                                   "the map's march, x the receiver's distance from the camera (UE: "
                                   "ScreenRayLength = 0.015); 0: off", min=0.0, max=1.0,
                            # off to ten times UE's
                            tune=TuneRange(0.0, 0.15)),
        "jitter": Param(True, "jitter each ray's light point within its stratum and its step offset per "
                              "pixel (integer hash); false: one fixed pattern for every pixel"),
    }

    def setup(self, frame, slot) -> None:
        """Fit the map's frustum, allocate the map, the programs and their uniforms."""
        light = slot.light
        self.atlas, notes = centre_map_atlas(frame, slot, self.resolution, self.name)
        self.notes.extend(notes)
        face = self.atlas.faces[0]
        self.map = self.own(targets.DepthTexture.create(self.atlas.size, DEPTH_BITS))
        self.depth_prog = self.program("shadow_depth.glsl", defines=depth_defines())
        self.lookup_prog = self.program("smrt.glsl", defines={"RAYS": self.rays, "SCREEN_STEPS": SCREEN_STEPS,
                                                            "SCREEN_TOLERANCE": f"{SCREEN_TOLERANCE:.6f}"})
        near, _ = near_far(face.proj)
        extents = light_extents(light, face.view, owner=self.name)
        shape = 0 if isinstance(light, RectLight) else 1 if isinstance(light, DiscLight) else 2
        lo, size = strata(self.rays)
        normal = light.normal if light.one_sided else np.zeros(3)
        camera = frame.camera
        programs.set_uniforms(self.lookup_prog, light.uniforms())
        self.lookup_prog["u_light_matrix"].write(programs.mat_bytes(BIAS @ face.view_proj))
        self.lookup_prog["u_light_view"].write(programs.mat_bytes(face.view))
        self.lookup_prog["u_light_extents"].write(np.ascontiguousarray(extents.T, dtype="f4").tobytes())
        self.lookup_prog["u_camera_view_proj"].write(programs.mat_bytes(frame.view_projection))
        programs.set_uniforms(self.lookup_prog, {
            "u_map": 2, "u_near": near, "u_bias": float(self.bias), "u_max_slope": float(self.slope),
            "u_texel_angle": float(face.texel_angle),
            "u_basis_switch": BASIS_SWITCH, "u_basis_helper_a": BASIS_HELPERS[0],
            "u_basis_helper_b": BASIS_HELPERS[1],
            "u_shape": shape, "u_light_radius": float(getattr(light, "radius", 0.0)),
            "u_one_sided": int(light.one_sided), "u_light_normal": tuple(map(float, normal)),
            "u_rays": self.rays, "u_samples": self.samples, "u_jitter": int(self.jitter),
            "u_strata_lo": lo.astype(np.float32), "u_strata_size": size.astype(np.float32),
            "u_screen_ray": float(self.screen_ray), "u_camera_eye": tuple(map(float, camera.eye)),
            "u_pixel_angle": float(2.0 * np.tan(np.radians(camera.fov_y) / 2.0) / frame.height),
        })
        self.evaluated_pixels = int(np.count_nonzero(slot.evaluated))
        self.quad = self.fullscreen_quad(self.lookup_prog)
        self.vis_tex, self.vis_fbo = self.visibility_target((frame.width, frame.height))

    def render(self) -> None:
        """The depth pass from the light's centre, then the march over the G-buffer."""
        with self.timed_pass("depth"):
            depth_pass(self.frame, self.map, self.depth_prog, self.atlas)
        with self.timed_pass("lookup"):
            lookup_pass(self, self.vis_fbo, self.quad, self.map.texture)

    def samples_per_pixel(self) -> int:
        """Texels one evaluated pixel's rays read at most: per ray ``samples`` + 1 map samples and,
        with the screen trace on, :data:`SCREEN_STEPS` G-buffer positions (rays that end early read
        fewer)."""
        return self.rays * (self.samples + 1 + (SCREEN_STEPS if self.screen_ray > 0 else 0))

    def work(self, counted: dict, stats: dict) -> dict:
        """Texture taps per lookup fragment, at most: the G-buffer's position and normal, then
        :meth:`samples_per_pixel` (the march stops at a ray's first crossing)."""
        return self.taps_work(counted, {"lookup": GBUFFER_TAPS + self.samples_per_pixel()})

    def stats(self) -> dict:
        """Map memory, passes, the rays cast (rays × evaluated pixels) and the texels marched per
        pixel (at most)."""
        return {"memory_bytes": self.map.nbytes, "passes": 2, "rays": self.rays * self.evaluated_pixels,
                "samples": self.samples_per_pixel(), "texel_world": None}
