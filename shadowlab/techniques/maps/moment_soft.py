"""Moment soft shadow mapping (Peters, Münstermann, Wetzstein & Klein, I3D 2016) from an area light.

Christoph Peters, Cedrick Münstermann, Nico Wetzstein, Reinhard Klein, "Beyond Hard Shadows:
Moment Shadow Maps for Single Scattering, Soft Shadows and Translucent Occluders", I3D 2016, its
section on moment soft shadow mapping (and the extended version, JCGT 6(1) 2017): PCSS's three
steps (Fernando 2005) on a moment shadow map, each region read from a summed-area table (SAT,
Crow 1984) of its four moments in a constant number of taps whatever its size.

Passes:

1. ``moments`` — the casters from the light's centre into one RGBA32F map (the filtered-map
   toolkit's moments pass, ``shadowlab/techniques/maps/filtered_depth.glsl`` with ``HEIGHT_DEPTH``) through a
   square frustum along a one-sided light's normal (:func:`normal_view`, turned so that its x
   axis is a rect's edge u: :func:`aligned_face`; a sphere light: the map toolkit's fit): per texel the
   four moments of the nearest caster's normalised height z = (h − h_lo) / (h_hi − h_lo) above the
   light's plane, in the optimised basis of Peters & Klein 2015 §4 (:data:`~shadowlab.techniques.
   filtered_map.MSM_QUANTIZE`, which keeps the moments of any z in [0, 1] inside [0, 1]). Heights
   are PCSS's parallel planes (:func:`~shadowlab.techniques.maps.toolkit.height_axis`): with them a
   receiver parallel to the light has one depth across any region. Along the normal the planes
   of constant height are the map's planes of constant depth, so the region at one height is an
   exact rectangle of texels of one size.
2. ``sat`` — the SAT of that map (compute, ``shadowlab/techniques/maps/moment_soft_sat.glsl``): row prefix sums,
   then column prefix sums.
3. ``lookup`` — per pixel (``shadowlab/techniques/maps/moment_soft.glsl``): the blocker search averages the
   moments over the search region (PCSS's: the light seen from the receiver through the
   casters' lowest height, :func:`~shadowlab.techniques.maps.toolkit.search_height`; one SAT rectangle,
   4 taps) and estimates the average blocker depth from them (the paper's estimate: the mean of
   the canonical three-point distribution's support in front of the receiver); the penumbra
   estimate takes the region through that height (parallel planes, as ``pcss``); the
   Hamburger 4MSM reconstruction (Peters & Klein 2015, ``shadowlab/techniques/maps/msm.glsl``, shared with
   ``filtered_map``) gives the visibility from the moments averaged over that region (one SAT
   rectangle with fractional edges, 16 taps).

SAT precision, the method's known weakness: a float32 table sums ~0.5 per texel and moment to
~5·10⁵ at the far corner of a 1024² map, where one float32 step is 2⁻⁵; a small rectangle
there, the difference of four such sums, keeps only a few bits of its moments, and the
reconstruction turns the error into light leaks and false shadow (on soft_overlap: see
docs/soft-shadows.md). The remedy (the paper's, with its published demo): a
fixed-point table of 32-bit unsigned integers (``sat_precision=
fixed32``, the default). Integer sums wrap around 2³², but a rectangle's sum taken from four
wrapped entries in the same modular arithmetic is exact as long as its true sum is below 2³²;
each moment is stored as round(m · s) with s = ⌊(2³² − 1) / A⌋ and A the largest rectangle (in
texels) any lookup reads — computed in :meth:`MomentSoftShadows.setup` from the evaluated
receivers' search regions (:func:`max_region_texels`), which hold every filter region. So the
table costs no more than float32 and a rectangle's average is exact to half a step, 0.5 / s
(``stats()['sat_bits']`` = log2 s, reported per run: 12 where a search region spans the whole
1024² map). ``sat_precision=float32`` sums the same moments in float32: the
artefact, on purpose.

The moments are biased towards Peters et al. 2017's three-point target
(:data:`SIGNED_BIAS_TARGET`), not filtered_map's 2015 one, which is singular exactly where a
caster at the top of the height range lies over the floor at its bottom.

Visibility approximates docs/metrics.md's: one average blocker depth for everything in the search
region (two casters at different heights get one penumbra width: hard case SS2, scene
``soft_two_heights``), box-shaped regions bounding the light's projection (a disc light's square),
and the 4MSM reconstruction's own light leaking where three or more depths fall in one region.
Receivers steep to the light span a large depth range over a region; each is compared at its
plane's lowest depth there (``receiver_plane``), which hides real blockers (``soft_below_plane``'s
slab, perpendicular to its light: lit, as pcss draws it). The receiver's horizon is not
modelled. Points behind a one-sided light get V = 0.
``blocker_search=false`` filters every pixel over a fixed square of ``fixed_filter`` texels
(filtered 4MSM from the SAT): no contact hardening.
"""
from __future__ import annotations

