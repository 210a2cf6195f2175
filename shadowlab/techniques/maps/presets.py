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
(``repo@commit:path:line``, or the documentation page and setting), and how faithfully the lab's
parameter reproduces the engine's meaning (:data:`EXACT`, :data:`APPROXIMATE`, :data:`UNCERTAIN`);
docs/your-scenes.md lists every one (generated from :func:`table_rows`). What the engines' biases
mean, read from their code (units matter; none of the code is copied here):

- **Godot 4** (``scene/3d/light_3d.cpp`` at godotengine/godot@8ea4ec9; ``light_storage.cpp`` at
  @8403baa and ``scene/main/scene_tree.cpp`` at @002874d, the nearest commits they could be read
  at; lines counted): ``Light3D`` sets ``shadow_bias`` 0.1,
  ``shadow_normal_bias`` 1.0 and ``shadow_blur`` 1.0, ``DirectionalLight3D`` raises the normal bias
  to 2.0, ``OmniLight3D`` keeps both, ``SpotLight3D`` lowers the bias to 0.03. ``update_light_buffers``
  sends a directional light's bias as shadow_bias / 100 × the split's bias scale × shadow_blur × the
  directional quality radius (2.0 at the Soft Low filter quality: that radius and that default were
  not read at a known commit of godotengine/godot, uncertain), its normal bias × the split's texel
  size; an omni light's bias unscaled and its normal bias × its atlas texel size × 10. The forward
  shaders that apply them (``BIAS_FUNC``, ``light_process_omni_shadow``) were not read: that the
  directional bias moves the lookup point along the light (a world distance: ``bias_space=units``)
  and the normal bias along the normal × (1 − N·L) is an earlier reading, unverified; the lab's
  ``normal_offset`` in texels has no (1 − N·L) factor. Positional atlas 4096 with quadrant
  subdivisions 4/4/16/64 shadows (SceneTree's ``GLOBAL_DEF``); ``directional_shadow/size`` 4096 and
  the filter quality were not read in Godot's own ``rendering_server.cpp``. Default filter: soft PCF
  over a Vogel disk: no lab twin, nearest is ``pcf3``.
- **Bevy** (bevyengine/bevy@4805ca7: ``crates/bevy_light/src/*_light.rs``;
  ``crates/bevy_pbr/src/render/light.rs`` and ``shadows.wesl``): the lookup point moves
  ``shadow_depth_bias`` world units towards the light (``bias_space=units``) and
  ``shadow_normal_bias`` × √2 (applied when the light is extracted) × the cascade's texel size
  along the normal: ``normal_offset`` = 1.8 × √2 texels, exact for directional lights. For point
  lights the CPU pre-multiplies the normal bias by the cube face's texel size at unit distance
  and √2, and the shader by the distance: ``normal_offset`` = 0.6 × √2 texels, approximate (Bevy's
  distance to the light against the lab's). Default filter: ``ShadowFilteringMethod::Gaussian``
  (Castaño 2013's weighted footprint): nearest lab twin ``pcf5`` (a box).
- **three.js** (r187, the npm release three@0.187.0: ``src/lights/LightShadow.js``;
  ``shadowmap_pars_fragment.glsl.js``): ``bias`` is added to the window depth
  (``bias_space=window``) and defaults to 0; ``normalBias`` (world units) is 0; ``mapSize`` 512;
  the renderer's default ``PCFShadowMap`` averages five Vogel-disk taps of hardware 2×2
  comparisons within one texel of the point, rotated per pixel: nearest lab twin ``pcf3``.
- **Unity URP** (14.0.12, Unity 2022.3: ``UniversalRenderPipelineAsset.cs`` defaults;
  ``ShadowUtils.GetShadowBias`` and ``ApplyShadowBias`` in ``Shadows.hlsl``): depth bias 1 and
  normal bias 1, each × the light's texel size (directional: the orthographic frustum's width /
  resolution; spot and point: the frustum's half-width at the light's range / resolution), applied
  to the *casters* in the shadow pass (moved away from the light; shrunk along their normal by
  (1 − N·L) × normal bias); point lights' normal bias is forced to 0. Lab: the receiver moved
  towards the light by 1 texel (``bias_space=texels``) plus ``normal_offset`` 1 texel (0 for the
  local kind, a point light's) — approximate (receiver side, no (1 − N·L)). Main light map 2048;
  additional lights: tier High (1024) in a 2048 atlas, where a point light's six faces are scaled
  to 512. Soft shadows are off by default: ``nearest``.
- **Unreal Engine 5**: not public on GitHub; from documentation pages, not code. Its default for
  movable lights is the virtual shadow map (the lab's ``virtual_map``); the values here are the
  conventional shadow map's: the light's Shadow Bias and Shadow Slope Bias (whose defaults were
  not found in the documentation read: Epic's page recommends about 0.5) and the cvars
  ``r.Shadow.CSMSlopeScaleDepthBias`` 3 and ``r.Shadow.MaxResolution`` 2048, whose units (UE
  scales them inside the renderer) could not be checked: uncertain.
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


_GODOT_AT = "godotengine/godot@8ea4ec9"
_GODOT = ("Godot 4 master: scene/3d/light_3d.cpp read at godotengine/godot@8ea4ec9531e385802c08b97cb214e2de03056ddc; "
          "servers/rendering/renderer_rd/storage_rd/light_storage.cpp read at "
          "godotengine/godot@8403baa5a1e36485516c769a6393e056ed55192a (the nearest commit it could be read at); "
          "scene/main/scene_tree.cpp at godotengine/godot@002874d427012c965eef4cdeff03c1da4ee0431a")
_GODOT_LIGHT = f"{_GODOT_AT}:scene/3d/light_3d.cpp"
_GODOT_STORE = "godotengine/godot@8403baa:servers/rendering/renderer_rd/storage_rd/light_storage.cpp"
_GODOT_TREE = ("godotengine/godot@002874d:scene/main/scene_tree.cpp SceneTree::SceneTree (GLOBAL_DEF; line not "
               "verified)")
_GODOT_RSERVER = ("servers/rendering_server.cpp RenderingServer::init GLOBAL_DEF (not read in godotengine/godot: "
                  "UNVERIFIED; seen only in third-party copies of that code)")
_GODOT_QUALITY = ("servers/rendering/renderer_rd/renderer_scene_render_rd.cpp "
                  "RendererSceneRenderRD::directional_soft_shadow_filter_set_quality (not read at a known commit of "
                  "godotengine/godot: UNVERIFIED)")
_GODOT_SHADER = ("servers/rendering/renderer_rd/shaders/scene_forward_lights_inc.glsl (not read: UNVERIFIED)")
_BEVY_AT = "bevyengine/bevy@4805ca7"
_BEVY = "Bevy main (0.20.0-dev), bevyengine/bevy@4805ca792c3e94eef07afd6fa9a2712f388c9a67"
_THREE_AT = "mrdoob/three.js@r187 (npm three@0.187.0)"
_THREE = "three.js r187, the npm release three@0.187.0 (its src/ tree)"
_URP_AT = ("URP 14.0.12 (Unity 2022.3) as vendored unmodified in "
           "AnyGCn/AnyG-URPExtensions@b3a5b80:Packages/com.unity.render-pipelines.universal")
_URP = ("URP 14.0.12 (com.unity.render-pipelines.universal, Unity 2022.3), read as vendored in "
        "AnyGCn/AnyG-URPExtensions@b3a5b8078073692320e442b4e43813e3368a7305")
_URP_ASSET = "Runtime/Data/UniversalRenderPipelineAsset.cs"
_UE5 = "Unreal Engine 5 documentation (source not public on GitHub): Epic's API pages and a UE 5.4.4 cvar wiki"
_UE5_CVARS = "https://indxzero.github.io/ue544cvarwiki/articles/"
_UE5_BIAS = ("https://dev.epicgames.com/documentation/en-us/unreal-engine/API/Runtime/Engine/Components/"
             "ULightComponent/ShadowBias?application_version=5.5")
_NOT_FOUND = "not found in the documentation read"


def _s(value, engine, source, fidelity, note=""):
    return Setting(value, engine, source, fidelity, note)


PRESETS: dict[str, Preset] = {
    "godot": Preset("godot", "Godot", _GODOT, {
        "shadow_map": {
            "directional": {
                "variant": _s("normal_offset", "depth bias + normal bias together",
                              f"{_GODOT_STORE}:710-711 (shadow_bias[j], shadow_normal_bias[j] sent to the shader); "
                              "servers/rendering/renderer_rd/shaders/forward_clustered/scene_forward_clustered.glsl "
                              "BIAS_FUNC (not read: UNVERIFIED)",
                              APPROXIMATE, "both move the lookup point; the lab's normal offset has no (1 - N.L) factor"),
                "bias_space": _s("units", "shadow_bias is a world distance along the light",
                                 "scene_forward_clustered.glsl BIAS_FUNC: light_dir * shadow_bias (not read: UNVERIFIED)",
                                 UNCERTAIN, "the shader that applies the bias was not read"),
                "bias": _s(0.002, "DirectionalLight3D keeps Light3D's shadow_bias 0.1; the renderer sends 0.1 / 100 x "
                                  "bias_scale x soft_shadow_scale, where soft_shadow_scale = shadow_blur 1.0 x the "
                                  "directional quality radius (2.0 at soft_shadow_filter_quality Soft Low)",
                           f"{_GODOT_LIGHT}:484 (set_param(PARAM_SHADOW_BIAS, 0.1)), :483 (PARAM_SHADOW_BLUR 1.0); "
                           f"{_GODOT_STORE}:684 (soft_shadow_scale = shadow_blur), :688 (x "
                           f"directional_shadow_quality_radius_get()), :709-710 (/ 100.0 x bias_scale x "
                           f"soft_shadow_scale); radius 2.0 for SHADOW_QUALITY_SOFT_LOW: {_GODOT_QUALITY}",
                           UNCERTAIN, "the x 2 rests on the Soft Low default and its radius 2.0, both UNVERIFIED; "
                                      "bias_scale (per split, renderer_scene_cull.cpp, not read) is taken as 1 on the "
                                      "first split, the one the lab's single map stands for"),
                "normal_offset": _s(2.0, "DirectionalLight3D shadow_normal_bias 2.0 x the split's texel size",
                                    f"{_GODOT_LIGHT}:596 (set_param(PARAM_SHADOW_NORMAL_BIAS, 2.0)); "
                                    f"{_GODOT_STORE}:711 (x shadow_transform[j].shadow_texel_size)",
                                    APPROXIMATE, "Godot's shader scales by (1 - N.L) and drops the part along the light "
                                                 "(BIAS_FUNC, not read); the lab offsets the full normal"),
                "resolution": _s(4096, "rendering/lights_and_shadows/directional_shadow/size 4096",
                                 f"{_GODOT_RSERVER}, directional_shadow/size; "
                                 f"{_GODOT_STORE}:49 (LightStorage reads it)",
                                 UNCERTAIN, "one 4096 atlas split 2x2 among the PSSM splits; the lab draws one map"),
                "filter": _s("pcf3", "soft_shadow_filter_quality 2 (Soft Low): 4 Vogel-disk taps within the "
                                     "quality radius",
                             f"{_GODOT_RSERVER}, directional_shadow/soft_shadow_filter_quality; {_GODOT_QUALITY}",
                             UNCERTAIN, "no disk-kernel PCF in the lab; pcf3 is the nearest"),
            },
            "local": {
                "variant": _s("normal_offset", "depth bias + normal bias together",
                              f"{_GODOT_STORE}:955, 957-961 (shadow_normal_bias, shadow_bias sent to the shader); "
                              f"{_GODOT_SHADER}", APPROXIMATE, "as directional"),
                "bias_space": _s("units", "omni: shadow_bias sent unscaled (world units, by the earlier reading of the "
                                          "shader: subtracted from the radial distance)",
                                 f"{_GODOT_STORE}:959-960 (omni: the raw shadow_bias); {_GODOT_SHADER} "
                                 f"light_process_omni_shadow",
                                 UNCERTAIN, "the shader was not read; spot lights send shadow_bias / 100 x "
                                            "soft_shadow_scale (:958, :1011) in projected depth"),
                "bias": _s(0.1, "OmniLight3D keeps Light3D's shadow_bias 0.1 (SpotLight3D sets 0.03)",
                           f"{_GODOT_LIGHT}:484 (Light3D::Light3D: set_param(PARAM_SHADOW_BIAS, 0.1); "
                           f"OmniLight3D::OmniLight3D, :639-642, does not override it); :673 (SpotLight3D: 0.03); "
                           f"{_GODOT_STORE}:960 (omni: sent as is)", APPROXIMATE,
                           "the omni value; spot lights would get 0.03 / 100 x the quality radius in projected depth"),
                "normal_offset": _s(10.0, "shadow_normal_bias 1.0 x the light's atlas texel size x 10",
                                    f"{_GODOT_LIGHT}:485 (set_param(PARAM_SHADOW_NORMAL_BIAS, 1.0)); "
                                    f"{_GODOT_STORE}:954-955 (x light_instance_get_shadow_texel_size(...) x 10.0)",
                                    UNCERTAIN, "the x 10 is read; how light_instance_get_shadow_texel_size measures a "
                                               "texel, and the shader's (1 - |N.L|) factor, were not read"),
                "resolution": _s(1024, "positional shadow atlas 4096, quadrant subdivisions 2/2/3/4 (4, 4, 16 and 64 "
                                       "shadows): a light in quadrant 0 or 1 gets 2048 / 2 = 1024",
                                 f"{_GODOT_TREE}: positional_shadow/atlas_size 4096, atlas_quadrant_0..3_subdiv 2, 2, 3, "
                                 f"4; {_GODOT_STORE}:482 (an omni light takes two atlas spots)",
                                 UNCERTAIN, "depends on how many lights share the atlas; an omni light's cube is "
                                            "stored in two spots"),
                "filter": _s("pcf3", "positional soft_shadow_filter_quality (Soft Low by the third-party copies)",
                             f"{_GODOT_RSERVER}, positional_shadow/soft_shadow_filter_quality; {_GODOT_STORE}:986 "
                             f"(omni: x shadows_quality_radius_get())", UNCERTAIN,
                             "no disk-kernel PCF in the lab"),
            },
        },
        "cascaded_map": {
            "directional": {
                "cascades": _s(4, "DirectionalLight3D directional_shadow_mode PSSM 4 splits",
                               f"{_GODOT_LIGHT}:598 (DirectionalLight3D::DirectionalLight3D: "
                               f"set_shadow_mode(SHADOW_PARALLEL_4_SPLITS))", EXACT),
                "resolution": _s(2048, "directional_shadow/size 4096 shared 2x2 by four splits",
                                 f"{_GODOT_RSERVER}, directional_shadow/size", UNCERTAIN),
                "split_lambda": _s(0.5, "splits at 0.1 / 0.2 / 0.5 of max distance 100",
                                   f"{_GODOT_LIGHT}:477-479 (PARAM_SHADOW_SPLIT_1/2/3_OFFSET 0.1, 0.2, 0.5); "
                                   f":593 (DirectionalLight3D: PARAM_SHADOW_MAX_DISTANCE 100)",
                                   UNCERTAIN, "fixed fractions, not a lambda mix; 0.5 lies between their uniform and "
                                              "log fits"),
                "blend": _s(False, "directional_shadow_blend_splits false",
                            f"{_GODOT_LIGHT}:599 (DirectionalLight3D::DirectionalLight3D: blend_splits = false)", EXACT),
                "filter": _s("pcf3", "soft_shadow_filter_quality Soft Low: Vogel-disk PCF",
                             f"{_GODOT_RSERVER}; {_GODOT_QUALITY}", UNCERTAIN),
            },
        },
    }),
    "bevy": Preset("bevy", "Bevy", _BEVY, {
        "shadow_map": {
            "directional": {
                "variant": _s("normal_offset", "depth_offset + normal_offset together",
                              f"{_BEVY_AT}:crates/bevy_pbr/src/render/shadows.wesl:189-191 (sample_directional_cascade)",
                              EXACT),
                "bias_space": _s("units", "shadow_depth_bias x direction_to_light (world units)",
                                 f"{_BEVY_AT}:crates/bevy_pbr/src/render/shadows.wesl:190", EXACT),
                "bias": _s(0.02, "DirectionalLight::DEFAULT_SHADOW_DEPTH_BIAS = 0.02",
                           f"{_BEVY_AT}:crates/bevy_light/src/directional_light.rs:165", EXACT),
                "normal_offset": _s(2.5456, "DirectionalLight::DEFAULT_SHADOW_NORMAL_BIAS 1.8, x SQRT_2 when the "
                                            "light is extracted, x the cascade's texel_size in the shader",
                                    f"{_BEVY_AT}:crates/bevy_light/src/directional_light.rs:167; "
                                    f"{_BEVY_AT}:crates/bevy_pbr/src/render/light.rs:880 (x SQRT_2); "
                                    f"{_BEVY_AT}:crates/bevy_pbr/src/render/shadows.wesl:189 (x texel_size); "
                                    f"{_BEVY_AT}:crates/bevy_light/src/cascade.rs:291 (texel_size = diameter / size)",
                                    EXACT, "1.8 x sqrt(2) texels of the map"),
                "resolution": _s(2048, "DirectionalLightShadowMap::default size 2048",
                                 f"{_BEVY_AT}:crates/bevy_light/src/directional_light.rs:204", EXACT),
                "filter": _s("pcf5", "ShadowFilteringMethod::Gaussian (Castano 2013, 5x5 weighted)",
                             f"{_BEVY_AT}:crates/bevy_light/src/lib.rs:305-306 (#[default] Gaussian); "
                             f"{_BEVY_AT}:crates/bevy_pbr/src/render/shadow_sampling.wesl:101", APPROXIMATE,
                             "the lab's pcf5 is a box, Castano's weights are a tent"),
            },
            "local": {
                "variant": _s("normal_offset", "depth_offset + normal_offset together",
                              f"{_BEVY_AT}:crates/bevy_pbr/src/render/shadows.wesl:34-36 (fetch_point_shadow)", EXACT),
                "bias_space": _s("units", "shadow_depth_bias x normalize(surface_to_light)",
                                 f"{_BEVY_AT}:crates/bevy_pbr/src/render/shadows.wesl:35", EXACT),
                "bias": _s(0.08, "PointLight::DEFAULT_SHADOW_DEPTH_BIAS = 0.08 (SpotLight 0.02)",
                           f"{_BEVY_AT}:crates/bevy_light/src/point_light.rs:149; "
                           f"{_BEVY_AT}:crates/bevy_light/src/spot_light.rs:139 (spot)", APPROXIMATE,
                           "the point light's value; spot lights default to 0.02"),
                "normal_offset": _s(0.8485, "PointLight::DEFAULT_SHADOW_NORMAL_BIAS 0.6 x texel at unit distance x "
                                            "sqrt 2 x distance (major axis)",
                                    f"{_BEVY_AT}:crates/bevy_light/src/point_light.rs:151; "
                                    f"{_BEVY_AT}:crates/bevy_pbr/src/render/light.rs:466,582-584 (2 / size x SQRT_2); "
                                    f"{_BEVY_AT}:crates/bevy_pbr/src/render/shadows.wesl:34 (x distance_to_light)",
                                    APPROXIMATE,
                                    "0.6 x sqrt(2) texels; Bevy's distance is the major axis, the lab's Euclidean; "
                                    "spot lights: 1.8 x sqrt(2) (spot_light.rs:141, light.rs:721-723)"),
                "resolution": _s(1024, "PointLightShadowMap::default size 1024",
                                 f"{_BEVY_AT}:crates/bevy_light/src/point_light.rs:188", EXACT,
                                 "spot lights use the directional map's 2048 (light.rs:702)"),
                "projection": _s("cube", "point lights render a cube map",
                                 f"{_BEVY_AT}:crates/bevy_pbr/src/render/light.rs:1498-1499 (cube faces of "
                                 f"point_light_shadow_map.size)", EXACT),
                "filter": _s("pcf5", "ShadowFilteringMethod::Gaussian",
                             f"{_BEVY_AT}:crates/bevy_light/src/lib.rs:305-306; "
                             f"{_BEVY_AT}:crates/bevy_pbr/src/render/shadow_sampling.wesl:509 (sample_shadow_cubemap)",
                             APPROXIMATE, "cube maps sample a jittered disk in Bevy"),
            },
        },
        "cascaded_map": {
            "directional": {
                "cascades": _s(4, "CascadeShadowConfigBuilder::default num_cascades 4 (native; 1 on WebGL 2)",
                               f"{_BEVY_AT}:crates/bevy_light/src/cascade.rs:143-151", EXACT),
                "resolution": _s(2048, "DirectionalLightShadowMap size 2048",
                                 f"{_BEVY_AT}:crates/bevy_light/src/directional_light.rs:204", EXACT),
                "split_lambda": _s(0.5, "first_cascade_far_bound 10, maximum_distance 150, minimum_distance 0.1, "
                                        "geometric bounds from the first",
                                   f"{_BEVY_AT}:crates/bevy_light/src/cascade.rs:152-154 (defaults), 41-56 "
                                   f"(calculate_cascade_bounds)", UNCERTAIN,
                                   "Bevy fixes the first bound in metres; no lambda reproduces it on every scene"),
                "blend": _s(True, "overlap_proportion 0.2 (cascades overlap and blend)",
                            f"{_BEVY_AT}:crates/bevy_light/src/cascade.rs:155", APPROXIMATE),
                "blend_width": _s(0.2, "overlap_proportion 0.2", f"{_BEVY_AT}:crates/bevy_light/src/cascade.rs:155",
                                  APPROXIMATE),
                "filter": _s("pcf5", "ShadowFilteringMethod::Gaussian", f"{_BEVY_AT}:crates/bevy_light/src/lib.rs:305-306",
                             APPROXIMATE),
            },
        },
    }),
    "threejs": Preset("threejs", "three.js", _THREE, {
        "shadow_map": {
            kind: {
                "variant": _s("constant", "bias added to the window depth; normalBias 0 adds nothing",
                              f"{_THREE_AT}:src/renderers/shaders/ShaderChunk/shadowmap_pars_fragment.glsl.js:162 "
                              f"(getShadow: shadowCoord.z += shadowBias); src/lights/LightShadow.js:74 (normalBias = 0)",
                              EXACT),
                "bias_space": _s("window", "bias in window depth [0, 1]",
                                 f"{_THREE_AT}:src/renderers/shaders/ShaderChunk/shadowmap_pars_fragment.glsl.js:"
                                 f"150-162", EXACT, "point lights: added to the cube map's normalised depth (:388)"),
                "bias": _s(0.0, "LightShadow bias = 0", f"{_THREE_AT}:src/lights/LightShadow.js:53", EXACT),
                "resolution": _s(512, "LightShadow mapSize 512 x 512", f"{_THREE_AT}:src/lights/LightShadow.js:104",
                                 EXACT),
                "filter": _s("pcf3", "WebGLShadowMap type PCFShadowMap: 5 Vogel-disk taps of hardware 2x2 comparisons "
                                     "within radius 1 texel, rotated per pixel",
                             f"{_THREE_AT}:src/renderers/webgl/WebGLShadowMap.js:89 (type = PCFShadowMap); "
                             f"src/renderers/shaders/ShaderChunk/shadowmap_pars_fragment.glsl.js:173-185; "
                             f"src/lights/LightShadow.js:87 (radius = 1)", APPROXIMATE,
                             "the lab's pcf3 averages the 3x3 texel grid; three.js jitters 5 bilinear taps"),
            } for kind in KINDS
        },
    }),
    "unity": Preset("unity", "Unity URP", _URP, {
        "shadow_map": {
            kind: {
                "variant": _s("normal_offset", "depth bias + normal bias, both x texel size",
                              f"{_URP_AT}/Runtime/ShadowUtils.cs:278-332 (GetShadowBias); "
                              f"ShaderLibrary/Shadows.hlsl:471-480 (ApplyShadowBias, casters)",
                              APPROXIMATE, "URP moves the casters, the lab the receiver; no (1 - N.L) factor"),
                "bias_space": _s("texels", "depthBias x texelSize (world)",
                                 f"{_URP_AT}/Runtime/ShadowUtils.cs:323-325", APPROXIMATE,
                                 "directional: the frustum's width / resolution; local lights: URP's texel at the "
                                 "light's range, the lab's at the map's far plane"),
                "bias": _s(1.0, "m_ShadowDepthBias = 1.0", f"{_URP_AT}/{_URP_ASSET}:497", EXACT),
                "normal_offset": (
                    _s(1.0, "m_ShadowNormalBias = 1.0", f"{_URP_AT}/{_URP_ASSET}:498", APPROXIMATE,
                       "applied as a receiver offset")
                    if kind == "directional" else
                    _s(0.0, "point lights: normalBias forced to 0 (spot lights keep m_ShadowNormalBias 1.0)",
                       f"{_URP_AT}/Runtime/ShadowUtils.cs:331-332; {_URP_ASSET}:498 (spot)", APPROXIMATE,
                       "the point light's value, as the other presets' local kind; a spot light would get 1")),
                "resolution": (
                    _s(2048, "m_MainLightShadowmapResolution 2048", f"{_URP_AT}/{_URP_ASSET}:468", EXACT)
                    if kind == "directional" else
                    _s(512, "default tier High (1024) in the 2048 additional-lights atlas: a point light's six "
                            "1024 faces do not fit, so each is scaled to 512 (a spot light keeps 1024)",
                       f"{_URP_AT}/Runtime/UniversalAdditionalLightData.cs:104,136 (tier High); {_URP_ASSET}:474 "
                       f"(atlas 2048), 478, 593 (High = 1024); Runtime/Passes/AdditionalLightsShadowCasterPass.cs:"
                       f"314-326 (scale factor 2)", UNCERTAIN,
                       "a single point light; more lights in the atlas shrink it further")),
                "filter": _s("nearest", "m_SoftShadowsSupported = false: hard shadows",
                             f"{_URP_AT}/{_URP_ASSET}:506", EXACT),
            } for kind in KINDS
        },
        "cascaded_map": {
            "directional": {
                "cascades": _s(1, "m_ShadowCascadeCount = 1", f"{_URP_AT}/{_URP_ASSET}:492", EXACT),
                "resolution": _s(2048, "m_MainLightShadowmapResolution 2048", f"{_URP_AT}/{_URP_ASSET}:468", EXACT),
                "filter": _s("nearest", "m_SoftShadowsSupported = false", f"{_URP_AT}/{_URP_ASSET}:506", EXACT),
            },
        },
    }),
    "ue5": Preset("ue5", "Unreal Engine 5", _UE5, {
        "shadow_map": {
            kind: {
                "variant": _s("slope", "Shadow Bias + Shadow Slope Bias (conventional shadow maps)",
                              f"{_UE5_BIAS}; {_UE5_CVARS}r.shadow.csmslopescaledepthbias", UNCERTAIN,
                              "UE5's default for movable lights is a virtual shadow map; the conventional map's "
                              "depth + slope-scaled depth bias is the fallback"),
                "bias_space": _s("texels", "UE scales the depth bias by the map's texel size", "UE5 documentation",
                                 UNCERTAIN, f"units {_NOT_FOUND}"),
                "bias": _s(0.5, "light Shadow Bias (UI range 0-1; 'around 0.5 seems to be a good tradeoff')",
                           _UE5_BIAS, UNCERTAIN,
                           f"the default value is {_NOT_FOUND} (the page recommends about 0.5); the cvars "
                           f"r.Shadow.CSMDepthBias 10 (directional), r.Shadow.PointLightDepthBias 0.02, "
                           f"r.Shadow.SpotLightDepthBias 3 ({_UE5_CVARS}r.shadow.csmdepthbias, "
                           f"r.shadow.pointlightdepthbias, r.shadow.spotlightdepthbias) scale it in units not documented"),
                "slope_scale": _s(1.5, "Shadow Slope Bias 0.5 x r.Shadow.CSMSlopeScaleDepthBias 3",
                                  f"{_UE5_CVARS}r.shadow.csmslopescaledepthbias (3.0); "
                                  f"{_UE5_CVARS}r.shadow.pointlightslopescaledepthbias (3.0)", UNCERTAIN,
                                  f"the light's Shadow Slope Bias default is {_NOT_FOUND} (0.5 recommended)"),
                "resolution": _s(2048, "r.Shadow.MaxResolution 2048", f"{_UE5_CVARS}r.shadow.maxresolution",
                                 UNCERTAIN, "a maximum: UE sizes each map by its screen size up to it"),
                "filter": _s("pcf3", "UE's shadow PCF", "UE5 documentation", UNCERTAIN,
                             f"{_NOT_FOUND}; UE's PCF kernel is wider and weighted"),
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
            if self.name not in chosen.settings:
                having = [p.name for p in PRESETS.values() if self.name in p.settings]
                raise TechniqueError(f"{self.name}: preset={name} has no {self.name} defaults ({chosen.engine}'s "
                                     f"are for {', '.join(chosen.settings)}; {self.name} presets: "
                                     f"{', '.join(having)})")
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
        # every key the preset fills back to its declared default first: a key only one light kind
        # sets (Bevy's cube projection for point lights) must not carry over to the next light
        values = {k: self.PARAMS[k].default for k in self._preset.keys(self.name) - self._given}
        values.update(self.preset_values(kind))
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
