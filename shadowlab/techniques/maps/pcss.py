"""Percentage-closer soft shadows (Fernando 2005) from an area light.

Randima Fernando, "Percentage-Closer Soft Shadows", SIGGRAPH 2005 sketch; NVIDIA's whitepaper
"Integrating Realistic Soft Shadows into Your Game Engine" (Bavoil 2008) for the uv scaling.
One depth map is rendered from the light's centre (a perspective frustum, the shadow map's
fitting: :func:`shadowlab.techniques.maps.toolkit.fit_light_views`). Fernando's parallel planes
are planes parallel to the light: h is the height above the light's plane along
:func:`height_axis` (rect, disc: the normal; sphere: the map's axis), h_r the receiver's. The
light seen from the receiver P and cut by the plane at height h is a copy of the light scaled
by (h_r − h) / h_r towards P; its taps are the points at height h on the segments from P to a
fixed pattern of light points X_i, projected from the centre into the map. Per pixel:

1. blocker search: the average height h_b of the map samples closer than the receiver (minus
   ``bias``) among the taps through the search height (:func:`search_height`, the casters'
   lowest: the largest slice, holding every lower one); no blocker → lit;
2. penumbra estimate, parallel planes: w = (h_r − h_b) · light size / h_b (world, at the
   receiver), implied by
3. PCF over the taps through h_b: tap i is lit when the ray P → X_i passes the blocker plane.

With the map's axis along the light's normal (h = linear depth z, near plane n) these are the
paper's regions exactly, in uv: search light_uv × (z_r − n) / z_r, PCF light_uv × (z_r − z_b) /
z_b × n / z_r, light_uv the light's extent at the near plane (:func:`light_uv`). A fitted frustum
can look along an axis far from the light's normal (scene ``soft_banding``: 47°, 160° wide,
near 0.37): depth along it is no height above the light, the light's own corners lie at depths
±0.73, beyond the near plane, and regions scaled in depth gave wrong kernels there.

The light's shape: rect — its two full edges u, v; disc — two orthogonal diameters of the disc;
sphere — its diameter along the map's x and y (the silhouette disc seen from the centre's axis)
(``shadowlab/techniques/maps/pcss.glsl``: ``u_light_extents``, world columns). The sample offsets are the centres
of N equal-area strata (:func:`shadowlab.scene.area_lights.strata`) of the unit square (rect), mapped
to the disc by the concentric map for disc and sphere — one fixed pattern for every pixel, so
visibility comes in steps of 1 / ``filter_samples``. ``stats()['light_size']`` reports the scalar
light size of the paper's formula: a rect's longer edge, a disc's or sphere's diameter.

Visibility here approximates docs/metrics.md's (the fraction of the light's area seen unoccluded):
PCSS assumes blockers and receiver parallel to the light and one average blocker height, so
overlapping blockers at different depths and the receiver's horizon (samples below its tangent
plane count as occluded in the truth) are not modelled. Points behind a one-sided light get
V = 0, as in the definition. Each tap is compared with the receiver's plane extrapolated to
it (receiver plane depth bias, Isidoro 2006), so wide kernels on a receiver tilted to the map
do not shadow themselves; ``receiver_plane=false`` compares every tap with the centre's depth.
Empty texels (still at the clear depth: no caster up to the far plane) never block: extrapolated
to them, the receiver's plane can pass the far plane (a wide map along a tilted axis, scene
``soft_banding``), and a cleared texel taken for a blocker at the far plane put the average
blocker behind the receiver and the kernel at 0: a hard shadow (soft_large_close's penumbra
was lost without this rule).

``blocker_search=false`` skips steps 1-2 and filters every pixel over light_uv, scaled so its
larger extent is ``fixed_filter`` texels: classic fixed-size PCF, whose penumbra width
does not grow with the blocker-receiver distance (scene ``soft_contact_hardening``).
"""
from __future__ import annotations

import numpy as np