import numpy as np

from ...gpu import glstate, programs, targets
from ...geometry import frusta
from ...geometry.frusta import LightView
from ...geometry.transforms import BIAS, look_along, look_at
from ...scene.area_lights import RectLight
from ...gpu.glstate import PassState
from ..base import FIRST, MAX, SUM, Param, PlotStyle, Technique, TuneRange
from .filtered_map import (
    MSM_DEQUANTIZE, MSM_QUANTIZE, MSM_QUANTIZE_OFFSET, VARIANT_DEFINES, VARIANT_ID, msm_quantize,
)
from .toolkit import (
    BASIS_HELPERS, BASIS_SWITCH, Atlas, TexelMapping, fit_light_views, height_axis, light_extents,
    light_size, near_far, search_height,
)
from .contact import ContactShadows

#: The two SAT formats: 32-bit fixed point summed modulo 2³² (the paper's remedy), float32 (the artefact).
SAT_PRECISIONS = ("fixed32", "float32")
#: Largest value of the fixed-point table's unsigned 32-bit sums.
UINT32_MAX = 2 ** 32 - 1
#: Invocations per work group of the SAT passes (one invocation per row, then per column).
LOCAL_SIZE = 64
#: The SAT passes' ``u_pass`` values (``shadowlab/techniques/maps/moment_soft_sat.glsl``).
ROW_PASS, COLUMN_PASS = 0, 1
#: The fully-lit bias ε of the blocker average (ε t + Σ w z) / (ε + Σ w): Peters et al.'s
#: published shader code (JCGT 2017 demo) uses 10⁻³; where almost nothing blocks, it pulls the
#: average to the receiver (a small kernel) instead of dividing by a vanishing weight.
LIT_BIAS = 1e-3
#: The smallest filter region's side, in texels (the demo's minimal kernel of one texel).
MIN_FILTER = 1.0
#: Bytes per texel: the RGBA32F moments map, the RGBA32 table, the depth renderbuffer.
MOMENT_BYTES, SAT_BYTES, DEPTH_BUFFER_BYTES = 16, 16, 4
#: Texel margin added on each side of the search regions when bounding their area: the shader
#: computes them in float32 and rounds them outwards (one texel), the numpy bound in float64.
REGION_MARGIN = 2.0
#: Map texels read per fragment or invocation: the G-buffer (position and normal), the search's
#: rectangle (4 SAT taps), the filter's with fractional edges (16).
GBUFFER_TAPS, SEARCH_TAPS, FILTER_TAPS = 2, 4, 16
#: The moment bias target of Peters et al., JCGT 2017 ("Improved Moment Shadow Maps...", their
#: improvements to moment shadow mapping itself, and the authors' published shader code),
#: for signed depth s in [−1, 1]: (E[s], E[s²], E[s³], E[s⁴]) = (0, 0.628, 0, 0.628), the moments of
#: the three points −1, 0, 1 with weights 0.314, 0.372, 0.314 (:func:`unsigned_bias_target` maps it
#: to z = (s + 1) / 2). The 2015 target (½, ½, ½, ½) of filtered_map is the two-point {0, 1}
#: distribution, whose Hankel matrix is singular: a region holding only a caster at z = 0 and the
#: floor at z = 1 (soft_overlap's high plank over the floor) stays singular after biasing, and
#: float32 gave d33 < 0 there — white speckles in the high plank's shadow, measured with the
#: 2015 target.
SIGNED_BIAS_TARGET = (0.0, 0.628, 0.0, 0.628)
#: Near and far planes of the map when no receiver lies in front of the light (nothing to map).
EMPTY_NEAR_FAR = (1.0, 2.0)
#: The height range's top lies this fraction above the highest caster or receiver.
HEIGHT_PAD = 1e-3
#: Corners of the unit square centred on 0: the light's corners are centre + extents · these.
CORNERS = np.array([[-0.5, -0.5], [0.5, -0.5], [-0.5, 0.5], [0.5, 0.5]])


