"""Depth-buffer shadow maps (Williams 1978) and their family of depth comparisons.

The map is an atlas of one face (spot, directional, target-direct, a point light's single
frustum) or six (a point light's cube, 90° faces, chosen in the lookup by the major axis of the
light-to-point vector). Passes: the casters' depth from the light (one per face and layer), an
optional resolve, then one lookup pass over the shared G-buffer writing visibility.

Variants (``variant=``), tuned by ``bias``, ``slope_scale``, ``normal_offset`` (texels) and
``adaptive_epsilon`` (a fraction of the scene's extent). ``bias`` means what ``bias_space`` says:

- ``world`` (the default): a distance the lookup moves the receiver towards the light,
  converted to window depth at the receiver (exactly, through the map's matrix:
  ``world_bias`` in shadowlab/techniques/maps/world_bias.glsl), so that it means the same distance at every
  receiver whatever the near plane. A window-depth bias is stretched by z²/near in a
  perspective map, so a near plane 1000x closer turns 0.002 of window depth into metres
  (0.002 · z² / near: a table 2 m below a lamp whose near plane is 0.4 mm away gets a bias of
  about 20 m, and every shadow is lost). On perspective maps the distance is ``bias`` × the
  scene's extent (one default serves a room and a city); on orthographic maps (lights at
  infinity) window depth is linear, so the window-depth bias already is one distance
  everywhere, ``bias`` × the map's depth range, and is kept: the defaults were chosen so
  (docs/tuning.md, "Near planes and the world-distance bias").
- ``window``: window-depth units [0, 1], the seed's and the literature's form (the bias
  experiments, ``dual``'s offset cap);
- ``units``: an absolute distance in scene units towards the light, as Bevy and Godot give their
  depth bias (metres): converted at each receiver on perspective maps, ``bias`` / the depth range
  of window depth on orthographic ones (the same distance: window depth is linear there);
- ``texels``: that many texels of the map, as Unity scales its depth bias: on orthographic maps
  the texel's world size, on perspective maps one texel's size at the far plane (Unity takes it
  at the light's range), as a distance converted at each receiver.

``preset=godot|bevy|threejs|unity|ue5`` starts from that engine's default shadow settings for the
light at hand (directional, or point/spot), keys given in the spec overriding them; the values,
their sources and how faithful each mapping is are in :mod:`shadowlab.techniques.maps.presets`.

The variants:

- ``none``: compare with no offset — shows acne;
- ``constant``: subtract ``bias``;
- ``slope``: ``bias`` plus ``slope_scale`` × the depth change over one texel on the receiver's
  plane, computed in the shader from the receiver's normal (the shader-side form of slope-scaled
  bias); with ``hardware_offset=true`` the depth pass instead applies glPolygonOffset(factor =
  ``slope_scale``, units = ``offset_units``), the hardware form;
- ``normal_offset``: ``bias`` plus the lookup point moved along the normal by ``normal_offset``
  texels (world size of a texel at the point);
- ``second_depth`` (Wang & Molnar 1994): the map holds the back faces only (front faces culled),
  no bias — single-sided casters vanish from it;
- ``midpoint`` (Woo 1992): the average of the first and second depth layers (depth peeling);
- ``dual`` (Weiskopf & Ertl 2003): the first layer plus min(half the gap to the second, ``bias``);
- ``receiver_plane`` (Isidoro 2006, "Shadow mapping: GPU-based tips and techniques", GDC: receiver
  plane depth bias): each tap compares its stored depth with the receiver's window depth
  extrapolated along the receiver's plane (dz/du, dz/dv in map space, from the normal) to the
  centre of that tap's texel — where the stored depth was rasterised — minus ``bias``; with
  ``filter=nearest`` the one tap is the texel holding the point, so the depth is extrapolated to
  its centre;
- ``adaptive`` (Dou, Yan, Kerzner, Dai & Wyman 2014, "Adaptive depth bias for shadow maps", I3D /
  JCGT 3(4)): per tap, the ray from the light through the centre of the tap's texel is
  intersected with the receiver's tangent plane; the window depth of that point bounds the depth
  of a false occluder in the texel, and the bias is the receiver's depth minus it (signed: it
  can also push the comparison away from the light) plus the *adaptive epsilon*
  ``adaptive_epsilon`` × the scene's extent (the diagonal of its bounds), a world distance
  along the ray converted to window depth at the intersection (so it follows a perspective
  map's depth compression). Differences from the paper: ``bias`` is added on top (``bias=0`` is
  the paper's form; the exact bias optimiser sweeps it); the paper derives its epsilon (its
  eq. 3) from a user constant scaled by the scene's scale and by the depth buffer's compression
  at the fragment's depth — we worked from summaries of that equation, not its text, so ours is
  our own form of the same idea: a world distance (constant × the scene's diagonal) mapped
  exactly to window depth at the intersection, which is where the depth dependence comes from;
  PCF compares every tap against its own texel's bound (the paper describes the texel the point
  falls in); where the ray misses the tangent plane in front of the light (an edge-on
  receiver) the offset is 0 and only the epsilon applies. The two intersections are the same
  plane — a projective map keeps planes planar, so ``receiver_plane``'s extrapolation and
  ``adaptive``'s ray intersection agree up to float32 round-off — and the variants differ in
  the epsilon: ``receiver_plane`` needs a constant ``bias`` above the depth format's step and
  the rasteriser's round-off (at ``bias=0`` acne remains: sm_grazing with fit=receivers, and
  16-bit depth on sm_contact), ``adaptive``'s epsilon scales with the scene. Both per-tap
  variants need a depth test per texel, so ``filter=hw2x2`` (one reference depth for the 2x2
  footprint) is refused with them;
- ``oriented`` (oriented depth bias: S. Fatnassi, "Shadow Techniques from Final Fantasy XVI",
  technical report, Square Enix 2023, §4): the constant ``bias`` applied with the sign of the
  surface's orientation to the light, d' = d − s · ``bias``, s = +1 where the visible side of the
  surface faces the light (N·L > 0, N the geometric normal turned towards the camera: the
  G-buffer normal of a deferred renderer) and s = −1 where it faces away. Points facing the
  light move towards it (as ``constant``); points facing away move away from it, so that they
  stay in their own object's shadow instead of leaking light through it. With
  ``bias_space=world`` the distance moved away is converted to window depth at the receiver as
  the distance towards it is. Source, stated: the paper's own text (PDF at
  www.jp.square-enix.com/tech/library/pdf/2023_FFXVIShadowTechPaper.pdf) could not be read
  here; the rule above is what independent implementations that cite the paper do (a flat
  depth offset, its sign chosen by whether the normal faces the light), which also put the
  paper's value at 2 mm of linear depth. One of them says the paper keeps the hardware
  slope-scaled bias (factor 1) in the depth pass while dropping its constant part; that part is
  not in this variant (``hardware_offset`` stays the ``slope`` variant's). Note for reading the
  figures: the metrics evaluate only points whose visible side faces the light
  (docs/metrics.md), where s = +1, so there this variant compares exactly as ``constant`` does
  (up to float32 round-off of the sign where N·L ≈ 0); it differs on the points facing away.

Filters (``filter=``): ``nearest``; ``hw2x2`` (sampler2DShadow with linear filtering: hardware
bilinear PCF); ``pcf3`` / ``pcf5`` (texel-exact percentage-closer filtering, Reeves et al. 1987).
Filtered visibility is fractional; the metrics report ``visibility_mae`` beside thresholded rates.

Light frusta are fitted to what the scene and camera involve (docs/architecture.md), never constants;
each light type fits its own (:meth:`shadowlab.scene.lights.Light.shadow_views`,
:mod:`shadowlab.geometry.frusta`). The points to cover are (``fit=shadowable``, the default) the evaluated receiver points that can
be in shadow at all — those whose segment to the light crosses a caster's bounding box
(:func:`shadowlab.techniques.maps.toolkit.shadowable`) — or (``fit=receivers``, the classic fit) every evaluated receiver point;
then
- directional: orthographic along the light, x/y extent fitted to those points, depth range
  from the nearest caster to the farthest receiver;
- target-direct: orthographic over the light's cylinder (radius R), clipped to those points;
  near plane at the light's disc (nothing behind the light casts);
- spot: perspective with the cone's full angle α;
- point: ``projection=frustum`` — one frustum around those points; ``cube`` — six faces;
  ``auto`` — the frustum when the points fit in a cone of
  ``geometry.frusta.MAX_POINT_HALF_ANGLE``, else the cube.
Near planes of perspective maps sit just in front of the nearest caster *triangle* inside each
view's frustum, measured along the view's axis (:func:`shadowlab.geometry.frusta.perspective_fit`:
every caster triangle clipped to the frustum, :mod:`shadowlab.geometry.caster_depth`), not in
front of caster bounding boxes — a light inside a caster's box, a lamp inside a room modelled as
one mesh, would otherwise get the floor far × 1e-4 — unless ``near`` forces one (to show what a
too-close near plane does to depth precision). Casters nearer than that floor are clipped, with
a note; far planes lie just past the farthest receiver.
"""
from __future__ import annotations

