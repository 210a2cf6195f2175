"""Animated scenes: the [animation] table's parsing, keyframe interpolation, scene_at, and the
`shadowlab animate` command end to end."""
from __future__ import annotations

import json
import textwrap

import numpy as np
import pandas as pd
import pytest

from shadowlab.scene.animation import frame_times, parse_animation, scene_at, slerp
from shadowlab.cli import main
from shadowlab.scene import load_scene
from shadowlab.util.validation import SceneError

BASE = textwrap.dedent("""
    name = "anim"
    [camera]
    eye = [0.0, 3.0, 6.0]
    target = [0.0, 0.0, 0.0]
    [[lights]]
    type = "directional"
    direction = [-0.3, -1.0, -0.2]
    [[lights]]
    type = "point"
    position = [1.0, 4.0, 1.0]
    [[objects]]
    mesh = "plane"
    size = [8.0, 8.0]
    [[objects]]
    mesh = "box"
    translate = [0.0, 0.5, 0.0]
""")

GOOD_ANIM = textwrap.dedent("""
    [animation]
    frames = 5
    [[animation.camera]]
    t = 0.0
    eye = [0.0, 3.0, 6.0]
    target = [0.0, 0.0, 0.0]
    fov_y = 40.0
    [[animation.camera]]
    t = 0.25
    eye = [2.0, 3.0, 6.0]
    target = [0.0, 0.0, 0.0]
    fov_y = 50.0
    [[animation.camera]]
    t = 1.0
    eye = [4.0, 3.0, 2.0]
    target = [0.0, 1.0, 0.0]
    fov_y = 50.0
    [[animation.lights]]
    light = 0
    t = 0.0
    direction = [0.0, -1.0, 0.0]
    [[animation.lights]]
    light = 0
    t = 1.0
    direction = [1.0, 0.0, 0.0]
    [[animation.lights]]
    light = 1
    t = 0.0
    position = [1.0, 4.0, 1.0]
    [[animation.lights]]
    light = 1
    t = 1.0
    position = [-1.0, 6.0, 1.0]
""")


