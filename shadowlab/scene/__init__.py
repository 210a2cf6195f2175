"""The scene model and its reading (docs/contracts.md#scene-files), no GL: :mod:`.model` (camera, materials,
objects, the scene), :mod:`.lights` (point, directional, spot, target-direct),
:mod:`.area_lights` (rect, disc, sphere), :mod:`.animation` (keyframes, ``scene_at``),
:mod:`.gltf` (glTF 2.0 files: meshes, KHR_lights_punctual lights, cameras) and :mod:`.reading`
(TOML scene files and glTF files → :class:`Scene`; shipped scenes live in
``shadowlab/scenes/``, package data).

Import order is one-way: lights ← area_lights ← model ← animation, gltf ← reading.
"""
from .model import (
    GENERAL_FAMILY, MANY_LIGHTS_FAMILY, SCENE_FAMILIES, SOFT_FAMILY, Camera, Material, Scene, SceneObject, Shading,
    default_of, family_from_name,
)
from .reading import (
    PRIMITIVES, builtin_scene_dir, builtin_scenes, load_scene, parse_light, parse_scene, resolve_scene_path,
    scene_family_key, scene_purpose, scene_summary,
)

__all__ = ["Camera", "Material", "Scene", "SceneObject", "Shading", "default_of", "GENERAL_FAMILY", "SCENE_FAMILIES",
           "SOFT_FAMILY", "MANY_LIGHTS_FAMILY", "family_from_name", "PRIMITIVES", "builtin_scene_dir", "builtin_scenes",
           "load_scene", "parse_light", "parse_scene", "resolve_scene_path", "scene_family_key", "scene_purpose",
           "scene_summary"]
