"""Engine presets: the default shadow settings of five engines, as the lab's parameters.

``shadow_map:preset=godot`` (or ``bevy``, ``threejs``, ``unity``, ``ue5``) starts a shadow map from
what that engine does when a user turns shadows on and changes nothing; keys written in the spec
override the preset's (``shadow_map:preset=godot,bias=0.002``). Why: a user who ships on an engine
wants to know what its defaults cost on their own scene, and ``shadowlab tune`` of a preset spec
reports exactly that — the regret of the engine's default against the exact optimum
(docs/your-scenes.md, "Engine presets").

Engines set different defaults per light type (Godot's DirectionalLight3D against its
OmniLight3D / SpotLight3D, Bevy's DirectionalLight against PointLight / SpotLight), so a preset
holds one :class:`Setting` per parameter and light kind: ``directional`` (lights at infinity:
directional and target-direct) and ``local`` (point, spot, and area lights, which shadow_map
renders as point lights at their samples). The technique resolves them when it learns its light
(:class:`PresetMixin`); before that, :meth:`Technique.params` shows the directional values.

Each value records where it comes from: the engine version or commit, the source file and line
(or documentation page and setting), and how faithfully the lab's parameter reproduces the
engine's meaning (:data:`EXACT`, :data:`APPROXIMATE`, :data:`UNCERTAIN`). What the engines' biases
mean, read from their code (units matter; none of the code is copied here):

- **Godot 4** (``scene/3d/light_3d.cpp``; ``servers/rendering/renderer_rd/storage_rd/light_storage.cpp``
  and the forward shaders' ``BIAS_FUNC``): the directional light's ``shadow_bias`` is divided by 100
  and scaled per split (1 on the first), then added to the lookup point along the light direction —
  a world distance: ``bias_space=units``. ``shadow_normal_bias`` is multiplied by the split's texel
  size and by (1 − N·L) and moves the lookup point along the normal: the lab's ``normal_offset`` in
  texels, without the (1 − N·L) factor (approximate). Omni lights subtract ``shadow_bias`` (world
  units) from the radial distance, spot lights add ``shadow_bias``/100 to the projected depth
  divided by the distance; both normal biases are ``shadow_normal_bias`` × texel size × 10 (spot:
  also × distance). Default filter: soft PCF over a rotated Poisson disk (quality "soft low"):
  no lab twin, nearest is ``pcf3``.
- **Bevy** (``crates/bevy_light/src/*_light.rs``; ``crates/bevy_pbr/src/render/shadows.wgsl``): the
  lookup point moves ``shadow_depth_bias`` world units towards the light (``bias_space=units``) and
  ``shadow_normal_bias`` × the cascade's texel size along the normal (``normal_offset`` in texels:
  exact for directional lights). For point lights the CPU pre-multiplies the normal bias by the
  cube face's texel size at unit distance and √2, and the shader by the distance (major axis):
  ``normal_offset`` = 0.6 × √2 texels, approximate (major axis against Euclidean distance).
  Default filter: ``ShadowFilteringMethod::Gaussian`` (Castaño 2013's weighted 5×5 footprint):
  nearest lab twin ``pcf5`` (a box).
- **three.js** (``src/lights/LightShadow.js``; ``shadowmap_pars_fragment.glsl.js``): ``bias`` is
  added to the window depth (``bias_space=window``) and defaults to 0; ``normalBias`` (world units)
  is 0; ``mapSize`` 512; the renderer's default ``PCFShadowMap`` averages nearest-texel comparisons
  within one texel of the point: ``pcf3``.
- **Unity URP** (``UniversalRenderPipelineAsset.cs`` defaults; ``ShadowUtils.GetShadowBias`` and
  ``ApplyShadowBias`` in ``Shadows.hlsl``): depth bias 1 and normal bias 1, each × the light's texel
  size (directional: the orthographic frustum's width / resolution; spot and point: the frustum's
  half-width at the light's range / resolution), applied to the *casters* in the shadow pass
  (moved away from the light; shrunk along their normal by (1 − N·L) × normal bias). Lab: the
  receiver moved towards the light by 1 texel (``bias_space=texels``) plus ``normal_offset`` 1
  texel — approximate (receiver side, no (1 − N·L)). Main light map 2048, additional lights 512
  (the asset's default tier). Soft shadows are off by default: ``nearest``.
- **Unreal Engine 5**: not public on GitHub; from its documentation, not code. Its default for
  movable lights is the virtual shadow map (the lab's ``virtual_map``); the values here are the
  conventional shadow map's light defaults (Shadow Bias 0.5, Shadow Slope Bias 0.5) and
  ``r.Shadow.CSMDepthBias`` / ``r.Shadow.CSMSlopeScaleDepthBias`` (10 / 3) whose units (UE scales
  them by the map's texel and depth range inside the renderer) could not be checked: uncertain.
"""
from __future__ import annotations

