"""glTF 2.0 scenes (issue 41): the reader's geometry, lights, cameras and notes on a hand-made
fixture (tests/scene/gltf/fixture.gltf, written by make_fixture.py beside it), broken files, the
``[gltf]`` table of a TOML scene, and the Blender scene against its plain-TOML twin."""
from __future__ import annotations

import base64
import json
import math
import shutil
import struct
from pathlib import Path

import numpy as np
import pytest

from shadowlab.scene import builtin_scenes, load_scene, scene_purpose, scene_summary
from shadowlab.scene import gltf
from shadowlab.scene.lights import DirectionalLight, PointLight, SpotLight
from shadowlab.util.validation import SceneError

HERE = Path(__file__).parent / "gltf"
FIXTURE = HERE / "fixture.gltf"
BLENDER = Path(builtin_scenes()["gltf_blender_cube"]).parent / "gltf" / "blender_cube.glb"


@pytest.fixture(scope="module")
def fixture():
    return gltf.read_gltf(FIXTURE)


def test_objects_are_node_instances_in_world_space(fixture):
    """Hierarchy, matrix and TRS: each box's world bounds worked out by hand (root: +1 in y,
    90° about y, so x → −z and z → x; the first box by matrix: ×0.5 then +2 in x; the second by
    TRS: ×(1, 2, 1) then −2 in x); a mesh used twice is two objects, the name made unique."""
    names = [o.name for o in fixture.objects]
    assert names == ["Box", "Box_2", "Floor"]
    bounds = {o.name: o.bounds() for o in fixture.objects}
    assert np.allclose(bounds["Box"], [[-0.25, 0.75, -2.25], [0.25, 1.25, -1.75]], atol=1e-12)
    assert np.allclose(bounds["Box_2"], [[-0.5, 0.0, 1.5], [0.5, 2.0, 2.5]], atol=1e-12)
    assert np.array_equal(bounds["Floor"], [[-3.0, 0.0, -3.0], [3.0, 0.0, 3.0]])
    for o in fixture.objects:
        assert o.vertices.dtype == np.float64 and o.faces.dtype == np.int64
    box = fixture.objects[0]
    assert box.vertices.shape == (8, 3) and box.faces.shape == (12, 3)  # welded: 8 corners
    # CCW outward after the transform: every face normal points away from the box's centre
    tri = box.triangles
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert (np.einsum("ij,ij->i", normals, tri.mean(1) - box.vertices.mean(0)) > 0).all()
    assert np.allclose(box.material.diffuse, [0.9, 0.2, 0.1]) and np.allclose(fixture.objects[2].material.diffuse, 0.5)
    assert fixture.objects[2].faces.shape == (2, 3)  # the points primitive is left out (noted)


def test_trimesh_agrees_on_the_world_transforms(fixture):
    """The reader's own TRS/matrix chain and trimesh's scene graph put the boxes in the same
    place (trimesh's glTF loader, reading the fixture itself)."""
    import trimesh

    scene = trimesh.load(FIXTURE, force="scene", process=False)
    theirs = sorted(np.round(np.concatenate([np.asarray(scene.geometry[g].vertices) @ m[:3, :3].T + m[:3, 3]
                                             for n in scene.graph.nodes_geometry for m, g in [scene.graph[n]]
                                             if g.startswith("cube")]), 9).tolist())
    ours = sorted(np.round(np.concatenate([o.vertices for o in fixture.objects[:2]]), 9).tolist())
    assert len(theirs) == 16 and np.allclose(theirs, ours, atol=1e-9)


def test_lights_are_placed_down_their_nodes_minus_z(fixture):
    spot, lamp = fixture.lights
    assert (spot.name, spot.type, lamp.name, lamp.type) == ("SpotNode", "spot", "PointNode", "point")
    assert np.allclose(spot.position, [0, 4, 0]) and np.allclose(spot.direction, [0, -1, 0])
    assert spot.inner == pytest.approx(math.radians(20)) and spot.outer == pytest.approx(math.radians(35))
    assert spot.range is None and lamp.range == 12.0
    assert np.allclose(lamp.position, [0, 3, -1])  # (1, 2, 0) turned by the root, + 1 in y
    # the mapping into the lab's [[lights]] keys
    t = gltf.light_table(spot, 0.01, 0.15)
    assert t["alpha"] == pytest.approx(70.0) and t["beta"] == pytest.approx(40.0)
    assert t["cone_falloff"] == "squared" and t["inverse_square"] is True and "range" not in t
    assert np.allclose(t["color"], [4.0, 3.6, 3.2]) and t["ambient"] == pytest.approx(0.6)
    t = gltf.light_table(lamp, 0.01, 0.0)
    assert t["range"] == 12.0 and "inverse_square" not in t and t["ambient"] == 0.0