from ...gpu import programs, targets
from ...scene.area_lights import RectLight, concentric_disc, strata
from ...geometry.transforms import BIAS
from ..base import FIRST, MAX, SUM, Param, PlotStyle, Technique, TuneRange
# The parallel-planes geometry is the map toolkit's, shared with moment_soft (imported here by
# name, so ``pcss.near_far`` and the others stay where the tests and older code look for them).
from .toolkit import (
    BASIS_HELPERS, BASIS_SWITCH, CLEAR_DEPTH, TexelMapping, centre_map_atlas, depth_defines, depth_pass, height_axis,
    light_extents, light_size, lookup_pass, near_far, search_height,
)
from .contact import ContactShadows

#: Depth format of the map (24-bit fixed point, as the shadow map's default).
DEPTH_BITS = 24


def sample_offsets(n: int, disc: bool) -> np.ndarray:
    """The fixed sample pattern, float32 (n, 2): centres of n equal-area strata of the unit square
    centred on 0 (``disc=False``: [−½, ½]²), or mapped by the concentric map onto the disc of
    diameter 1 (``disc=True``). n = 1 gives the centre (0, 0)."""
    lo, size = strata(n)
    centres = lo + 0.5 * size
    pts = 0.5 * concentric_disc(centres) if disc else centres - 0.5
    return pts.astype(np.float32)


def light_uv(extents: np.ndarray, view: np.ndarray, proj: np.ndarray) -> np.ndarray:
    """The light's extents (3, 2) seen along the map's axis at its near plane, in map uv units
    (2, 2), columns as given: a lateral offset Δx at linear depth z moves u by
    ½ · proj[0,0] · Δx / z (BIAS · perspective), taken at z = near."""
    near, _ = near_far(proj)
    lateral = view[:2, :3] @ extents  # the extents in the map's x, y axes
    return lateral * (np.array([proj[0, 0], proj[1, 1]])[:, None] / (2.0 * near))