from dataclasses import dataclass

from ...util.validation import did_you_mean
from ..base import TechniqueError

EXACT = "exact"
APPROXIMATE = "approximate"
UNCERTAIN = "uncertain"
#: How faithfully a lab value reproduces the engine's setting.
FIDELITY = (EXACT, APPROXIMATE, UNCERTAIN)
#: The light kinds a preset distinguishes.
KINDS = ("directional", "local")
#: Light types (``Light.type_name``) → the preset's light kind.
KIND_OF_LIGHT = {"directional": "directional", "target_direct": "directional",
                 "point": "local", "spot": "local", "area": "local"}
#: The name of no preset (a spec without ``preset=`` is the technique at its own defaults).
NONE = "none"


@dataclass(frozen=True)
class Setting:
    """One preset value: the lab parameter's value, the engine setting it stands for, where the
    engine's default is written (version, file and line, or documentation page and setting), and
    how faithful the mapping is (:data:`FIDELITY`) with a note saying why."""

    value: object
    engine: str
    source: str
    fidelity: str
    note: str = ""

    def __post_init__(self):
        """A fidelity outside :data:`FIDELITY` is a declaration error."""
        if self.fidelity not in FIDELITY:
            raise TypeError(f"Setting {self.engine}: fidelity must be one of {FIDELITY}, got {self.fidelity!r}")


@dataclass(frozen=True)
class Preset:
    """An engine's default shadow settings: ``version`` (the release or commit read), and per
    technique name and light kind the lab parameters → :class:`Setting`."""

    name: str
    engine: str
    version: str
    settings: dict  # technique name -> kind -> {param: Setting}

    def values(self, technique: str, kind: str) -> dict:
        """{param: value} for ``technique`` on a light of ``kind`` ({} where the preset has none)."""
        return {k: s.value for k, s in self.settings.get(technique, {}).get(kind, {}).items()}

    def keys(self, technique: str) -> set:
        """Every parameter the preset sets for ``technique``, on any light kind."""
        return {k for per in self.settings.get(technique, {}).values() for k in per}


_GODOT = "Godot 4.x, godotengine/godot@0225c6d"
_GODOT_LIGHT = "scene/3d/light_3d.cpp"
_GODOT_STORE = "servers/rendering/renderer_rd/storage_rd/light_storage.cpp (update_light_buffers)"
_BEVY = "Bevy 0.16-era main, bevyengine/bevy@a0d0176 (directional_light.rs), @459870a (point_light.rs)"
_THREE = "three.js r16x, mrdoob/three.js@078eee1 (LightShadow.js), @012f562 (shadowmap_pars_fragment)"
_URP = "URP 14+ (Unity-Technologies/Graphics, com.unity.render-pipelines.universal)"
_URP_ASSET = "Runtime/Data/UniversalRenderPipelineAsset.cs (Shadows Settings)"
_UE5 = "Unreal Engine 5 documentation (source not public on GitHub)"


def _s(value, engine, source, fidelity, note=""):
    return Setting(value, engine, source, fidelity, note)