from ...geometry.frusta import LightView
from ..base import Param, PlotStyle, TechniqueError, TuneRange
from .toolkit import FILTERS, DepthMapTechnique, fit_light_views
from .contact import ContactShadows
from .presets import PRESET_NAMES, PresetMixin

VARIANTS = ("none", "constant", "slope", "normal_offset", "second_depth", "midpoint", "dual",
            "receiver_plane", "adaptive", "oriented")
#: The variants that compare against a resolved pair of layers (depth peeling).
TWO_LAYER_VARIANTS = ("midpoint", "dual")
#: The variants whose comparison applies no constant bias of its own.
UNBIASED_VARIANTS = ("none", "second_depth", "midpoint", "dual")
#: The variants that compare each PCF tap with its own receiver depth / bias (the lookup's
#: ``u_depth_comparison``: shadowlab/techniques/maps/shadow_lookup.glsl's DEPTH_COMPARISON_*); the others compare
#: every tap with the point's own depth (0, DEPTH_COMPARISON_POINT).
PER_TAP_VARIANTS = {"receiver_plane": 1, "adaptive": 2}

#: The largest ``bias`` in the absolute bias spaces (``units``: scene units; ``texels``); the
#: fractional spaces (``world``, ``window``) stop at 1 (:meth:`ComparisonVariants.check_bias`).
MAX_ABSOLUTE_BIAS = 1000.0
#: The bias spaces in which ``bias`` is a fraction (of the extent, the depth range or window depth).
FRACTION_BIAS_SPACES = ("world", "window")