def test_cameras_by_name_node_name_or_index(fixture):
    assert [c.name for c in fixture.cameras] == ["A", "B", "Top"]
    assert gltf.choose_camera(fixture)[1] == 0
    for choice, index in (("B", 1), ("CamBNode", 1), ("1", 1), (1, 1), ("A", 0)):
        assert gltf.choose_camera(fixture, choice)[1] == index
    b = gltf.choose_camera(fixture, "B")[0]
    # under a parent turned 90° about y: (0, 2, 8) → (8, 2, 0), looking down −x, up +y
    assert np.allclose(b.eye, [8, 2, 0]) and np.allclose(b.forward, [-1, 0, 0]) and np.allclose(b.up, [0, 1, 0])
    with pytest.raises(SceneError, match="camera 'Top' is orthographic"):
        gltf.choose_camera(fixture, "Top")
    with pytest.raises(SceneError, match="no camera 'Tp'; did you mean 'Top'"):
        gltf.choose_camera(fixture, "Tp")
    cam = gltf.lab_camera(gltf.choose_camera(fixture)[0], np.array([[-3.0, 0, -3], [3, 2, 3]]))
    assert cam.fov_y == pytest.approx(50.0) and (cam.near, cam.far) == (0.1, 100.0)
    assert np.allclose(cam.target, [0, 2, 0])  # the point of its ray nearest the bounds' centre (0, 1, 0)


def test_what_is_left_out_is_named(fixture):
    notes = "\n".join(fixture.notes)
    for what in ("KHR_materials_emissive_strength", "skin", "morph targets", "points left out",
                 "unknown type 'area'", "'Top' is orthographic"):
        assert what in notes, what
    assert all(n.startswith("glTF fixture.gltf: ") for n in fixture.notes)


def test_a_gltf_path_is_a_scene(tmp_path):
    """``load_scene`` reads a glTF path, ``#name`` / ``#index`` choosing the camera; the lights
    at the automatic exposure: the lights' summed strengths at the centre of the scene's bounds
    are 1, whichever camera is chosen."""
    scene = load_scene(FIXTURE)
    assert scene.name == "fixture" and scene.family == "general" and len(scene.objects) == 3
    assert [type(l) for l in scene.lights] == [SpotLight, PointLight]
    assert np.allclose(scene.camera.eye, [0, 2, 8]) and any("exposure 'auto'" in n for n in scene.notes)
    target = scene.bounds().mean(0)
    spot, lamp = gltf.read_gltf(FIXTURE).lights
    strength = sum(l.intensity * l.color.max() / np.sum((target - l.position) ** 2) for l in (spot, lamp))
    assert scene.lights[0].color.max() == pytest.approx(400.0 / strength)
    other = load_scene(f"{FIXTURE}#B")
    assert np.allclose(other.camera.eye, [8, 2, 0])
    assert all(np.array_equal(a.color, b.color) for a, b in zip(other.lights, scene.lights))
    assert np.allclose(load_scene(f"{FIXTURE}#1").camera.eye, [8, 2, 0])
    assert "general" == load_scene(f"{FIXTURE}#CamA").family
    assert "3 objects" in scene_summary(FIXTURE) and "tests/scene/gltf/make_fixture.py" in scene_purpose(FIXTURE)


def _write_glb(path: Path, doc: dict, blob: bytes = b"") -> Path:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text
    if blob:
        blob += b"\0" * (-len(blob) % 4)
        body += struct.pack("<II", len(blob), 0x004E4942) + blob
    path.write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)
    return path


def _fixture_doc() -> dict:
    return json.loads(FIXTURE.read_text())