PRESETS: dict[str, Preset] = {
    "godot": Preset("godot", "Godot", _GODOT, {
        "shadow_map": {
            "directional": {
                "variant": _s("normal_offset", "depth bias + normal bias together", "scene_forward_clustered.glsl BIAS_FUNC",
                              APPROXIMATE, "both move the lookup point; the lab's normal offset has no (1 - N.L) factor"),
                "bias_space": _s("units", "shadow_bias is a world distance along the light", "BIAS_FUNC: light_dir * shadow_bias",
                                 EXACT),
                "bias": _s(0.001, "DirectionalLight3D shadow_bias 0.1, / 100 x bias_scale (1 on the first split)",
                           f"{_GODOT_LIGHT} DirectionalLight3D::DirectionalLight3D, set_param(PARAM_SHADOW_BIAS, 0.1); "
                           f"{_GODOT_STORE}: / 100.0 * bias_scale", APPROXIMATE,
                           "bias_scale grows on later splits; the lab's single map uses the first split's"),
                "normal_offset": _s(1.0, "shadow_normal_bias 1.0 x the split's texel size",
                                    f"{_GODOT_LIGHT} Light3D::Light3D, set_param(PARAM_SHADOW_NORMAL_BIAS, 1.0); "
                                    f"{_GODOT_STORE}: * shadow_texel_size", APPROXIMATE,
                                    "Godot scales by (1 - N.L) and drops the part along the light"),
                "resolution": _s(4096, "rendering/lights_and_shadows/directional_shadow/size 4096",
                                 "project settings doc, directional_shadow/size (4 splits share it: 2048 each)",
                                 APPROXIMATE, "one 4096 atlas split 2x2 among the PSSM splits; the lab draws one map"),
                "filter": _s("pcf3", "soft_shadow_filter_quality 2 (soft low): rotated Poisson-disk PCF",
                             "project settings doc, directional_shadow/soft_shadow_filter_quality", APPROXIMATE,
                             "no disk-kernel PCF in the lab; pcf3 is the nearest"),
            },
            "local": {
                "variant": _s("normal_offset", "depth bias + normal bias together", "scene_forward_lights_inc.glsl",
                              APPROXIMATE, "as directional"),
                "bias_space": _s("units", "omni: shadow_bias subtracted from the radial distance (world units)",
                                 "scene_forward_lights_inc.glsl light_process_omni_shadow", APPROXIMATE,
                                 "spot lights divide by 100 and by the distance in projected depth"),
                "bias": _s(0.2, "OmniLight3D shadow_bias 0.2 (SpotLight3D keeps Light3D's 0.03, / 100)",
                           f"{_GODOT_LIGHT} OmniLight3D::OmniLight3D, set_param(PARAM_SHADOW_BIAS, 0.2)", APPROXIMATE,
                           "the omni value; spot lights would get 0.0003 x distance in projected depth"),
                "normal_offset": _s(10.0, "shadow_normal_bias 1.0 x texel size x 10",
                                    f"{_GODOT_STORE}: PARAM_SHADOW_NORMAL_BIAS * shadow_texel_size * 10.0", APPROXIMATE,
                                    "(1 - |N.L|) factor not modelled"),
                "resolution": _s(1024, "positional shadow atlas 4096, quadrant subdivision 2/4/16/64: a first-quadrant "
                                       "light gets 1024 (a cube face of an omni light less)",
                                 "project settings doc, positional_shadow/atlas_size and atlas_quadrant_*_subdiv",
                                 UNCERTAIN, "depends on how many lights share the atlas"),
                "filter": _s("pcf3", "soft_shadow_filter_quality 2 (soft low)", "project settings doc", APPROXIMATE,
                             "no disk-kernel PCF in the lab"),
            },
        },
        "cascaded_map": {
            "directional": {
                "cascades": _s(4, "DirectionalLight3D directional_shadow_mode PSSM 4 splits",
                               f"{_GODOT_LIGHT} DirectionalLight3D: set_shadow_mode(SHADOW_PARALLEL_4_SPLITS)", EXACT),
                "resolution": _s(2048, "directional_shadow/size 4096 shared 2x2 by four splits",
                                 "project settings doc, directional_shadow/size", EXACT),
                "split_lambda": _s(0.5, "splits at 0.1 / 0.2 / 0.5 of max distance 100",
                                   f"{_GODOT_LIGHT} Light3D: SPLIT_1/2/3_OFFSET 0.1, 0.2, 0.5", UNCERTAIN,
                                   "fixed fractions, not a lambda mix; 0.5 lies between their uniform and log fits"),
                "blend": _s(False, "directional_shadow_blend_splits false", f"{_GODOT_LIGHT} blend_splits = false", EXACT),
                "filter": _s("pcf3", "soft low Poisson-disk PCF", "project settings doc", APPROXIMATE),
            },
        },
    }),
    "bevy": Preset("bevy", "Bevy", _BEVY, {
        "shadow_map": {
            "directional": {
                "variant": _s("normal_offset", "depth_offset + normal_offset together", "bevy_pbr shadows.wgsl sample_cascade",
                              EXACT),
                "bias_space": _s("units", "shadow_depth_bias x direction_to_light (world units)",
                                 "bevy_pbr shadows.wgsl sample_cascade: depth_offset", EXACT),
                "bias": _s(0.02, "DirectionalLight::DEFAULT_SHADOW_DEPTH_BIAS = 0.02",
                           "crates/bevy_light/src/directional_light.rs, impl DirectionalLight", EXACT),
                "normal_offset": _s(1.8, "DirectionalLight::DEFAULT_SHADOW_NORMAL_BIAS = 1.8 x cascade texel_size",
                                    "crates/bevy_light/src/directional_light.rs; shadows.wgsl normal_offset", EXACT),
                "resolution": _s(2048, "DirectionalLightShadowMap::default size 2048",
                                 "crates/bevy_light/src/directional_light.rs, impl Default for DirectionalLightShadowMap",
                                 EXACT),
                "filter": _s("pcf5", "ShadowFilteringMethod::Gaussian (Castano 2013, 5x5 weighted)",
                             "crates/bevy_light/src/lib.rs ShadowFilteringMethod #[default] Gaussian", APPROXIMATE,
                             "the lab's pcf5 is a box, Castano's weights are a tent"),
            },
            "local": {
                "variant": _s("normal_offset", "depth_offset + normal_offset together", "shadows.wgsl fetch_point_shadow",
                              EXACT),
                "bias_space": _s("units", "shadow_depth_bias x normalize(surface_to_light)", "shadows.wgsl fetch_point_shadow",
                                 EXACT),
                "bias": _s(0.08, "PointLight::DEFAULT_SHADOW_DEPTH_BIAS = 0.08 (SpotLight 0.02)",
                           "crates/bevy_light/src/point_light.rs, impl PointLight", APPROXIMATE,
                           "the point light's value; spot lights default to 0.02"),
                "normal_offset": _s(0.8485, "PointLight::DEFAULT_SHADOW_NORMAL_BIAS 0.6 x texel at unit distance x sqrt 2 "
                                            "x distance (major axis)",
                                    "point_light.rs; bevy_pbr render/light.rs (x point texel size x SQRT_2)", APPROXIMATE,
                                    "0.6 x sqrt(2) texels; Bevy's distance is the major axis, the lab's Euclidean"),
                "resolution": _s(1024, "PointLightShadowMap::default size 1024",
                                 "crates/bevy_light/src/point_light.rs, impl Default for PointLightShadowMap", EXACT),
                "projection": _s("cube", "point lights render a cube map", "bevy_pbr render/light.rs (6 cube faces)", EXACT),
                "filter": _s("pcf5", "ShadowFilteringMethod::Gaussian", "crates/bevy_light/src/lib.rs", APPROXIMATE,
                             "cube maps sample a jittered disk in Bevy"),
            },
        },
        "cascaded_map": {
            "directional": {
                "cascades": _s(4, "CascadeShadowConfigBuilder::default num_cascades 4 (native)",
                               "crates/bevy_light/src/cascade.rs, impl Default for CascadeShadowConfigBuilder", EXACT),
                "resolution": _s(2048, "DirectionalLightShadowMap size 2048", "directional_light.rs", EXACT),
                "split_lambda": _s(0.5, "first_cascade_far_bound 5, maximum_distance 1000, geometric splits after the "
                                        "first", "crates/bevy_light/src/cascade.rs", UNCERTAIN,
                                   "Bevy fixes the first bound in metres; no lambda reproduces it on every scene"),
                "blend": _s(True, "overlap_proportion 0.2 (cascades overlap and blend)", "cascade.rs", APPROXIMATE),
                "blend_width": _s(0.2, "overlap_proportion 0.2", "cascade.rs", APPROXIMATE),
                "filter": _s("pcf5", "ShadowFilteringMethod::Gaussian", "crates/bevy_light/src/lib.rs", APPROXIMATE),
            },
        },
    }),
    "threejs": Preset("threejs", "three.js", _THREE, {
        "shadow_map": {
            kind: {
                "variant": _s("constant", "bias added to the window depth; normalBias 0 adds nothing",
                              "shadowmap_pars_fragment.glsl.js getShadow: shadowCoord.z += shadowBias", EXACT),
                "bias_space": _s("window", "bias in window depth [0, 1]", "shadowmap_pars_fragment.glsl.js getShadow", EXACT),
                "bias": _s(0.0, "LightShadow bias = 0", "src/lights/LightShadow.js constructor: this.bias = 0", EXACT),
                "resolution": _s(512, "LightShadow mapSize 512 x 512",
                                 "src/lights/LightShadow.js constructor: new Vector2( 512, 512 )", EXACT),
                "filter": _s("pcf3", "WebGLRenderer shadowMap.type PCFShadowMap: nearest comparisons within one texel",
                             "shadowmap_pars_fragment.glsl.js SHADOWMAP_TYPE_PCF (17 taps, radius 1)", APPROXIMATE,
                             "three.js taps 17 points within +-1 texel of the point, the lab the 3x3 texel grid"),
            } for kind in KINDS
        },
    }),
    "unity": Preset("unity", "Unity URP", _URP, {
        "shadow_map": {
            kind: {
                "variant": _s("normal_offset", "depth bias + normal bias, both x texel size",
                              "Runtime/ShadowUtils.cs GetShadowBias; ShaderLibrary/Shadows.hlsl ApplyShadowBias",
                              APPROXIMATE, "URP moves the casters, the lab the receiver; no (1 - N.L) factor"),
                "bias_space": _s("texels", "depthBias x texelSize (world)", "Runtime/ShadowUtils.cs GetShadowBias", APPROXIMATE,
                                 "local lights: URP's texel at the light's range, the lab's at the map's far plane"),
                "bias": _s(1.0, "m_ShadowDepthBias = 1.0", f"{_URP_ASSET}: m_ShadowDepthBias = 1.0f", EXACT),
                "normal_offset": _s(1.0, "m_ShadowNormalBias = 1.0", f"{_URP_ASSET}: m_ShadowNormalBias = 1.0f", APPROXIMATE,
                                    "applied as a receiver offset"),
                "resolution": _s(2048 if kind == "directional" else 512,
                                 "m_MainLightShadowmapResolution 2048" if kind == "directional" else
                                 "additional lights: the medium tier, 512 (tiers low 256 / medium 512 / high 1024)",
                                 _URP_ASSET, EXACT if kind == "directional" else UNCERTAIN,
                                 "" if kind == "directional" else "the per-light tier and the atlas decide"),
                "filter": _s("nearest", "m_SoftShadowsSupported = false: hard shadows",
                             f"{_URP_ASSET}: m_SoftShadowsSupported = false", EXACT),
            } for kind in KINDS
        },
        "cascaded_map": {
            "directional": {
                "cascades": _s(1, "m_ShadowCascadeCount = 1", f"{_URP_ASSET}: m_ShadowCascadeCount = 1", EXACT),
                "resolution": _s(2048, "m_MainLightShadowmapResolution 2048", _URP_ASSET, EXACT),
                "filter": _s("nearest", "m_SoftShadowsSupported = false", _URP_ASSET, EXACT),
            },
        },
    }),
    "ue5": Preset("ue5", "Unreal Engine 5", _UE5, {
        "shadow_map": {
            kind: {
                "variant": _s("slope", "Shadow Bias + Shadow Slope Bias (conventional shadow maps)",
                              "UE5 docs: Light component, Shadow Bias 0.5 / Shadow Slope Bias 0.5", UNCERTAIN,
                              "UE5's default for movable lights is a virtual shadow map"),
                "bias_space": _s("texels", "UE scales the depth bias by the map's texel size", "UE5 docs (no code)",
                                 UNCERTAIN),
                "bias": _s(0.5, "Shadow Bias 0.5", "UE5 docs: Light component properties, Shadow Bias", UNCERTAIN,
                           "the cvar r.Shadow.CSMDepthBias / r.Shadow.PointLightDepthBias multiplies it"),
                "slope_scale": _s(1.5, "Shadow Slope Bias 0.5 x r.Shadow.CSMSlopeScaleDepthBias 3",
                                  "UE5 docs: console variables r.Shadow.*SlopeScaleDepthBias", UNCERTAIN),
                "resolution": _s(2048, "r.Shadow.MaxResolution 2048", "UE5 docs: console variable r.Shadow.MaxResolution",
                                 UNCERTAIN),
                "filter": _s("pcf3", "Shadow Filter Sharpen 0, r.ShadowQuality 5: PCF", "UE5 docs: scalability", UNCERTAIN,
                             "UE's PCF kernel is wider and weighted"),
            } for kind in KINDS
        },
    }),
}
#: The names ``preset=`` takes: no preset, then the engines.
PRESET_NAMES = (NONE,) + tuple(PRESETS)