#: The parameters of the depth comparison that shadow_map and lispsm share.
COMPARISON_PARAMS = {
    "resolution": Param(2048, "shadow map width and height in texels (per cube face)", min=16, max=16384,
                        # powers of two from coarse to a cube atlas's practical limit (3 x 8192 wide)
                        tune=TuneRange(256, 8192, log=True)),
    "bias": Param(0.002, "constant depth bias: with bias_space=world a distance towards the light, as a fraction "
                         "of the scene's extent (perspective maps) or of the depth range (orthographic maps); "
                         "with window, window-depth units [0, 1] (dual: the offset cap, window depth); with units, scene "
                         "units; with texels, map texels",
                  # acne below ~1e-6 of the depth range (or extent) even at 32 bits; 0.05 detaches every contact.
                  # At most 1 as a fraction (world, window: checked in ComparisonVariants); scene units and
                  # texels go further (an engine's bias of 2 texels, or of 0.5 m in a city)
                  min=0.0, max=MAX_ABSOLUTE_BIAS, tune=TuneRange(1e-6, 0.05, log=True)),
    "bias_space": Param("world", "what bias measures: world (a distance moved towards the light at each receiver, "
                                 "the same whatever the near plane: bias x the scene's extent on perspective maps, "
                                 "converted to window depth at the receiver; on orthographic maps window depth is "
                                 "linear and the bias is kept as it is, bias x the depth range) or window (window "
                                 "depth, the seed's and the literature's form, which a near plane close to the light "
                                 "turns into metres); shadow_map also takes units (an absolute distance in scene units moved towards the light, as engines "
                                 "give it: Bevy's and Godot's depth bias) or texels (that many of the map's texels: on "
                                 "orthographic maps the texel's world size, on perspective maps a texel's size at the "
                                 "far plane; Unity's depth bias)",
                        choices=("world", "window", "units", "texels")),
    "depth_bits": Param(24, "depth format: 16 / 24 fixed point, 32 float", choices=(16, 24, 32)),
    "variant": Param("constant", "depth comparison", choices=VARIANTS),
    "slope_scale": Param(2.0, "slope variant: multiple of the receiver's depth change over one texel",
                         # 1-2 texels' slope is the usual setting; 16 already pushes grazing shadows off
                         min=0.0, max=1e4, tune=TuneRange(0.0, 16.0)),
    "normal_offset": Param(1.0, "normal_offset variant: lookup point moved along the normal, in texels",
                           # about one texel is typical; past a few texels the shadow visibly shifts
                           min=0.0, max=1e3, tune=TuneRange(0.0, 4.0)),
    "adaptive_epsilon": Param(1e-4, "adaptive variant: the adaptive epsilon, a fraction of the scene's extent "
                                     "(world distance along the light's ray, converted to window depth)",
                              # float32 round-off of the plane intersection is ~1e-7 of the extent; 1e-2 of
                              # the extent already lifts the receiver visibly off its contacts
                              min=0.0, max=1.0, tune=TuneRange(1e-7, 1e-2, log=True)),
    "hardware_offset": Param(False, "slope variant: glPolygonOffset in the depth pass instead of the shader form"),
    "offset_units": Param(4.0, "hardware_offset: glPolygonOffset units", min=0.0, max=1e6,
                          # units of the depth format's resolution: a few to tens of them is the usual range
                          tune=TuneRange(0.0, 64.0)),
    "filter": Param("nearest", "nearest, hw2x2 (hardware bilinear comparison), pcf3, pcf5",
                    choices=tuple(FILTERS)),
}