def unsigned_bias_target(signed=SIGNED_BIAS_TARGET) -> tuple[float, float, float, float]:
    """The moments (E[z], …, E[z⁴]) of z = (s + 1) / 2 from those of s (E[s], …, E[s⁴]):
    E[z^k] = Σ_j C(k, j) E[s^j] / 2^k (binomial expansion, E[s⁰] = 1)."""
    from math import comb

    m = (1.0,) + tuple(float(v) for v in signed)
    return tuple(sum(comb(k, j) * m[j] for j in range(k + 1)) / 2.0 ** k for k in range(1, 5))


def normal_view(light, receivers: np.ndarray, casters: frusta.Casters, resolution: int) \
        -> tuple[LightView, list[str]]:
    """A square perspective view from a one-sided light's centre along its normal, wide enough
    for the ``receivers`` (M, 3) in front of the light (their largest angle from the normal,
    capped at :data:`~shadowlab.geometry.frusta.MAX_POINT_HALF_ANGLE`), and notes for the run.

    Along the normal the planes parallel to the light are the map's planes of constant depth,
    and each projects onto the map by a similarity: the region at one height is an exact
    rectangle (with :func:`aligned_face`), and a box average over it in texels is a uniform
    average over the light's copy. The map toolkit's fit looks along the receivers' mean
    direction instead (47° from the normal on ``soft_banding``, a 160° frustum), where the
    same light-sized region covers texels of very different sizes and the box average weighed
    its far side less: the whole penumbra moved towards the near side (a visibility error
    several times pcss's there)."""
    p = np.asarray(light.position, np.float64)
    axis = np.asarray(light.normal, np.float64)
    d = np.asarray(receivers, np.float64) - p
    dist = np.linalg.norm(d, axis=1)
    cos = (d @ axis) / np.where(dist > 0, dist, 1.0)
    front = cos > 0.0  # behind the emitting plane: V = 0 in the lookup, no need to map them
    notes = []
    if not front.any():  # nothing to answer (every receiver sees V = 0): any valid frustum will do
        return frusta.perspective_view(p, axis, 2 * frusta.MAX_POINT_HALF_ANGLE, *EMPTY_NEAR_FAR, resolution), notes
    angles = np.degrees(np.arccos(np.clip(cos[front], -1.0, 1.0)))
    half = float(angles.max()) * (1 + frusta.PAD)
    if half > frusta.MAX_POINT_HALF_ANGLE:
        outside = int(np.sum(angles > frusta.MAX_POINT_HALF_ANGLE))
        notes.append(f"moment_soft: receivers lie up to {half:.1f} degrees from the light's normal, more than the "
                     f"map's {frusta.MAX_POINT_HALF_ANGLE}; {outside} of them lie outside the map and are treated as lit")
        half = frusta.MAX_POINT_HALF_ANGLE
    # The near plane is fitted over the cone around the square (tan × √2): aligned_face may turn the
    # square about its axis afterwards, and its corners must not lose a nearer caster.
    cone = 2 * float(np.degrees(np.arctan(np.sqrt(2.0) * np.tan(np.radians(half)))))
    near, far, fit_notes = frusta.perspective_fit(p, d[front] + p, casters, [look_along(p, axis)], cone)
    return frusta.perspective_view(p, axis, 2 * half, near, far, resolution), notes + fit_notes