def write(tmp_path, text, name="anim.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_good_keyframes_parse_and_interpolate(tmp_path):
    s = load_scene(write(tmp_path, BASE + GOOD_ANIM))
    a = s.animation
    assert a.frames == 5 and a.camera_moves and [k.t for k in a.camera] == [0.0, 0.25, 1.0]
    assert sorted(a.lights) == [0, 1]
    # halfway through the first camera segment
    s1 = scene_at(s, 0.125)
    assert np.allclose(s1.camera.eye, [1.0, 3.0, 6.0]) and s1.camera.fov_y == pytest.approx(45.0)
    # t = 0.25 + 0.75/2: halfway through the second
    s2 = scene_at(s, 0.625)
    assert np.allclose(s2.camera.eye, [3.0, 3.0, 4.0]) and np.allclose(s2.camera.target, [0.0, 0.5, 0.0])
    # the sun turns 90 degrees at a constant rate: at t = 1/3 it is 30 degrees from straight down
    d = scene_at(s, 1.0 / 3.0).lights[0].direction
    assert np.degrees(np.arccos(-d[1])) == pytest.approx(30.0, abs=1e-9) and d[2] == pytest.approx(0.0, abs=1e-15)
    assert np.allclose(scene_at(s, 0.5).lights[1].position, [0.0, 5.0, 1.0])
    # objects shared, the still scene untouched
    assert all(a is b for a, b in zip(s1.objects, s.objects)) and np.array_equal(s.lights[0].direction, load_scene(
        write(tmp_path, BASE, "still.toml")).lights[0].direction)
    assert s.animation is not None and load_scene(write(tmp_path, BASE, "still.toml")).animation is None


def test_endpoints_are_exact_and_slerp_stays_unit(tmp_path):
    s = load_scene(write(tmp_path, BASE + GOOD_ANIM))
    a = s.animation
    for t, cam_key, light_key in ((0.0, a.camera[0], a.lights[0][0]), (1.0, a.camera[-1], a.lights[0][-1])):
        st = scene_at(s, t)
        assert np.array_equal(st.camera.eye, cam_key.eye) and np.array_equal(st.camera.target, cam_key.target)
        assert np.array_equal(st.lights[0].direction, light_key.direction)
    # a keyframe inside the path is hit exactly too
    assert np.array_equal(scene_at(s, 0.25).camera.eye, a.camera[1].eye)
    rng = np.random.default_rng(1)
    worst = 0.0
    for _ in range(200):
        u, v = rng.normal(size=(2, 3))
        u, v = u / np.linalg.norm(u), v / np.linalg.norm(v)
        for sval in rng.random(5):
            worst = max(worst, abs(np.linalg.norm(slerp(u, v, float(sval))) - 1.0))
        assert np.array_equal(slerp(u, v, 0.0), u) and np.array_equal(slerp(u, v, 1.0), v)
    assert worst < 1e-15  # measured 2.2e-16 (one ulp)
    # nearly equal directions (normalised lerp branch) stay unit and between the two
    u = np.array([0.0, -1.0, 0.0])
    v = np.array([1e-9, -1.0, 0.0]) / np.linalg.norm([1e-9, -1.0, 0.0])
    w = slerp(u, v, 0.5)
    assert abs(np.linalg.norm(w) - 1) < 1e-15 and 0 < w[0] < 1e-9


def test_frame_times():
    t = frame_times(5)
    assert t.tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert frame_times(24)[-1] == 1.0 and frame_times(24)[0] == 0.0
    with pytest.raises(ValueError, match="at least 2"):
        frame_times(1)


def test_scene_at_rejects_times_outside_the_animation(tmp_path):
    s = load_scene(write(tmp_path, BASE + GOOD_ANIM))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        scene_at(s, 1.5)


def _light_keys(light, *keys):
    return "".join(f"[[animation.lights]]\nlight = {light}\n{k}\n" for k in keys)


CAM2 = ("[[animation.camera]]\nt = 0.0\neye = [0.0, 3.0, 6.0]\ntarget = [0.0, 0.0, 0.0]\n"
        "[[animation.camera]]\nt = 1.0\neye = [1.0, 3.0, 6.0]\ntarget = [0.0, 0.0, 0.0]\n")


@pytest.mark.parametrize("anim, key, reason", [
    ("[animation]\n" + CAM2, "animation.frames", "required"),
    ("[animation]\nframes = 1\n" + CAM2, "animation.frames", ">= 2"),
    ("[animation]\nframes = 2.5\n" + CAM2, "animation.frames", "integer"),
    ("[animation]\nframes = 4\nspeed = 2\n" + CAM2, "animation.speed", "unknown key"),
    ("[animation]\nframes = 4\n", "animation.camera", "needs camera keyframes"),
    ("[animation]\nframes = 4\n[[animation.camera]]\nt = 0.0\neye = [0.0, 3.0, 6.0]\ntarget = [0.0, 0.0, 0.0]\n",
     "animation.camera", "at least 2 keyframes"),
    ("[animation]\nframes = 4\n" + CAM2.replace("t = 0.0", "t = 0.1"), "animation.camera.t", "first keyframe"),
    ("[animation]\nframes = 4\n" + CAM2.replace("t = 1.0", "t = 0.9"), "animation.camera.t", "last keyframe"),
    ("[animation]\nframes = 4\n" + CAM2.replace("t = 1.0", "t = 1.5"), "animation.camera[1].t", "<= 1"),
    ("[animation]\nframes = 4\n" + CAM2 + "[[animation.camera]]\nt = 1.0\neye = [2.0, 3.0, 6.0]\ntarget = [0.0, 0.0, 0.0]\n",
     "animation.camera.t", "increase strictly"),
    ("[animation]\nframes = 4\n" + CAM2.replace("eye = [1.0, 3.0, 6.0]", "eye = [0.0, 0.0, 0.0]"),
     "animation.camera[1].target", "differ from eye"),
    ("[animation]\nframes = 4\n" + CAM2.replace("target = [0.0, 0.0, 0.0]\n[[", "target = [0.0, 0.0, 0.0]\n"
                                                "fov_y = 40.0\n[[", 1), "animation.camera.fov_y", "every camera"),
    ("[animation]\nframes = 4\n" + CAM2.replace("eye = [1.0, 3.0, 6.0]", "eye = [1.0, 3.0]"),
     "animation.camera[1].eye", "list of 3"),
    ("[animation]\nframes = 4\n" + CAM2.replace("t = 1.0\n", "t = 1.0\nup = [0.0, 1.0, 0.0]\n"),
     "animation.camera[1].up", "unknown key"),
    ("[animation]\nframes = 4\n" + _light_keys(5, "t = 0.0\ndirection = [0.0, -1.0, 0.0]",
                                               "t = 1.0\ndirection = [0.1, -1.0, 0.0]"),
     "animation.lights[0].light", "no light 5"),
    ("[animation]\nframes = 4\n" + _light_keys(1, "t = 0.0\ndirection = [0.0, -1.0, 0.0]",
                                               "t = 1.0\ndirection = [0.1, -1.0, 0.0]"),
     "animation.lights[0].direction", "point) has no direction"),
    ("[animation]\nframes = 4\n" + _light_keys(0, "t = 0.0\nposition = [0.0, 1.0, 0.0]",
                                               "t = 1.0\nposition = [0.1, 1.0, 0.0]"),
     "animation.lights[0].position", "directional) has no position"),
    ("[animation]\nframes = 4\n" + _light_keys(0, "t = 0.0", "t = 1.0\ndirection = [0.1, -1.0, 0.0]"),
     "animation.lights[0].direction", "needs a direction and/or a position"),
    ("[animation]\nframes = 4\n" + _light_keys(0, "t = 0.0\ndirection = [0.0, 0.0, 0.0]",
                                               "t = 1.0\ndirection = [0.1, -1.0, 0.0]"),
     "animation.lights[0].direction", "zero vector"),
    ("[animation]\nframes = 4\n" + _light_keys(0, "t = 0.0\ndirection = [0.0, -1.0, 0.0]",
                                               "t = 1.0\ndirection = [0.0, 2.0, 0.0]"),
     "animation.lights (light 0).direction", "opposite"),
    ("[animation]\nframes = 4\n" + _light_keys(0, "t = 0.0\ndirection = [0.0, -1.0, 0.0]"),
     "animation.lights (light 0)", "at least 2 keyframes"),
    ("[animation]\nframes = 4\n" + _light_keys(1, "t = 0.0\nposition = [0.0, 4.0, 0.0]",
                                               "t = 0.0\nposition = [0.0, 5.0, 0.0]", "t = 1.0\nposition = [0.0, 5.0, 0.0]"),
     "animation.lights (light 1).t", "increase strictly"),
    ("[animation]\nframes = 4\n" + _light_keys(0, "t = 0.0\ndirection = [0.0, -1.0, 0.0]\ncolor = [1.0, 0.0, 0.0]",
                                               "t = 1.0\ndirection = [0.1, -1.0, 0.0]"),
     "animation.lights[0].color", "unknown key"),
    ("[animation]\nframes = 4\n" + _light_keys(0, "t = 0.0\ndirection = [0.0, -1.0, 0.0]",
                                               "t = 1.0\ndirection = [0.1, -1.0, nan]"),
     "animation.lights[1].direction", "finite"),
    ('[animation]\nframes = 4\ncamera = "dolly"\n', "animation.camera", "array of tables"),
])
def test_bad_animation_is_rejected_naming_the_key(tmp_path, anim, key, reason):
    path = write(tmp_path, BASE + anim)
    with pytest.raises(SceneError) as exc:
        load_scene(path)
    assert exc.value.key == key, str(exc.value)
    assert reason in exc.value.reason, str(exc.value)
    assert str(path) in str(exc.value)


def test_parse_animation_without_lights_skips_the_light_checks():
    """parse_animation on its own (no scene lights): indices and light types are not checked."""
    a = parse_animation({"frames": 3, "lights": [{"light": 7, "t": 0.0, "position": [0.0, 1.0, 0.0]},
                                                 {"light": 7, "t": 1.0, "position": [0.0, 2.0, 0.0]}]}, "f.toml")
    assert list(a.lights) == [7] and not a.camera_moves


def test_shipped_animated_scenes_load():
    sun = load_scene("tm_rotating_sun")
    assert sun.animation.frames == 24 and not sun.animation.camera_moves
    d0, d1 = (scene_at(sun, t).lights[0].direction for t in (0.0, 1.0))
    assert 2.0 < np.degrees(np.arccos(d0 @ d1)) < 6.0  # "a few degrees": 4.1
    dolly = load_scene("tm_camera_dolly")
    assert dolly.animation.camera_moves and not dolly.animation.lights
    assert np.linalg.norm(scene_at(dolly, 1.0).camera.eye - scene_at(dolly, 0.0).camera.eye) == pytest.approx(20.0)


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_animate_end_to_end_writes_every_file(tmp_path, capsys):
    out = tmp_path / "anim"
    code = main(["animate", "tm_rotating_sun", "-t", "shadow_map:resolution=128", "-t", "shadow_volume",
                 "--frames", "3", "--size", "64x48", "--out", str(out)])
    assert code == 0
    printed = capsys.readouterr().out
    assert "report.html" in printed and "flip_rate_mean" in printed
    for name in ("frames.csv", "summary.csv", "report.html", "animation.json",
                 "flicker_shadow_map_resolution_128.png", "flicker_shadow_volume.png",
                 "strip_shadow_map_resolution_128.gif", "strip_shadow_volume.gif"):
        assert (out / name).stat().st_size > 0, name
    df = pd.read_csv(out / "frames.csv")
    assert len(df) == 3 * 3 and list(df.columns[:2]) == ["frame", "t"]
    assert sorted(set(df["t"])) == [0.0, 0.5, 1.0]
    assert df.loc[df["frame"] == 0, "flip_rate"].isna().all()
    later = df[df["frame"] > 0]
    assert later[["flip_rate", "temporal_error", "valid_pixels"]].notna().all().all()
    assert (later.loc[later["reference"], ["flip_rate", "temporal_error"]] == 0).all().all()
    summary = pd.read_csv(out / "summary.csv")
    assert len(summary) == 3
    for col in ("error_rate_mean", "flip_rate_mean", "flip_rate_p95", "flip_rate_max", "temporal_error_mean",
                "temporal_error_max"):
        assert col in summary.columns
    row = summary[summary["short_label"] == "shadow_map:resolution=128"].iloc[0]
    flips = later.loc[later["short_label"] == "shadow_map:resolution=128", "flip_rate"]
    assert row["flip_rate_mean"] == pytest.approx(flips.mean()) and row["flip_rate_max"] == pytest.approx(flips.max())
    rec = json.loads((out / "animation.json").read_text())
    assert rec["frames"] == 3 and rec["times"] == [0.0, 0.5, 1.0] and rec["animation"]["lights"]["0"]
    for key in ("revision", "versions", "renderer", "date", "command"):
        assert rec[key]
    from PIL import Image

    gif = Image.open(out / "strip_shadow_map_resolution_128.gif")
    assert gif.n_frames == 3 and gif.size == (3 * 64 + 2 * 2, 48)
    html = (out / "report.html").read_text()
    assert "<table" in html and "strip_shadow_volume.gif" in html and "flicker_shadow_volume.png" in html
    # summary.csv: the columns users' scripts read, in their order, then the added time column
    assert list(summary.columns[:12]) == SUMMARY_COLUMNS_V1 and "time_ms_median" in summary.columns
    assert (summary["time_ms_median"] > 0).all()
    _check_summary_table(html, summary)
    _check_flicker_png(out / "flicker_shadow_map_resolution_128.png")


#: summary.csv's columns before the time column was added (a contract: only ever add).
SUMMARY_COLUMNS_V1 = ["label", "short_label", "technique", "reference", "light", "frames", "error_rate_mean",
                      "flip_rate_mean", "flip_rate_p95", "flip_rate_max", "temporal_error_mean", "temporal_error_max"]
#: Largest share of near-black pixels the flicker PNG may have among its non-white ones: the old
#: heat map was black on every covered pixel that did not flicker (most of the picture).
FLICKER_MAX_BLACK_SHARE = 0.05
#: Smallest mean brightness of the flicker PNG's picture pixels (not the figure's white, not
#: the slate background): the grey scene underneath is at least FLICKER_UNDERLAY_GREY's low end.
FLICKER_MIN_MEAN = 0.3


def _summary_rows(html: str) -> list[list[str]]:
    """The cells of the page's summary table, row by row (header left out)."""
    import re

    table = re.search(r'<table class="animate-summary">(.*?)</table>', html, re.S).group(1)
    return [re.findall(r"<td[^>]*>(.*?)</td>", row, re.S) for row in re.findall(r"<tr[^>]*>(.*?)</tr>", table, re.S)
            if "<td" in row]


def _check_summary_table(html: str, summary: pd.DataFrame) -> None:
    """The page's summary: the short label first (the full spec only as its tooltip), rates in
    percent (two decimals, more for a small nonzero rate), the temporal error with 4 decimals
    (more when small and nonzero) and a time column."""
    import html as html_lib
    import re

    rows = _summary_rows(html)
    assert len(rows) == len(summary)
    header = re.search(r'<table class="animate-summary">\s*<tr>(.*?)</tr>', html, re.S).group(1)
    assert "time ms" in header and header.index("configuration") < header.index("light")
    for cells, (_, r) in zip(rows, summary.iterrows()):
        first = re.sub(r"<[^>]+>.*?</[^>]+>", "", cells[0]).strip()
        assert first == r["short_label"], cells[0]
        assert r["label"] not in html_lib.unescape(first)
        assert f'title="{html_lib.escape(r["label"])}"' in html
        rates = [c for c in cells if re.fullmatch(r"\d+\.\d+ %", c)]
        assert len(rates) == 4, cells  # error rate, flip rate mean / p95 / max
        assert sum(bool(re.fullmatch(r"\d\.\d{4,}", c)) for c in cells) == 2, cells  # temporal error mean / max
        for c in cells:
            if re.fullmatch(r"[\d.]+ %", c) and float(c[:-2]) == 0:
                assert c == "0.00 %", cells  # zero only when exactly zero
        assert re.fullmatch(r"\d+(\.\d+)?", cells[-1]) and float(cells[-1]) > 0, cells  # time, ms


def _check_flicker_png(path) -> None:
    """The flicker picture shows the scene: few near-black pixels and a bright enough mean over
    the picture's pixels (the figure's white and the slate background left out)."""
    from PIL import Image

    from shadowlab.output import pictures

    rgb = np.asarray(Image.open(path).convert("RGB")).reshape(-1, 3) / 255.0
    ink = rgb[(rgb < 0.95).any(axis=1)]
    black = (ink.max(axis=1) < 0.1).mean()
    assert black < FLICKER_MAX_BLACK_SHARE, black
    scene = ink[np.abs(ink - pictures.BACKGROUND).max(axis=1) > 0.02]
    assert scene.mean() > FLICKER_MIN_MEAN, scene.mean()


def test_gif_frames_are_labelled(tmp_path, monkeypatch):
    """The GIF's first frame differs from the same run's frame without labels (the renders are
    deterministic), and only in the label corners."""
    import shadowlab.commands.animate as anim
    from PIL import Image

    from shadowlab.output import animation_pictures

    args = dict(frames=2, size=(64, 48))
    spec = ["shadow_map:resolution=128"]
    labelled = anim.animate("tm_rotating_sun", spec, out=tmp_path / "a", **args)
    monkeypatch.setattr(animation_pictures, "label_strip", lambda strip, k, n: strip)
    plain = anim.animate("tm_rotating_sun", spec, out=tmp_path / "b", **args)
    a, b = (np.asarray(Image.open(d / "strip_shadow_map_resolution_128.gif").convert("RGB"))
            for d in (labelled, plain))
    diff = (a != b).any(axis=2)
    assert diff.sum() > 50, diff.sum()
    h = a.shape[0]
    assert not diff[h // 3:2 * h // 3].any()  # the labels sit at the top and the bottom


@pytest.mark.slow  # a sweep: every registered technique animated over three frames, with its report
def test_still_frames_flip_nothing(tmp_path):
    """--frames on a scene without [animation]: identical frames, so flip_rate and
    temporal_error are exactly 0 for every registered technique (the renders are deterministic;
    those that render for area lights only — pcss, moment_soft, penumbra_wedges, exact_soft,
    rt_soft — are left out, and the truth is always there)."""
    from shadowlab.techniques import REGISTRY

    names = [n for n, cls in REGISTRY.items() if n != "raytrace" and cls.supports_type("directional")]
    specs = [f"{n}:resolution=64" if n == "shadow_map" else n for n in names]
    out = tmp_path / "still"
    args = ["animate", "sun_scene", "--frames", "3", "--size", "64x48", "--out", str(out)]
    assert main(args + [x for s in specs for x in ("-t", s)]) == 0
    df = pd.read_csv(out / "frames.csv")
    later = df[df["frame"] > 0]
    assert len(later) == 2 * (1 + len(specs)) and set(later["technique"]) == set(names) | {"raytrace"}
    assert (later["flip_rate"] == 0).all() and (later["temporal_error"] == 0).all()
    assert (later["valid_pixels"] == later["evaluated_pixels"]).all()
    # the low-resolution map does get pixels wrong, so 0 flips is stability, not emptiness
    assert (df.loc[df["short_label"] == "shadow_map:resolution=64", "error_rate"] > 0).all()


def test_animate_bad_input(tmp_path, capsys):
    # no [animation] and no --frames
    assert main(["animate", "box_on_plane", "--size", "64x48", "--out", str(tmp_path / "a")]) == 2
    assert "no [animation]" in capsys.readouterr().err
    assert main(["animate", "tm_rotating_sun", "--frames", "1", "--size", "64x48", "--out", str(tmp_path / "b")]) == 2
    assert "--frames must be >= 2" in capsys.readouterr().err
    assert main(["animate", "tm_rotating_sun", "-t", "nonsense", "--out", str(tmp_path / "c")]) == 2
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists() and not (tmp_path / "c").exists()


@pytest.mark.parametrize("scene,spec,need", [
    ("multi_light", "cascaded_map", "a directional light"),   # multi_light: three lights of different types
    ("multi_light", "lispsm", "a directional light"),
    ("tm_rotating_sun", "pcss", "an area light"),
])
def test_animate_rejects_a_technique_the_lights_cannot_take(tmp_path, capsys, monkeypatch, scene, spec, need):
    """A technique that cannot run on one of the scene's lights is a clear error (exit 2) before
    any GL work: no frame is built."""
    import shadowlab.commands.animate as anim

    def no_frame(*a, **k):
        raise AssertionError("a frame was built")

    monkeypatch.setattr(anim, "Frame", no_frame)
    assert main(["animate", scene, "-t", spec, "--frames", "2", "--size", "32x24", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert f"needs {need}" in err and "does not render for light 0" in err, err
    assert not (tmp_path / "x").exists()


def test_failed_animate_leaves_earlier_results(tmp_path, monkeypatch):
    out = tmp_path / "keep"
    out.mkdir()
    (out / "frames.csv").write_text("old")
    import shadowlab.commands.animate as anim
    from shadowlab.output import animation_pictures

    def boom(*a, **k):
        raise RuntimeError("disk full")

    monkeypatch.setattr(animation_pictures, "write_gif", boom)
    with pytest.raises(RuntimeError, match="disk full"):
        anim.animate("tm_rotating_sun", ["shadow_map:resolution=64"], frames=2, size=(32, 24), out=out)
    assert (out / "frames.csv").read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["keep"]


def test_objects_move_along_their_keyframes(tmp_path):
    """[[animation.objects]]: a rigid offset, interpolated linearly; other objects are shared;
    an unknown object name is an error naming the key, with a hint."""
    import numpy as np

    from shadowlab.scene import load_scene, parse_scene
    from shadowlab.scene.animation import scene_at
    from shadowlab.util.validation import SceneError

    scene = load_scene("tm_moving_caster")
    crate = [o.name for o in scene.objects].index("crate")
    half = scene_at(scene, 0.5)
    np.testing.assert_allclose(half.objects[crate].vertices, scene.objects[crate].vertices + [3.0, 0.0, 0.0])
    assert all(half.objects[i] is o for i, o in enumerate(scene.objects) if i != crate)
    assert scene_at(scene, 0.0).objects[crate].vertices.tolist() == scene.objects[crate].vertices.tolist()
    import tomllib

    data = tomllib.loads(scene.path.read_text())
    data["animation"]["objects"][0]["object"] = "crat"
    with pytest.raises(SceneError, match=r"animation\.objects\[0\]\.object.*did you mean 'crate'"):
        parse_scene(data, "moving.toml")
    data["animation"]["objects"][0]["object"] = "crate"
    data["objects"].append({**data["objects"][1], "name": "crate"})  # two objects named crate
    with pytest.raises(SceneError, match=r"animation\.objects\[0\]\.object.*2 objects are named 'crate'"):
        parse_scene(data, "moving.toml")