class PCSS(ContactShadows, TexelMapping, Technique):
    """Percentage-closer soft shadows: blocker search, penumbra estimate, variable-size PCF."""

    name = "pcss"
    summary = "percentage-closer soft shadows (Fernando 2005): blocker search, penumbra estimate, PCF"
    PASSES = ("depth", "lookup")
    STYLE = PlotStyle("#8c564b", "P")
    #: Only an area light has the size the penumbra estimate needs (suites and tests give it
    #: soft-shadow scenes; planning a compare, study or animation elsewhere is an error).
    LIGHTS = frozenset({"area"})
    STATS = {"memory_bytes": MAX, "faces": FIRST, "passes": SUM, "depth_range": FIRST, "light_size": FIRST,
             "texel_world": FIRST}
    READS = frozenset({"position", "normal"})
    PROVIDES = frozenset({"texel_mapping"})
    PARAMS = {
        "resolution": Param(2048, "shadow map width and height in texels", min=16, max=16384,
                            # powers of two; the taps' cost does not grow with it, the map's memory does
                            tune=TuneRange(256, 4096, log=True)),
        "bias": Param(0.002, "constant depth bias in window-depth units [0, 1], subtracted from the "
                             "receiver's depth at every tap (as shadow_map's constant variant)", min=0.0, max=1.0,
                      # orders of magnitude from acne to detached contacts, as shadow_map's bias
                      tune=TuneRange(1e-5, 0.05, log=True)),
        "blocker_samples": Param(16, "taps of the blocker search (fixed stratified pattern)", min=1, max=256),
        "filter_samples": Param(32, "taps of the PCF (fixed stratified pattern): visibility steps of 1/N",
                                min=1, max=256),
        "blocker_search": Param(True, "false: skip the blocker search and penumbra estimate, PCF every pixel "
                                      "over a fixed kernel of fixed_filter texels (classic PCF)"),
        "fixed_filter": Param(8.0, "blocker_search=false: the kernel's larger extent, in texels", min=0.0, max=4096.0,
                              # one texel (hard) to a penumbra 32 texels wide
                              tune=TuneRange(1.0, 32.0)),
        "receiver_plane": Param(True, "compare each tap with the receiver's plane extrapolated to it "
                                      "(Isidoro 2006) instead of the centre's depth"),
    }

    def setup(self, frame, slot) -> None:
        """Fit the map's frustum, allocate the map, programs and uniforms."""
        light = slot.light
        self.atlas, notes = centre_map_atlas(frame, slot, self.resolution, self.name)
        self.notes.extend(notes)
        face = self.atlas.faces[0]
        self.map = self.own(targets.DepthTexture.create(self.atlas.size, DEPTH_BITS))
        self.depth_prog = self.program("shadow_depth.glsl", defines=depth_defines())
        self.lookup_prog = self.program("pcss.glsl", defines={"BLOCKER_SAMPLES": self.blocker_samples,
                                                            "FILTER_SAMPLES": self.filter_samples})
        proj, view = face.proj, face.view
        near, far = near_far(proj)
        extents = light_extents(light, view)
        axis = height_axis(light, view)
        self.search_height = search_height(axis, light.position, frame.caster_bounds(), near, -view[2, :3])
        self.light_uv = light_uv(extents, view, proj)
        disc = not isinstance(light, RectLight)
        extent_texels = self.resolution * float(np.linalg.norm(self.light_uv, axis=0).max())
        programs.set_uniforms(self.lookup_prog, light.uniforms())
        self.lookup_prog["u_light_matrix"].write(programs.mat_bytes(BIAS @ face.view_proj))
        # mat2 is column-major: write the transpose of the row-major (2, 2) matrix
        self.lookup_prog["u_light_uv"].write(np.ascontiguousarray(self.light_uv.T, dtype="f4").tobytes())
        # mat2x3: two vec3 columns, the extents
        self.lookup_prog["u_light_extents"].write(np.ascontiguousarray(extents.T, dtype="f4").tobytes())
        normal = light.normal if light.one_sided else np.zeros(3)
        programs.set_uniforms(self.lookup_prog, {
            "u_map": 2,
            "u_near": near, "u_far": far, "u_bias": float(self.bias), "u_empty_depth": float(CLEAR_DEPTH),
            "u_basis_switch": BASIS_SWITCH, "u_basis_helper_a": BASIS_HELPERS[0],
            "u_basis_helper_b": BASIS_HELPERS[1],
            "u_height_axis": tuple(map(float, axis)), "u_height_axis_view": tuple(map(float, view[:3, :3] @ axis)),
            "u_proj_scale": (float(proj[0, 0]), float(proj[1, 1])), "u_search_height": self.search_height,
            "u_receiver_plane": int(self.receiver_plane), "u_texel_angle": float(face.texel_angle),
            "u_search": int(self.blocker_search),
            "u_fixed_scale": float(self.fixed_filter / extent_texels) if extent_texels > 0 else 0.0,
            "u_one_sided": int(light.one_sided), "u_light_normal": tuple(map(float, normal)),
            "u_blocker_samples": self.blocker_samples, "u_filter_samples": self.filter_samples,
            "u_blocker_offsets": sample_offsets(self.blocker_samples, disc),
            "u_filter_offsets": sample_offsets(self.filter_samples, disc),
        })
        self.near, self.far = near, far
        self.quad = self.fullscreen_quad(self.lookup_prog)
        self.vis_tex, self.vis_fbo = self.visibility_target((frame.width, frame.height))

    def render(self) -> None:
        """The depth pass from the light's centre, then the PCSS lookup over the G-buffer."""
        with self.timed_pass("depth"):
            depth_pass(self.frame, self.map, self.depth_prog, self.atlas)
        with self.timed_pass("lookup"):
            lookup_pass(self, self.vis_fbo, self.quad, self.map.texture)

    def work(self, counted: dict, stats: dict) -> dict:
        """Texture taps per lookup fragment: the G-buffer's position and normal, the blocker
        search's taps (when on) and the PCF's."""
        per = 2 + (self.blocker_samples if self.blocker_search else 0) + self.filter_samples
        return self.taps_work(counted, {"lookup": per})

    def stats(self) -> dict:
        """Map memory, passes per frame, the map's depth range and the light size used."""
        return {"memory_bytes": self.map.nbytes, "faces": 1, "passes": 2,
                "depth_range": self.far - self.near, "light_size": light_size(self.light),
                "texel_world": None}