class ComparisonVariants:
    """The bias family and two-layer comparisons of a :class:`DepthMapTechnique` with the
    :data:`COMPARISON_PARAMS` (shadow_map, lispsm): which layers, the depth pass's state and
    the lookup's uniforms, per ``variant``."""

    def __init__(self, **params):
        super().__init__(**params)
        self.check_bias()
        if self.variant in PER_TAP_VARIANTS and FILTERS[self.filter] is None:
            raise TechniqueError(f"{self.name}: variant={self.variant} compares each texel with its own receiver "
                                 f"depth; filter={self.filter} compares one depth in the texture unit; use nearest, "
                                 f"pcf3 or pcf5")

    def check_bias(self) -> None:
        """``bias`` is a fraction in the fractional bias spaces (world: of the extent or depth range;
        window: of window depth), so at most 1 there; the absolute spaces (units, texels) take up to
        :data:`MAX_ABSOLUTE_BIAS`. A one-line TechniqueError otherwise."""
        if self.bias_space in FRACTION_BIAS_SPACES and self.bias > 1.0:
            absolute = [b for b in self.PARAMS["bias_space"].choices if b not in FRACTION_BIAS_SPACES]
            raise TechniqueError(f"{self.name}: bias must be <= 1.0 with bias_space={self.bias_space} (a fraction), "
                                 f"got {self.bias}" + (f"; bias_space={' or '.join(absolute)} take larger values"
                                                       if absolute else ""))

    def two_layer(self) -> bool:
        """Midpoint and dual compare against the resolved pair of the first two layers."""
        return self.variant in TWO_LAYER_VARIANTS

    def resolve_uniforms(self) -> dict:
        """Dual resolves min(half the gap, ``bias``) behind the first layer; midpoint the average."""
        return {"u_resolve": 1 if self.variant == "dual" else 0, "u_dual_offset": float(self.bias)}

    def depth_state(self) -> tuple[bool, tuple[float, float] | None]:
        """Second-depth culls front faces; hardware slope bias offsets the depth pass."""
        hardware = self.variant == "slope" and self.hardware_offset
        return self.variant == "second_depth", ((float(self.slope_scale), float(self.offset_units))
                                                if hardware else None)

    def converts_world_bias(self) -> bool:
        """True when the lookup converts a world-distance bias at each receiver: ``bias_space``
        world, units or texels on a perspective map. An orthographic map's window depth is
        linear, so there a window-depth bias already is one world distance everywhere (× the
        depth range)."""
        atlas = getattr(self, "atlas", None)  # before setup the map's projection is not known yet
        return self.bias_space != "window" and (atlas is None or atlas.faces[0].proj[3, 3] != 1.0)

    def bias_unit(self) -> tuple[str, float]:
        """What one unit of ``bias`` is in the lookup, after setup: ("world", s) — a distance of
        s world units towards the light, converted at each receiver — or ("window", s), s of
        window depth. ``world``: the scene's extent on perspective maps, 1 window unit on
        orthographic ones (the defaults' form, docs/tuning.md); ``window``: 1 window unit;
        ``units``: 1 world unit (perspective), 1 / the depth range of window depth
        (orthographic: window depth is linear in distance, so this is the same distance);
        ``texels``: one texel's world size — on orthographic maps ``texel_world`` (as window
        depth), on perspective maps ``texel_angle`` × the far plane's distance, one texel's size
        where the map ends (Unity's texel at the light's range is the same idea)."""
        if self.bias_space == "window":
            return "window", 1.0
        face = self.atlas.faces[0]
        ortho = face.proj[3, 3] == 1.0
        if self.bias_space == "world":
            return ("window", 1.0) if ortho else ("world", float(self.frame.scene.extent()))
        if self.bias_space == "units":
            return ("window", 1.0 / face.depth_range) if ortho else ("world", 1.0)
        # texels
        if ortho:
            return "window", float(face.texel_world) / face.depth_range
        return "world", float(face.texel_angle) * face.near_far()[1]

    def bias_window_world(self) -> tuple[float, float]:
        """The constant bias as (window depth, world distance), as the lookup applies it
        (:meth:`bias_unit`): with ``bias_space=world``, ``bias`` × the scene's extent as a
        distance on perspective maps, and ``bias`` in window depth (= ``bias`` × the depth
        range, in world units) on orthographic ones; with ``window``, window depth; ``units``
        and ``texels`` likewise through their unit. (0, 0) for the variants without one."""
        if self.variant in UNBIASED_VARIANTS:
            return 0.0, 0.0
        kind, unit = self.bias_unit()
        if kind == "world":
            return 0.0, float(self.bias) * unit
        return float(self.bias) * unit, 0.0  # × 1.0 is exact: window and world-ortho biases unchanged

    def comparison_uniforms(self) -> dict:
        """The variant's bias terms, the first face's texel size, the PCF radius, the per-tap
        comparison (receiver plane, adaptive), what the adaptive bias needs (the inverse light
        matrices, the epsilon and the scene's extent) and the oriented bias's switch and camera
        position (the visible side of a surface is the side facing the camera)."""
        face = self.atlas.faces[0]
        window, world = self.bias_window_world()
        return {
            "u_depth_comparison": PER_TAP_VARIANTS.get(self.variant, 0),
            "u_light_matrix_inverse": self.atlas.inverse_light_matrices(),
            "u_adaptive_epsilon": float(self.adaptive_epsilon) if self.variant == "adaptive" else 0.0,
            "u_scene_extent": float(self.frame.scene.extent()),
            "u_bias": window,
            "u_bias_world": world,
            "u_slope_scale": float(self.slope_scale) if self.variant == "slope" and not self.hardware_offset else 0.0,
            "u_normal_offset": float(self.normal_offset) if self.variant == "normal_offset" else 0.0,
            "u_texel_world": float(face.texel_world), "u_texel_angle": float(face.texel_angle),
            "u_kernel_radius": FILTERS[self.filter] or 0,
            # oriented: the bias's sign follows the visible side's orientation to the light
            "u_oriented": 1 if self.variant == "oriented" else 0,
            "u_eye": tuple(float(v) for v in self.frame.camera.eye),
        }