def aligned_face(face: LightView, edge: np.ndarray) -> LightView:
    """``face`` turned about its own axis so that the map's x axis is the light's ``edge`` (3,)
    seen along that axis (unchanged when the edge is along the axis). The fitted frustum is a
    square cone around its axis (:func:`~shadowlab.geometry.frusta.perspective_view`), so the
    turned face covers what it covered; a rect light's regions are then boxes along the map's
    axes, and their bounding boxes in the map are tight where the map looks along the light's
    normal (turned 26° on ``soft_overlap``, the bounding box of the light's square was 1.8x its area)."""
    view = face.view
    forward = -view[2, :3]
    centre = -view[:3, :3].T @ view[:3, 3]  # the view's eye: view = [R | −R · eye]
    up = np.cross(edge, forward)             # forward × (edge × forward) = edge seen along the axis
    if np.linalg.norm(up) < 1e-9 * np.linalg.norm(edge):
        return face
    return LightView(look_at(centre, centre + forward, up), face.proj, texel_world=face.texel_world,
                     texel_angle=face.texel_angle)


def region_texels(points: np.ndarray, heights: np.ndarray, h: float, centre: np.ndarray, extents: np.ndarray,
                  light_matrix: np.ndarray, size: int) -> np.ndarray:
    """(M, 4) float64: per receiver point (M, 3) at height ``heights`` (M,) above the light, the
    map rectangle (x0, y0, x1, y1) in texels bounding its region at height ``h`` — the four
    points at height h on the segments from the point to the light's corners (``centre`` (3,) +
    ``extents`` (3, 2) · (±½, ±½)), projected by ``light_matrix`` (4, 4: BIAS · projection · view)
    into a ``size``² map; as ``region()`` in ``shadowlab/techniques/maps/moment_soft.glsl``."""
    points = np.asarray(points, np.float64)
    s = np.clip((heights - h) / heights, 0.0, 1.0)[:, None, None]
    corners = centre + CORNERS @ extents.T  # (4, 3)
    q = points[:, None, :] + s * (corners[None] - points[:, None, :])  # (M, 4, 3)
    hom = np.concatenate([q, np.ones(q.shape[:2] + (1,))], axis=2) @ light_matrix.T
    uv = hom[..., :2] / hom[..., 3:4] * size
    return np.concatenate([uv.min(axis=1), uv.max(axis=1)], axis=1)


def max_region_texels(regions: np.ndarray, size: int, margin: float = REGION_MARGIN) -> float:
    """The largest area, in texels, of the rectangles ``regions`` (M, 4: x0, y0, x1, y1) grown by
    ``margin`` on each side and clipped to the ``size``² map (at least one texel): the largest
    rectangle a lookup reads from the SAT, which the fixed-point scale must keep below 2³²."""
    if len(regions) == 0:
        return 1.0
    lo = np.clip(regions[:, :2] - margin, 0.0, size)
    hi = np.clip(regions[:, 2:] + margin, 0.0, size)
    return float(max(1.0, np.prod(np.maximum(hi - lo, 1.0), axis=1).max()))


