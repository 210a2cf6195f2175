"""Scene files: shipped scenes load; malformed input fails with file, key and reason (docs/contracts.md#scene-files)."""
from __future__ import annotations

import textwrap

import numpy as np
import pytest
import trimesh

from shadowlab.scene import builtin_scenes, load_scene
from shadowlab.util.validation import SceneError

GOOD = textwrap.dedent("""
    name = "t"
    [camera]
    eye = [4.0, 3.0, 5.0]
    target = [0.0, 0.5, 0.0]
    [[lights]]
    type = "point"
    position = [2.0, 6.0, 1.0]
    [[objects]]
    mesh = "plane"
    size = [10.0, 10.0]
    [[objects]]
    mesh = "box"
    translate = [0.0, 0.5, 0.0]
""")


def write(tmp_path, text, name="scene.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_shipped_scenes_load():
    names = set(builtin_scenes())
    assert {"box_on_plane", "spot_scene", "sun_scene", "target_direct_scene"} <= names
    for name in names:
        s = load_scene(name)
        assert s.lights and s.objects


def _nearest_caster(scene, light) -> float:
    """Distance from a light's position to the nearest point of any casting triangle."""
    best = np.inf
    for o in scene.objects:
        if o.casts:
            tris = o.vertices[o.faces]
            q = trimesh.triangles.closest_point(tris, np.repeat(light.position[None], len(tris), 0))
            best = min(best, float(np.linalg.norm(q - light.position, axis=1).min()))
    return best


def test_the_lamp_scenes_hold_their_hard_cases():
    """Issue 35's scenes keep what they test: in sm_room_lamp both lamps stand inside the bounding
    box of the room, one mesh of closed outward boxes that casts and receives, with no caster
    within 0.5 m; in sm_lamp_contact each lamp has a caster under 1 cm away (5 mm)."""
    room = load_scene("sm_room_lamp")
    assert len(room.objects) == 1 and room.objects[0].casts and room.objects[0].receives
    mesh = room.objects[0]
    lo, hi = mesh.vertices.min(0), mesh.vertices.max(0)
    assert {l.type_name for l in room.lights} == {"spot", "point"}
    for light in room.lights:
        assert np.all(lo < light.position) and np.all(light.position < hi)
        assert _nearest_caster(room, light) > 0.5
    parts = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).split(only_watertight=False)
    assert len(mesh.faces) == 336 and len(parts) == 16
    assert all(p.is_watertight and p.is_winding_consistent and p.volume > 0 for p in parts)
    contact = load_scene("sm_lamp_contact")
    assert len(contact.lights) == 2
    for light in contact.lights:
        assert 0.004 < _nearest_caster(contact, light) < 0.006


def test_good_scene_and_transforms(tmp_path):
    s = load_scene(write(tmp_path, GOOD))
    box = s.objects[1]
    assert np.allclose(box.vertices.min(0), [-0.5, 0.0, -0.5]) and np.allclose(box.vertices.max(0), [0.5, 1.0, 0.5])
    cam = s.fitted_camera()
    assert 0 < cam.near < cam.far


def test_scale_rotate_translate_order(tmp_path):
    text = GOOD.replace('translate = [0.0, 0.5, 0.0]',
                        'size = [2.0, 1.0, 1.0]\nscale = [1.0, 1.0, 3.0]\nrotate = [0.0, 90.0, 0.0]\ntranslate = [5.0, 0.0, 0.0]')
    box = load_scene(write(tmp_path, text)).objects[1]
    # box 2x1x1, scaled z by 3 -> 2x1x3, rotated 90 deg about y -> 3x1x2, moved by +5 in x
    ext = box.vertices.max(0) - box.vertices.min(0)
    assert np.allclose(ext, [3, 1, 2]) and np.allclose(box.vertices.mean(0), [5, 0, 0])


@pytest.mark.parametrize("old,new,key", [
    ('type = "point"', 'type = "spot"\ndirection = [0.0, -1.0, 0.0]\nalpha = 30.0\nbeta = 40.0', "lights[0].beta"),
    ('type = "point"\nposition = [2.0, 6.0, 1.0]',
     'type = "target_direct"\nposition = [0.0, 5.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\nR = 1.0\nr = 2.0', "lights[0].r"),
    ('type = "point"\nposition = [2.0, 6.0, 1.0]', 'type = "directional"\ndirection = [0.0, 0.0, 0.0]', "lights[0].direction"),
    ('position = [2.0, 6.0, 1.0]', 'position = [2.0, nan, 1.0]', "lights[0].position"),
    ('position = [2.0, 6.0, 1.0]', 'position = [2.0, 6.0]', "lights[0].position"),
    ('position = [2.0, 6.0, 1.0]', 'position = [2.0, 6.0, 1.0]\nbrightness = 2', "lights[0].brightness"),
    ('type = "point"', 'type = "laser"', "lights[0].type"),
    ('eye = [4.0, 3.0, 5.0]', 'eye = [0.0, 0.5, 0.0]', "camera.target"),
    ('eye = [4.0, 3.0, 5.0]', 'eye = "here"', "camera.eye"),
    ('eye = [4.0, 3.0, 5.0]\n', '', "camera.eye"),
    ('mesh = "box"', 'mesh = "missing_mesh.obj"', "objects[1].mesh"),
    ('mesh = "box"', 'mesh = "box"\nsize = [1.0, -1.0, 1.0]', "objects[1].size"),
    ('mesh = "box"', 'mesh = "box"\ncasts = "yes"', "objects[1].casts"),
    ('name = "t"', 'name = "t"\ncolour = 1', "colour"),
])
def test_bad_scenes_name_file_key_reason(tmp_path, old, new, key):
    assert old in GOOD
    path = write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.key == key, str(info.value)
    assert str(path) in str(info.value) and info.value.reason