def preset(name: str, owner: str = "preset") -> Preset | None:
    """The :class:`Preset` called ``name`` (None for ``none``); a one-line TechniqueError with
    the closest name for an unknown one."""
    if name == NONE:
        return None
    if name not in PRESETS:
        raise TechniqueError(f"{owner}: preset must be one of {', '.join(PRESET_NAMES)}, got {name!r}"
                             f"{did_you_mean(name, PRESET_NAMES)}")
    return PRESETS[name]


class PresetMixin:
    """A technique with a ``preset`` parameter (:data:`PRESET_NAMES`): the keys the spec did not
    give take the preset's values for the light at hand; ``spec()`` writes ``preset=NAME`` and the
    keys given, so that ``from_spec(t.spec())`` keeps the light-dependent values light-dependent;
    ``short_label()`` names the preset and what the spec changed from it. With ``preset=none``
    (the default) the technique is exactly what it was without the mixin (its spec does not
    mention the preset).

    Listed before the technique base in a class's bases; the class's ``PARAMS`` must include
    ``preset``."""

    def __init__(self, **params):
        name = str(params.get("preset", NONE))
        chosen = preset(name, getattr(self, "name", "preset"))
        #: The keys the spec gave (they override the preset's).
        self._given = set(params) - {"preset"}
        self._preset = chosen
        self._kind = None
        if chosen is not None:
            # the directional values until the light is known (resolve_preset)
            params = {**chosen.values(self.name, "directional"), **params}
        super().__init__(**params)

    def preset_values(self, kind: str) -> dict:
        """The preset's values for a light of ``kind`` that the spec did not override."""
        if self._preset is None:
            return {}
        return {k: v for k, v in self._preset.values(self.name, kind).items() if k not in self._given}

    def resolve_preset(self, light) -> None:
        """Set the preset's parameters for ``light``'s kind (:data:`KIND_OF_LIGHT`); a note says
        which kind's defaults were used. Keys the spec gave are kept."""
        if self._preset is None:
            return
        kind = KIND_OF_LIGHT.get(light.type_name, "local")
        values = self.preset_values(kind)
        parsed = {k: self.PARAMS[k].parse(self.name, k, v) for k, v in values.items()}
        self._params.update(parsed)
        self._check_params()
        if kind != self._kind:
            self.notes.append(f"preset={self._preset.name}: {self._preset.engine}'s defaults for a {kind} light")
        self._kind = kind

    def _check_params(self) -> None:
        """Re-run the technique's cross-parameter checks after the preset changed values (none by default)."""

    def prepare(self, frame, slot) -> None:
        """Resolve the preset for the slot's light, then prepare as usual."""
        self.resolve_preset(frame.as_slot(slot).light)
        super().prepare(frame, slot)

    def _spec_params(self) -> dict:
        """The parameters ``spec()`` writes: every parameter but those the preset fills in."""
        filled = (self._preset.keys(self.name) - self._given) if self._preset is not None else set()
        out = {k: v for k, v in self.params().items() if k not in filled}
        if self._preset is None:
            out.pop("preset", None)
        return out

    def params_string(self) -> str:
        """``key=value,...``: the preset's name, the keys given and the parameters it does not set."""
        from ..base import format_value

        return ",".join(f"{k}={format_value(v)}" for k, v in self._spec_params().items())

    def short_label(self) -> str:
        """The name, ``preset=NAME`` and the parameters that differ from the preset's values
        (from their declared defaults for those it does not set)."""
        from ..base import format_value

        if self._preset is None:
            return super().short_label()
        base = {k: p.default for k, p in self.PARAMS.items()}
        base.update(self._preset.values(self.name, self._kind or "directional"))
        diff = [f"preset={self._preset.name}"]
        diff += [f"{k}={format_value(v)}" for k, v in self._params.items()
                 if k != "preset" and v != base.get(k)]
        diff += [f"{k}={format_value(v)}" for k, v in self._budget.items()
                 if k in ("budget", "select")]
        return f"{self.name}:{','.join(diff)}"


def table_rows() -> list[dict]:
    """Every preset value as a row (preset, technique, light kind, parameter, value, engine
    setting, source, fidelity, note): what the docs table lists."""
    rows = []
    for p in PRESETS.values():
        for tech, kinds in p.settings.items():
            for kind, params in kinds.items():
                for key, s in params.items():
                    rows.append({"preset": p.name, "engine": p.engine, "version": p.version, "technique": tech,
                                 "light": kind, "parameter": key, "value": s.value, "setting": s.engine,
                                 "source": s.source, "fidelity": s.fidelity, "note": s.note})
    return rows