def fixed_scale(max_texels: float) -> int:
    """The fixed-point steps per unit moment of the 32-bit table: ⌊(2³² − 1) / A⌋ for the largest
    rectangle A (texels) a lookup reads — every moment lies in [0, 1], so no rectangle's true
    sum reaches 2³² and its modular sum is exact."""
    return max(1, int(UINT32_MAX // int(np.ceil(max_texels))))


class MomentSoftShadows(ContactShadows, TexelMapping, Technique):
    """Moment soft shadow mapping: blocker search and filter from a summed-area table of a
    four-moment shadow map (module docstring)."""

    name = "moment_soft"
    summary = ("moment soft shadow mapping (Peters et al. 2016): blocker search and 4-moment filtering "
               "from a summed-area table of a moment shadow map")
    PASSES = ("moments", "sat", "lookup")
    STYLE = PlotStyle("#c49c94", "H")
    #: An area light's size sets the regions (as PCSS).
    LIGHTS = frozenset({"area"})
    STATS = {"memory_bytes": MAX, "faces": FIRST, "passes": SUM, "depth_range": FIRST, "light_size": FIRST,
             "texel_world": FIRST, "sat_bits": FIRST, "max_region_texels": FIRST}
    READS = frozenset({"position", "normal"})
    PROVIDES = frozenset({"texel_mapping"})
    PARAMS = {
        "resolution": Param(1024, "moment map (and SAT) width and height in texels", min=16, max=4096,
                            # the paper's 1024²; the SAT's 16 bytes a texel make 4096² cost 256 MiB
                            tune=TuneRange(256, 2048, log=True)),
        "sat_precision": Param("fixed32", "the SAT's sums: fixed32 (32-bit fixed point summed modulo 2^32, exact "
                                          "rectangles: the paper's remedy) or float32 (the classic table: the "
                                          "artefact)", choices=SAT_PRECISIONS),
        "bias": Param(1e-3, "constant depth bias, in units of the normalised height range [0, 1], subtracted from "
                            "the receiver's depth", min=0.0, max=1.0,
                      # from none (acne on tilted receivers) to a bias that detaches contacts
                      tune=TuneRange(1e-5, 0.05, log=True)),
        "moment_bias": Param(3e-5, "alpha in b' = (1 - alpha) b + alpha b*, b* the moments of 0, 1/2, 1 weighted "
                                   "0.314, 0.372, 0.314 (Peters et al. 2017's target)",
                             min=0.0, max=0.99, min_open=True,
                             # from float32 round-off to a bias that visibly lightens the shadows
                             tune=TuneRange(1e-6, 1e-2, log=True)),
        "receiver_plane": Param(True, "compare at the receiver plane's lowest depth over each region (Isidoro "
                                      "2006's plane, its lower envelope) instead of the centre's depth"),
        "blocker_search": Param(True, "false: skip the blocker search and penumbra estimate, filter every pixel "
                                      "over a fixed square of fixed_filter texels"),
        "fixed_filter": Param(8.0, "blocker_search=false: the fixed square's side, in texels", min=1.0,
                              max=4096.0,
                              # one texel (hard) to a penumbra 32 texels wide
                              tune=TuneRange(1.0, 32.0)),
    }

    def setup(self, frame, slot) -> None:
        """Fit the map's frustum (as pcss), the height range, the SAT's fixed-point scale from the
        receivers' search regions, the textures and the three programs."""
        ctx, light = frame.ctx, slot.light
        res = self.resolution
        # Every evaluated receiver, as pcss (the outer penumbra stays on the map); a one-sided
        # light's map looks along its normal (normal_view), a sphere's along the fitted axis.
        receivers = frame.compact_position[slot.evaluated]
        if light.one_sided:
            face, notes = normal_view(light, receivers, frame.casters(), res)
        else:
            faces, notes = fit_light_views(frame, slot, res, "frustum", 0.0, "receivers")
            face = faces[0]
        self.notes.extend(notes)
        if isinstance(light, RectLight):
            face = aligned_face(face, light.u)
        self.atlas = Atlas.grid([face], res, self.name)
        proj, view = face.proj, face.view
        near, _ = near_far(proj)
        centre = np.asarray(light.position, np.float64)
        extents = light_extents(light, view, self.name)
        axis = height_axis(light, view)
        bounds = frame.caster_bounds()
        self.search_height = search_height(axis, centre, bounds, near, -view[2, :3], self.name)
        heights = (receivers - centre) @ axis
        # Heights of the casters' box corners and of the receivers: the range z = 0 … 1 spans.
        corners = np.stack(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij"), -1).reshape(-1, 3)
        caster_heights = ((bounds[:, corners, [0, 1, 2]].reshape(-1, 3) - centre) @ axis) if len(bounds) else heights
        # (padded: a floor alone still has a range, and it lies below the empty texels' z = 1)
        self.h_lo = self.search_height
        self.h_hi = float(max(caster_heights.max(initial=self.h_lo), heights.max(initial=self.h_lo))) * (1 + HEIGHT_PAD)
        light_matrix = BIAS @ face.view_proj
        shadowed = heights > self.search_height
        if self.blocker_search:
            regions = region_texels(receivers[shadowed], heights[shadowed], self.search_height, centre, extents,
                                    light_matrix, res)
            self.max_region = max_region_texels(regions, res)
        else:
            self.max_region = 1.0
        side = max(self.fixed_filter if not self.blocker_search else 0.0, MIN_FILTER) + 2 * REGION_MARGIN
        self.max_region = float(min(max(self.max_region, side * side), (res + 1) ** 2))
        fixed = self.sat_precision == "fixed32"
        self.scale = fixed_scale(self.max_region) if fixed else None

        # Textures: the moments (with a depth buffer), the SAT.
        self.moments = self.own(ctx.texture((res, res), 4, dtype="f4"))
        self.depth_rb = self.own(ctx.depth_renderbuffer((res, res)))
        self.moments_fbo = self.own(targets.framebuffer([self.moments], self.depth_rb))
        self.sat = self.own(ctx.texture((res, res), 4, dtype="u4" if fixed else "f4"))
        for tex in (self.moments, self.sat):
            tex.filter = (ctx.NEAREST, ctx.NEAREST)  # read texel by texel (an integer texture must not filter)
            tex.repeat_x = tex.repeat_y = False
        self.clear = tuple(float(v) for v in msm_quantize(np.ones(4)))  # the moments of z = 1: nothing casts

        self.depth_prog = self.program("filtered_depth.glsl", defines={**VARIANT_DEFINES, "HEIGHT_DEPTH": 1})
        self.depth_prog["u_light_view_proj"].write(programs.mat_bytes(face.view_proj))
        self.depth_prog["u_quantize"].write(programs.mat_bytes(MSM_QUANTIZE))
        programs.set_uniforms(self.depth_prog, {"u_near": self.h_lo, "u_far": self.h_hi, "u_variant": VARIANT_ID["msm"],
                                                "u_quantize_offset": tuple(map(float, MSM_QUANTIZE_OFFSET)),
                                                "u_height_origin": tuple(map(float, centre)),
                                                "u_height_axis": tuple(map(float, axis))})
        sat_defines = {"LOCAL_SIZE": LOCAL_SIZE, **({"SAT_FIXED": 1} if fixed else {})}
        self.sat_prog = self.program("moment_soft_sat.glsl", defines=sat_defines)
        programs.set_uniforms(self.sat_prog, {"u_moments": 0, "u_sat": 0, "u_size": (res, res),
                                              **({"u_fixed_scale": float(self.scale)} if fixed else {})})

        self.lookup_prog = self.program("moment_soft.glsl", defines={"SAT_FIXED": 1} if fixed else {})
        programs.set_uniforms(self.lookup_prog, light.uniforms())
        self.lookup_prog["u_light_matrix"].write(programs.mat_bytes(light_matrix))
        self.lookup_prog["u_light_extents"].write(np.ascontiguousarray(extents.T, dtype="f4").tobytes())
        self.lookup_prog["u_dequantize"].write(programs.mat_bytes(MSM_DEQUANTIZE))
        normal = light.normal if light.one_sided else np.zeros(3)
        programs.set_uniforms(self.lookup_prog, {
            "u_sat": 2,
            "u_sat_step": 1.0 / self.scale if fixed else 1.0,
            "u_height_axis": tuple(map(float, axis)), "u_search_height": self.search_height,
            "u_height_range": (self.h_lo, self.h_hi),
            "u_quantize_offset": tuple(map(float, MSM_QUANTIZE_OFFSET)),
            "u_moment_bias": float(self.moment_bias), "u_moment_bias_target": unsigned_bias_target(),
            "u_bias": float(self.bias), "u_lit_bias": LIT_BIAS, "u_min_filter": MIN_FILTER,
            "u_receiver_plane": int(self.receiver_plane), "u_texel_angle": float(face.texel_angle),
            "u_basis_switch": BASIS_SWITCH, "u_basis_helper_a": BASIS_HELPERS[0],
            "u_basis_helper_b": BASIS_HELPERS[1],
            "u_search": int(self.blocker_search), "u_fixed_filter": float(self.fixed_filter),
            "u_one_sided": int(light.one_sided), "u_light_normal": tuple(map(float, normal)),
        })
        self.quad = self.fullscreen_quad(self.lookup_prog)
        self.vis_tex, self.vis_fbo = self.visibility_target((frame.width, frame.height))

    def _dispatch(self, pass_id: int) -> None:
        """One SAT pass: an invocation per row (``ROW_PASS``) or per column (``COLUMN_PASS``)."""
        self.sat_prog["u_pass"].value = pass_id
        self.sat_prog.run(-(-self.resolution // LOCAL_SIZE))

    def render(self) -> None:
        """The moments from the light's centre, the SAT's two prefix-sum passes, the lookup."""
        from OpenGL import GL

        ctx = self.frame.ctx
        with self.timed_pass("moments"):
            self.moments_fbo.use()
            glstate.apply(PassState(depth_test=True, depth_func="<", depth_write=True))
            ctx.viewport = (0, 0, self.resolution, self.resolution)
            GL.glClearBufferfv(GL.GL_COLOR, 0, self.clear)
            GL.glClearBufferfv(GL.GL_DEPTH, 0, (1.0,))
            self.frame.draw(self.depth_prog, "casters")
        with self.timed_pass("sat"):
            self.moments.use(0)
            self.sat.bind_to_image(0, read=True, write=True)
            self._dispatch(ROW_PASS)
            ctx.memory_barrier()  # the rows' stores before the columns' loads
            self._dispatch(COLUMN_PASS)
            ctx.memory_barrier()  # the table's stores before the lookup's texel fetches
        with self.timed_pass("lookup"):
            self.vis_fbo.use()
            glstate.apply(PassState())
            self.bind_gbuffer(self.lookup_prog)
            self.sat.use(2)
            self.quad.render()

    def sat_table(self) -> np.ndarray:
        """The SAT as rendered (valid after :meth:`render`): (height, width, 4), row 0 = the map's
        first row (y up, as the table sums), uint32 (fixed32: the sums modulo 2³² of the
        fixed-point moments) or float32."""
        dtype = "u4" if self.sat_precision == "fixed32" else "f4"
        return np.frombuffer(self.sat.read(), dtype=np.dtype(dtype)).reshape(self.resolution, self.resolution, 4)

    def moment_map(self) -> np.ndarray:
        """The moments map as rendered (valid after :meth:`render`): float32 (height, width, 4),
        row 0 = the map's first row, the optimised basis (:data:`MSM_QUANTIZE`)."""
        return np.frombuffer(self.moments.read(), dtype=np.float32).reshape(self.resolution, self.resolution, 4)

    def work(self, counted: dict, stats: dict) -> dict:
        """Texture taps: each SAT invocation reads its whole row or column (``resolution``
        texels); the lookup reads the G-buffer's position and normal, the search's 4 SAT taps
        (with the blocker search on) and the filter's 16."""
        per = GBUFFER_TAPS + (SEARCH_TAPS if self.blocker_search else 0) + FILTER_TAPS
        return self.taps_work(counted, {"sat": self.resolution, "lookup": per})

    def stats(self) -> dict:
        """Memory (moments, depth buffer, SAT), passes per frame (moments, two SAT dispatches,
        lookup), the height range, the light size, the fixed-point bits and the largest
        rectangle they were sized for."""
        texels = self.resolution ** 2
        return {"memory_bytes": texels * (MOMENT_BYTES + SAT_BYTES + DEPTH_BUFFER_BYTES), "faces": 1, "passes": 4,
                "depth_range": self.h_hi - self.h_lo, "light_size": light_size(self.light),
                "texel_world": float(self.atlas.faces[0].texel_world) or None,
                "sat_bits": float(np.log2(self.scale)) if self.scale else None,
                "max_region_texels": self.max_region}