@pytest.mark.parametrize("name,break_it,key", [
    ("bad_json.gltf", lambda p: p.write_text("{ not json"), "json"),
    ("truncated.glb", lambda p: p.write_bytes(BLENDER.read_bytes()[:3000]), "glb"),
    ("short.glb", lambda p: p.write_bytes(b"glTF"), "glb"),
    ("v1.gltf", lambda p: p.write_text(json.dumps({**_fixture_doc(), "asset": {"version": "1.0"}})), "asset.version"),
    ("nobuf.gltf", lambda p: p.write_text(json.dumps({**_fixture_doc(), "buffers": [
        {"byteLength": 10, "uri": "missing.bin"}]})), "buffers[0].uri"),
    ("index.gltf", lambda p: p.write_text(json.dumps(
        {**_fixture_doc(), "nodes": [{**n, "mesh": 7} if n.get("name") == "Floor" else n
                                     for n in _fixture_doc()["nodes"]]})), "nodes[3].mesh"),
    ("extent.gltf", lambda p: p.write_text(json.dumps(
        {**_fixture_doc(), "accessors": [{**a, "count": a["count"] * 50} if i == 0 else a
                                         for i, a in enumerate(_fixture_doc()["accessors"])]})), "accessors[0]"),
    ("cycle.gltf", lambda p: p.write_text(json.dumps(
        {**_fixture_doc(), "nodes": [{**n, "children": [0]} if n.get("name") == "CamA" and False else
                                     ({**n, "children": [1, 2, 4, 5, 0]} if n.get("name") == "Root" else n)
                                     for n in _fixture_doc()["nodes"]]})), "nodes[0]"),
    ("faces.gltf", None, "indices"),
    ("count.gltf", lambda p: p.write_text(json.dumps(
        {**_fixture_doc(), "accessors": [{**a, "count": 2.5} if i == 0 else a
                                         for i, a in enumerate(_fixture_doc()["accessors"])]})), "accessors[0].count"),
    ("offset.gltf", lambda p: p.write_text(json.dumps(
        {**_fixture_doc(), "bufferViews": [{**v, "byteOffset": -100} if i == 0 else v
                                           for i, v in enumerate(_fixture_doc()["bufferViews"])]})),
     "bufferViews[0].byteOffset"),
    ("stride.gltf", lambda p: p.write_text(json.dumps(
        {**_fixture_doc(), "bufferViews": [{**v, "byteStride": 6} if i == 0 else v
                                           for i, v in enumerate(_fixture_doc()["bufferViews"])]})),
     "bufferViews[0].byteStride"),
])
def test_a_broken_file_is_one_scene_error_naming_the_key(tmp_path, name, break_it, key):
    path = tmp_path / name
    if break_it is None:  # an index past the vertices: rewrite the first cube index to 99
        doc = _fixture_doc()
        blob = bytearray(base64.b64decode(doc["buffers"][0]["uri"].split(",", 1)[1]))
        view = doc["bufferViews"][doc["accessors"][1]["bufferView"]]
        struct.pack_into("<H", blob, view["byteOffset"], 99)
        doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()
        path.write_text(json.dumps(doc))
    else:
        break_it(path)
    with pytest.raises(SceneError) as err:
        load_scene(path)
    assert str(path) in str(err.value) and key in err.value.key and "\n" not in str(err.value)


def test_no_camera_or_no_lights_says_what_to_write(tmp_path):
    doc = {k: v for k, v in _fixture_doc().items() if k != "cameras"}
    doc["nodes"] = [{k: v for k, v in n.items() if k != "camera"} for n in doc["nodes"]]
    (tmp_path / "nocam.gltf").write_text(json.dumps(doc))
    with pytest.raises(SceneError, match="nocam.gltf has no camera; write a TOML scene that includes it"):
        load_scene(tmp_path / "nocam.gltf")
    doc = _fixture_doc()
    doc["nodes"] = [{k: v for k, v in n.items() if k != "extensions"} for n in doc["nodes"]]
    (tmp_path / "dark.gltf").write_text(json.dumps(doc))
    with pytest.raises(SceneError, match="dark.gltf has no lights"):
        load_scene(tmp_path / "dark.gltf")