@pytest.mark.parametrize("primitive,key,triangles", [
    ('mesh = "torus"\nmajor_sections = 100000', "objects[1].major_sections", "4,800,000"),
    ('mesh = "torus"\nmajor_sections = 30\nminor_sections = 100000', "objects[1].minor_sections", "6,000,000"),
    ('mesh = "cylinder"\nsections = 2000000', "objects[1].sections", "8,000,000"),
    ('mesh = "plane"\ndivisions = 2048', "objects[1].divisions", "8,388,608"),
])
def test_primitives_are_bounded_before_they_are_built(tmp_path, primitive, key, triangles):
    """A procedural primitive with absurd sections is a one-line scene error naming the key and
    the triangle count it would make — not a MemoryError traceback after minutes of building."""
    from shadowlab.scene.reading import MAX_PRIMITIVE_TRIANGLES

    path = write(tmp_path, GOOD.replace('mesh = "box"', primitive, 1))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.key == key and triangles in str(info.value) and "\n" not in str(info.value)
    assert f"{MAX_PRIMITIVE_TRIANGLES:,}" in str(info.value)


@pytest.mark.slow  # builds a 4.2-million-triangle torus (~20 s)
def test_a_primitive_at_the_bound_still_builds(tmp_path):
    """The bound refuses only what is above it: a torus of exactly 2 × 2048 × 1024 triangles."""
    from shadowlab.scene.reading import MAX_PRIMITIVE_TRIANGLES

    ok = load_scene(write(tmp_path, GOOD.replace('mesh = "box"', 'mesh = "torus"\nmajor_sections = 2048\nminor_sections = 1024', 1)))
    assert len(ok.objects[1].faces) == MAX_PRIMITIVE_TRIANGLES


def test_not_toml_and_unknown_scene(tmp_path):
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(write(tmp_path, "name = = 3"))
    with pytest.raises(SceneError, match="not a shipped scene"):
        load_scene("no_such_scene_anywhere")


def test_mesh_file_is_loaded_relative_and_welded(tmp_path):
    # An OBJ whose faces do not share vertices (a "triangle soup") is welded on load.
    box = trimesh.creation.box()
    soup = trimesh.Trimesh(box.vertices[box.faces].reshape(-1, 3), np.arange(36).reshape(12, 3), process=False)
    (tmp_path / "meshes").mkdir()
    soup.export(tmp_path / "meshes" / "soup.obj")
    s = load_scene(write(tmp_path, GOOD.replace('mesh = "box"', 'mesh = "meshes/soup.obj"')))
    obj = s.objects[1]
    assert len(obj.faces) == 12 and len(obj.vertices) == 8


def test_a_scene_declares_its_family_strictly(tmp_path):
    """``family`` is optional and read strictly: a declared family is the scene's, none gives
    None (the study falls back on the name), and a misspelt one is a one-line error naming the
    file and the key, with the closest family."""
    declared = load_scene(write(tmp_path, GOOD.replace('name = "t"', 'name = "t"\nfamily = "soft shadows"')))
    assert declared.family == "soft shadows"
    assert load_scene(write(tmp_path, GOOD, "plain.toml")).family is None
    path = write(tmp_path, GOOD.replace('name = "t"', 'name = "t"\nfamily = "sof shadows"'), "misspelt.toml")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    assert info.value.key == "family" and str(path) in message and "\n" not in message
    assert "did you mean 'soft shadows'?" in message


def test_every_shipped_scene_declares_the_family_its_name_gave():
    """Every shipped scene file (the scaling suite's included) declares its family, the one the
    name's prefix gave before files declared it, so that no study's grouping or judged metric
    changed. Read as TOML only: the meshes are not built."""
    import tomllib
    from pathlib import Path

    from shadowlab.scene import SCENE_FAMILIES, builtin_scene_dir, family_from_name

    files = sorted(builtin_scene_dir().glob("*.toml"))
    files += sorted((Path(builtin_scene_dir()).parent / "suites" / "scaling").glob("*.toml"))
    assert len(files) > 40
    for path in files:
        data = tomllib.loads(path.read_text())
        assert data.get("family") in SCENE_FAMILIES, path.name
        assert data["family"] == family_from_name(data.get("name", path.stem)), path.name
