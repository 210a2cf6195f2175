"""The viewer's pure parts, without a window or GL: the fly camera's maths, the view state and its
key map, the script format, the saved view's scene file, the HUD drawing."""
from __future__ import annotations

import tomllib

import numpy as np
import pytest

from shadowlab.scene import load_scene
from shadowlab.scene.model import Camera
from shadowlab.util.validation import SceneError
from shadowlab.viewer import scene_file, state
from shadowlab.viewer.app import FrameTime, frame_time_summary, greyed, hud_picture
from shadowlab.viewer.script import parse_script
from shadowlab.viewer.state import FlyCamera, ViewState


def _camera():
    return Camera(np.array([2.9, 1.1, 0.3]), np.array([1.3, 0.1, -0.9]), np.array([0.0, 1.0, 0.0]), 45.0)


def test_an_unmoved_fly_camera_is_the_scene_camera_bit_for_bit():
    cam = _camera()
    out = FlyCamera.of(cam).camera()
    for key in ("eye", "target", "up"):
        assert np.array_equal(getattr(out, key), getattr(cam, key))
    assert (out.fov_y, out.near, out.far) == (45.0, None, None)


def test_moving_translates_eye_and_target_along_the_camera_axes():
    fly = FlyCamera.of(_camera())
    forward = (fly.target - fly.eye) / np.linalg.norm(fly.target - fly.eye)
    eye, target = fly.eye.copy(), fly.target.copy()
    fly.move(2.0, 0.0, 0.0)
    assert np.allclose(fly.eye - eye, 2.0 * forward) and np.allclose(fly.target - target, 2.0 * forward)
    fly.move(0.0, 0.0, -0.5)
    assert np.allclose(fly.eye - eye, 2.0 * forward + [0.0, -0.5, 0.0])
    before = fly.eye.copy()
    fly.move(0.0, 1.0, 0.0)
    right = fly.eye - before
    # right is horizontal (perpendicular to up) and perpendicular to the view direction, at unit length
    assert abs(np.linalg.norm(right) - 1.0) < 1e-12 and abs(right[1]) < 1e-12 and abs(np.dot(right, forward)) < 1e-12
    # forward x up points right (a right-handed camera)
    assert np.dot(right, np.cross(forward, [0.0, 1.0, 0.0])) > 0


def test_looking_turns_about_the_eye_and_keeps_the_distance():
    cam = Camera(np.zeros(3), np.array([0.0, 0.0, -4.0]), np.array([0.0, 1.0, 0.0]), 60.0)
    fly = FlyCamera.of(cam)
    fly.look(90.0, 0.0)  # turn right: from -z to +x
    assert np.allclose(fly.target, [4.0, 0.0, 0.0]) and np.array_equal(fly.eye, np.zeros(3))
    fly.look(0.0, 30.0)  # look up 30 degrees
    assert np.allclose(fly.target, 4.0 * np.array([np.cos(np.radians(30)), np.sin(np.radians(30)), 0.0]))
    fly.look(0.0, 500.0)  # clamped short of the up vector
    f = (fly.target - fly.eye) / 4.0
    assert np.isclose(np.degrees(np.arccos(f[1])), state.PITCH_MARGIN)
    assert np.isclose(np.linalg.norm(fly.target - fly.eye), 4.0)
    fly.look(0.0, -1000.0)
    f = (fly.target - fly.eye) / 4.0
    assert np.isclose(np.degrees(np.arccos(f[1])), 180.0 - state.PITCH_MARGIN)


def test_step_flies_with_held_keys_and_turns_with_the_drag():
    vs = ViewState(["a", "b"], _camera(), speed=3.0)
    fly0 = vs.fly.camera()
    assert not vs.step(0.5)  # nothing held: the clock runs, the camera stays
    assert vs.camera_version == 0 and vs.clock == 0.5
    assert vs.step(0.5, {"w"})
    forward = (fly0.target - fly0.eye) / np.linalg.norm(fly0.target - fly0.eye)
    assert np.allclose(vs.fly.eye - fly0.eye, 1.5 * forward)
    eye = vs.fly.eye.copy()
    assert not vs.step(0.5, {"w", "s"}) and np.array_equal(vs.fly.eye, eye)  # opposite keys cancel
    vs.step(0.1, {"w"}, fast=True)
    assert np.allclose(vs.fly.eye - eye, state.FAST * 0.3 * forward)
    version = vs.camera_version
    assert vs.step(0.0, drag=(10.0, 0.0))  # dragging right turns right
    assert vs.camera_version == version + 1
    new_forward = (vs.fly.target - vs.fly.eye) / np.linalg.norm(vs.fly.target - vs.fly.eye)
    assert np.dot(np.cross(forward, new_forward), [0.0, 1.0, 0.0]) < 0  # clockwise seen from above: to the right