def test_a_glb_with_external_and_bin_buffers(tmp_path):
    """The same fixture as a glb (BIN chunk) and as a .gltf with a .bin file: the same objects."""
    doc = _fixture_doc()
    blob = base64.b64decode(doc["buffers"][0]["uri"].split(",", 1)[1])
    glb = _write_glb(tmp_path / "f.glb", {**doc, "buffers": [{"byteLength": len(blob)}]}, blob)
    (tmp_path / "f.bin").write_bytes(blob)
    (tmp_path / "f.gltf").write_text(json.dumps({**doc, "buffers": [{"byteLength": len(blob), "uri": "f.bin"}]}))
    base = gltf.read_gltf(FIXTURE)
    for path in (glb, tmp_path / "f.gltf"):
        other = gltf.read_gltf(path)
        assert all(np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
                   for a, b in zip(base.objects, other.objects))
    from shadowlab.output.cache import scene_content_hash, scene_mesh_files

    assert [r for r, _ in scene_mesh_files(tmp_path / "f.gltf")] == ["f.bin"]
    h = scene_content_hash(tmp_path / "f.gltf")
    (tmp_path / "f.bin").write_bytes(blob[:-4] + b"\1\1\1\1")
    assert scene_content_hash(tmp_path / "f.gltf") != h  # the buffer is part of the scene's content


def _toml(tmp_path, body: str) -> Path:
    shutil.copy(FIXTURE, tmp_path / "fixture.gltf")
    path = tmp_path / "s.toml"
    path.write_text(body)
    return path


def test_a_toml_scene_includes_a_gltf_file(tmp_path):
    """[gltf] with an override (a range, a colour), a fixed exposure, the second camera, extra
    [[objects]] and [[lights]], an animation naming an imported object."""
    scene = load_scene(_toml(tmp_path, '''
name = "inc"
[gltf]
file = "fixture.gltf"
camera = "B"
exposure = 0.01
ambient = 0.0
[gltf.light_overrides.SpotNode]
range = 20.0
color = [1.0, 2.0, 3.0]
[[objects]]
mesh = "box"
name = "extra"
translate = [0.0, 0.5, 0.0]
[[lights]]
type = "directional"
direction = [0.0, -1.0, 0.0]
[animation]
frames = 2
[[animation.objects]]
object = "Box_2"
t = 0.0
translate = [0.0, 0.0, 0.0]
[[animation.objects]]
object = "Box_2"
t = 1.0
translate = [1.0, 0.0, 0.0]
'''))
    assert [o.name for o in scene.objects] == ["Box", "Box_2", "Floor", "extra"]
    spot, lamp, sun = scene.lights
    assert spot.range == 20.0 and not spot.inverse_square and spot.color.tolist() == [1.0, 2.0, 3.0]
    assert spot.cone_falloff == "squared" and lamp.range == 12.0 and lamp.ambient == 0.0
    assert lamp.color == pytest.approx([0.5, 0.5, 0.5]) and isinstance(sun, DirectionalLight)
    assert np.allclose(scene.camera.eye, [8, 2, 0]) and scene.animation is not None
    assert not any("exposure" in n for n in scene.notes) and any("skin" in n for n in scene.notes)
    # lights = false and a [camera]: only the file's objects
    scene = load_scene(_toml(tmp_path, '''
[gltf]
file = "fixture.gltf"
lights = false
[camera]
eye = [0.0, 5.0, 9.0]
target = [0.0, 0.0, 0.0]
[[lights]]
type = "point"
position = [0.0, 5.0, 0.0]
'''))
    assert len(scene.lights) == 1 and scene.camera.eye.tolist() == [0.0, 5.0, 9.0]


@pytest.mark.parametrize("body,culprit", [
    ('[gltf]\nfile = "fixture.gltf"\ncamra = "A"\n', "gltf.camra: unknown key; did you mean 'camera'"),
    ('[gltf]\nfile = "fixture.gltf"\n[gltf.light_overrides.Spot]\nrange = 3.0\n',
     "gltf.light_overrides.Spot: no light 'Spot' in fixture.gltf; did you mean 'SpotNode'"),
    ('[gltf]\nfile = "fixture.gltf"\n[gltf.light_overrides.SpotNode]\ntype = "point"\n', "not its type"),
    ('[gltf]\nfile = "fixture.gltf"\n[gltf.light_overrides.SpotNode]\nalpah = 3.0\n',
     "gltf.light_overrides.SpotNode.alpah: unknown key; did you mean 'alpha'"),
    ('[gltf]\nfile = "fixture.gltf"\nexposure = -1\n', "gltf.exposure: must be > 0"),
    ('[gltf]\nfile = "nowhere.glb"\n', "gltf.file: glTF file not found"),
    ('[gltf]\nfile = "fixture.gltf"\ncamera = "Top"\n', "gltf.camera: camera 'Top' is orthographic"),
    ('[gltf]\nfile = "fixture.gltf"\n[[objects]]\nmesh = "box"\nname = "Floor"\n', "objects[0].name"),
    ('[gltf]\nfile = "fixture.gltf"\nlights = false\n', "lights: at least one light is required"),
])
def test_bad_gltf_tables_name_the_key(tmp_path, body, culprit):
    with pytest.raises(SceneError) as err:
        load_scene(_toml(tmp_path, body))
    assert culprit in str(err.value) and "\n" not in str(err.value)