class ShadowMap(PresetMixin, ContactShadows, ComparisonVariants, DepthMapTechnique):
    """Depth-buffer shadow maps: every light type, the bias family, two-layer variants, filters."""

    name = "shadow_map"
    summary = ("depth-buffer shadow maps (Williams 1978): bias variants (receiver-plane, adaptive and oriented "
               "bias among them), second-depth, midpoint, dual, PCF")
    STYLE = PlotStyle("#1f77b4", "o")
    LIGHT_SAMPLED = True  # light_samples=N: averaged over N points of an area light (shadowlab.measurement.light_sampling)
    #: The map's texel mapping, and the bias family the exact optimiser sweeps (ComparisonVariants).
    PROVIDES = frozenset({"texel_mapping", "depth_bias", "world_bias"})
    PARAMS = {
        **COMPARISON_PARAMS,
        "projection": Param("auto", "point lights: cube (six faces), frustum (one), auto",
                            choices=("auto", "cube", "frustum")),
        "near": Param(0.0, "perspective maps: force this near plane (0 = fitted to the casters)", min=0.0),
        "fit": Param("shadowable", "cover the receivers that can be shadowed (shadowable) or all visible "
                                   "receivers (receivers, the classic fit)", choices=("shadowable", "receivers")),
        "preset": Param("none", "start from an engine's default shadow settings for the light at hand (keys given "
                                "in the spec override them; shadowlab/techniques/maps/presets.py, docs/your-scenes.md)",
                        choices=PRESET_NAMES),
    }

    def _check_params(self) -> None:
        """The per-tap variants need a depth test per texel: refused with hw2x2 (as when parsed);
        the bias within its space's range (:meth:`check_bias`)."""
        self.check_bias()
        if self.variant in PER_TAP_VARIANTS and FILTERS[self.filter] is None:
            raise TechniqueError(f"{self.name}: variant={self.variant} compares each texel with its own receiver "
                                 f"depth; filter={self.filter} compares one depth in the texture unit")

    def fit_views(self, frame, slot) -> tuple[list[LightView], list[str]]:
        """The map's faces and notes for the run (:func:`~shadowlab.techniques.maps.toolkit.fit_light_views`)."""
        return fit_light_views(frame, slot, self.resolution, self.projection, self.near, self.fit)