def test_the_truth_is_due_after_the_camera_is_still_long_enough():
    vs = ViewState(["a"], _camera(), speed=1.0)
    vs.step(0.2, {"w"})
    assert not vs.truth_due()
    vs.step(0.2)
    assert not vs.truth_due()
    vs.step(state.STILL_SECONDS - 0.2)
    assert vs.truth_due()
    # a script's fixed step: the same number of frames always
    vs.step(state.SCRIPT_DT, {"w"})
    frames = 0
    while not vs.truth_due():
        vs.step(state.SCRIPT_DT)
        frames += 1
    assert frames == int(np.ceil(state.STILL_SECONDS / state.SCRIPT_DT - 1e-9))


def test_keys_switch_configurations_views_and_the_hud():
    vs = ViewState(["a", "b", "c"], _camera(), speed=1.0)
    assert vs.press("tab") == [] and vs.spec == "b"
    vs.press("tab"), vs.press("tab")
    assert vs.spec == "a"
    vs.press("shift+tab")
    assert vs.spec == "c"
    vs.press("2")
    assert vs.spec == "b"
    vs.press("9")  # no ninth configuration: nothing
    assert vs.spec == "b"
    seen = [vs.view]
    for _ in state.VIEWS:
        vs.press("v")
        seen.append(vs.view)
    assert seen == [*state.VIEWS, state.VIEWS[0]]
    vs.press("f3")
    assert vs.view == "error"
    vs.press("h")
    assert not vs.hud
    for key, effect in (("p", "screenshot"), ("x", "save_view"), ("r", "truth_now"), ("escape", "quit")):
        assert vs.press(key) == [effect]
    assert vs.press("j") == []  # unbound


def test_reset_returns_to_the_scene_camera():
    vs = ViewState(["a"], _camera(), speed=1.0)
    vs.step(1.0, {"d"}, drag=(5.0, 5.0))
    vs.press("backspace")
    assert np.array_equal(vs.fly.eye, _camera().eye) and np.array_equal(vs.fly.target, _camera().target)


def test_every_bound_action_is_explained():
    actions = {("config_n" if a.startswith("config_") else a) for a in state.KEYMAP.values()}
    assert actions == set(state.ACTION_HELP)
    assert not set(state.MOVE_KEYS) & set(state.KEYMAP)
    assert {f"view_{v}" for v in state.VIEWS} <= set(state.KEYMAP.values())


def test_a_script_runs_in_frames():
    script = parse_script({"step": [
        {"key": "tab"}, {"frame": 3, "hold": "shift+w", "frames": 4}, {"drag": [8, -4], "frames": 2},
        {"screenshot": "a.png"}, {"wait_truth": True}, {"save_view": "v.toml"}, {"quit": True}]}, "s.toml")
    assert [(s.kind, s.frame, s.frames) for s in script.steps] == [
        ("key", 0, 1), ("hold", 3, 4), ("drag", 7, 2), ("screenshot", 9, 1), ("wait_truth", 10, 1),
        ("save_view", 11, 1), ("quit", 12, 1)]
    assert [s.kind for s in script.instants(0)] == ["key"]
    assert script.instants(5) == []
    assert script.held(2) == (set(), False) and script.held(3) == ({"w"}, True) and script.held(7) == (set(), False)
    assert script.drag(7) == (4.0, -2.0) and script.drag(8) == (4.0, -2.0) and script.drag(9) == (0.0, 0.0)
    assert [s.kind for s in script.instants(11)] == ["screenshot", "wait_truth", "save_view"]
    assert not script.done and [s.kind for s in script.instants(12)] == ["quit"] and script.done


@pytest.mark.parametrize("steps, culprit", [
    ([], "step"),
    ([{"key": "tab", "quit": True}], "step[0].quit"),
    ([{"frames": 2}], "step[0].key"),
    ([{"key": "tabb"}], "did you mean 'tab'"),
    ([{"hold": "tab"}], "step[0].hold"),
    ([{"drag": [1, 2, 3]}], "step[0].drag"),
    ([{"key": "tab", "frame": 5}, {"key": "v", "frame": 2}], "step[1].frame"),
    ([{"quit": False}], "step[0].quit"),
    ([{"key": "tab", "colour": 1}], "step[0].colour"),
    ([{"screenshot": ""}], "step[0].screenshot"),
])
def test_bad_scripts_are_one_line_errors(steps, culprit):
    with pytest.raises(SceneError) as err:
        parse_script({"step": steps}, "s.toml")
    assert culprit in str(err.value) and "\n" not in str(err.value)