def test_the_blender_file_is_what_blender_wrote():
    g = gltf.read_gltf(BLENDER)
    assert g.generator.startswith("Khronos glTF Blender I/O") and g.notes == []
    assert [o.name for o in g.objects] == ["Cube", "Ground", "Crate"]
    assert [(l.name, l.type) for l in g.lights] == [("Sun", "directional"), ("Spot", "spot"), ("Point", "point")]
    assert [c.name for c in g.cameras] == ["Camera", "TopCamera"]
    assert g.lights[2].intensity == pytest.approx(54351.41306588226)  # Blender's 1000 W point light, in cd
    assert np.array_equal(g.objects[0].bounds(), [[-1, -1, -1], [1, 1, 1]])  # the default cube


def test_the_blender_scene_and_its_toml_twin_are_the_same_scene():
    """gltf_blender_cube (Blender's glb, included by a TOML scene) and the plain TOML scene of
    tests/scene/gltf/blender_cube_twin (OBJ meshes of the world-space vertices in repr() floats,
    lights and camera as the reader mapped them) load to identical arrays."""
    a = load_scene("gltf_blender_cube")
    b = load_scene(HERE / "blender_cube_twin" / "scene.toml")
    assert [o.name for o in a.objects] == [o.name for o in b.objects]
    for x, y in zip(a.objects, b.objects):
        assert np.array_equal(x.vertices, y.vertices) and np.array_equal(x.faces, y.faces)
        assert np.array_equal(x.material.diffuse, y.material.diffuse)
    assert [l.describe() for l in a.lights] == [l.describe() for l in b.lights]
    for key in ("eye", "target", "up"):
        assert np.array_equal(getattr(a.camera, key), getattr(b.camera, key))
    assert (a.camera.fov_y, a.camera.near, a.camera.far) == (b.camera.fov_y, b.camera.near, b.camera.far)


def test_a_suite_runs_a_gltf_file_like_a_toml_scene(tmp_path):
    from shadowlab.output.cache import scene_mesh_files
    from shadowlab.study.suite import SuiteError, load_suite

    shutil.copy(FIXTURE, tmp_path / "fixture.gltf")
    (tmp_path / "s.toml").write_text('name = "s"\nscenes = ["fixture.gltf", "gltf_blender_cube"]\n'
                                     'techniques = ["shadow_map"]\n')
    suite = load_suite(tmp_path / "s.toml")
    entry = suite.scenes[0]
    assert (entry.name, entry.family, entry.light_types) == ("fixture", "general", ("spot", "point"))
    assert suite.notes == []
    refs = [r for r, _ in scene_mesh_files(builtin_scenes()["gltf_blender_cube"])]
    assert refs == ["gltf/blender_cube.glb"]  # the cache hash and a Dask bundle carry the glb
    (tmp_path / "s.toml").write_text('name = "s"\nscenes = ["fixture.gltf#B"]\ntechniques = ["shadow_map"]\n')
    with pytest.raises(SuiteError, match="cannot choose a glTF file's camera"):
        load_suite(tmp_path / "s.toml")


def test_a_spot_wider_than_the_labs_cone_is_narrowed_with_a_note(tmp_path):
    """outerConeAngle = π/2 (a half space, glTF's widest) becomes the lab's widest cone, 179°,
    and the scene's notes say so: nothing is changed silently."""
    doc = _fixture_doc()
    lights = doc["extensions"]["KHR_lights_punctual"]["lights"]
    spot = next(i for i, l in enumerate(lights) if l["type"] == "spot")
    lights[spot]["spot"] = {"innerConeAngle": 0.2, "outerConeAngle": math.pi / 2}
    path = tmp_path / "wide.gltf"
    path.write_text(json.dumps(doc))
    scene = load_scene(path)
    wide = next(l for l in scene.lights if isinstance(l, SpotLight))
    assert wide.alpha == 179.0
    assert any("outer cone 180° wide, narrowed to 179°" in n for n in scene.notes)