def test_toml_text_round_trips():
    data = {"name": "x", "n": 3, "flag": True, "f": 0.1, "big": 1e300, "tiny": -2.5e-7, "whole": 2.0,
            "v": [0.1, 0.2, 1.0], "s": 'quote " and \\', "weird key": 1,
            "camera": {"eye": [1.0, 2.0, 3.0]},
            "objects": [{"mesh": "box", "material": {"diffuse": [0.1, 0.2, 0.3]}}, {"mesh": "plane"}],
            "animation": {"frames": 3, "camera": [{"t": 0.0, "eye": [0.0, 1.0, 2.0]}]}}
    assert tomllib.loads(scene_file.toml_text(data)) == data


def test_a_saved_view_is_the_scene_from_the_new_camera(tmp_path):
    """The city scene (mesh files beside the shipped scene): a copy with the camera replaced, bit for
    bit, whose meshes resolve from another folder; everything else as the scene file says."""
    scene = load_scene("city_sf_sun")
    fly = FlyCamera.of(scene.camera)
    fly.move(12.345678901234567, -3.0, 1.0 / 3.0)
    fly.look(17.0, -4.0)
    out = tmp_path / "deep" / "saved.toml"
    scene_file.save_view(scene, fly.camera(), out)
    again = load_scene(out)
    assert np.array_equal(again.camera.eye, fly.eye) and np.array_equal(again.camera.target, fly.target)
    assert again.camera.near is None and again.camera.far is None and again.camera.fov_y == scene.camera.fov_y
    assert again.name == "saved" and again.family == scene.family
    assert [o.name for o in again.objects] == [o.name for o in scene.objects]
    assert all(np.array_equal(a.vertices, b.vertices) for a, b in zip(again.objects, scene.objects))
    assert [l.describe() for l in again.lights] == [l.describe() for l in scene.lights]
    text = out.read_text()
    assert text.startswith("# The view of city_sf_sun.toml saved by `shadowlab view`")
    assert "# City scale, real data" in text  # the scene's purpose stays
    # a mesh path relative to the new folder, not absolute
    mesh = tomllib.loads(text)["objects"][0]["mesh"]
    assert not mesh.startswith("/") and mesh.endswith("meshes/city_sf_terrain.ply.gz")


def test_a_gltf_view_saves_as_an_include_with_its_camera(tmp_path):
    """A view of a .glb scene is saved as ``[gltf] file`` (relative to the new file) plus the
    viewer's ``[camera]``; read back, it is the same scene — objects and lights (the automatic
    exposure does not depend on the camera) — seen from that camera, bit for bit."""
    from shadowlab.scene import builtin_scene_dir

    glb = builtin_scene_dir() / "gltf" / "blender_cube.glb"
    scene = load_scene(f"{glb}#TopCamera")
    moved = Camera(scene.camera.eye + np.array([0.25, -0.5, 1.0]), scene.camera.target, scene.camera.up, 37.5)
    out = scene_file.save_view(scene, moved, tmp_path / "views" / "v.toml")
    data = tomllib.loads(out.read_text())
    assert not data["gltf"]["file"].startswith("/") and data["gltf"]["file"].endswith("gltf/blender_cube.glb")
    again = load_scene(out)
    assert np.array_equal(again.camera.eye, moved.eye) and again.camera.fov_y == 37.5
    assert [l.describe() for l in again.lights] == [l.describe() for l in scene.lights]
    assert all(np.array_equal(a.vertices, b.vertices) for a, b in zip(again.objects, scene.objects))
    text = scene_file.gltf_view_text(tmp_path / "assets" / "model.glb", _camera(), tmp_path / "views" / "v.toml")
    data = tomllib.loads(text)
    assert data["gltf"] == {"file": "../assets/model.glb"}
    assert data["camera"]["eye"] == [2.9, 1.1, 0.3] and "near" not in data["camera"]


def test_hud_and_greyed_pictures():
    picture = np.full((60, 200, 3), 200, np.uint8)
    with_hud = hud_picture(picture, ["shadow_map", "view: shaded"])
    assert with_hud.shape == picture.shape and with_hud.dtype == np.uint8
    assert (with_hud[:20, :60] != 200).any() and (with_hud[40:, :] == 200).all()  # a band at the top only
    assert hud_picture(picture, []) is picture
    grey = greyed(np.dstack([np.ones((2, 2)), np.zeros((2, 2)), np.zeros((2, 2))]))
    assert np.allclose(grey, 0.25 + 0.4 / 3)


def test_frame_time_summary_counts_only_frames_with_the_camera_moving():
    rows = [FrameTime(0, "a", "shaded", False, 0.0, 5.0, 10.0, 100.0),
            FrameTime(1, "a", "shaded", True, 1.0, 4.0, 8.0, 20.0),
            FrameTime(2, "a", "shaded", True, 1.0, 6.0, 8.0, 30.0),
            FrameTime(3, "b", "shaded", False, 0.0, None, 0.0, 1.0)]
    assert frame_time_summary(rows) == [
        "a: 25.0 ms per frame with the camera moving (40.0 frames/s, technique render 5.0 ms; median of 2 frames)"]
