"""Lights: the numpy and GLSL definitions agree; footprints follow docs/architecture.md#the-shading-pass-shadowlabgpushadingpy."""
from __future__ import annotations

import json
import re

import numpy as np
import pytest
import trimesh

from shadowlab.gpu import glsl, programs, targets
from shadowlab.geometry.frusta import Casters
from shadowlab.scene.area_lights import AREA_SHAPES, DiscLight, RectLight, SphereLight
from shadowlab.scene import parse_light
from shadowlab.scene.lights import LIGHT_TYPE_IDS, DirectionalLight, PointLight, SpotLight, TargetDirectLight
from shadowlab.util.validation import SceneError

LIGHTS = [
    PointLight(position=np.array([0.5, 4.0, -1.0])),
    DirectionalLight(direction=np.array([-0.3, -1.0, 0.2]) / np.linalg.norm([-0.3, -1.0, 0.2])),
    SpotLight(position=np.array([0.0, 3.0, 0.0]), direction=np.array([0.0, -1.0, 0.0]), alpha=70.0, beta=40.0),
    SpotLight(position=np.array([1.0, 3.0, 0.0]), direction=np.array([0.0, -1.0, 0.0]), alpha=50.0, beta=50.0),
    TargetDirectLight(position=np.array([0.0, 3.0, 0.0]), direction=np.array([0.0, -1.0, 0.0]), R=2.0, r=1.0),
    # area lights: lit (footprint, direction) as a point light at the centre (docs/metrics.md)
    RectLight(position=np.array([0.3, 3.5, -0.2]), u=np.array([1.5, 0.0, 0.0]), v=np.array([0.0, 0.0, 1.0])),
    DiscLight(position=np.array([-0.5, 3.2, 0.4]), direction=np.array([0.0, -1.0, 0.0]), radius=0.6),
    SphereLight(position=np.array([0.2, 3.4, 0.1]), radius=0.3),
    # lights with a range: λ = shape factor × the windowed 1/d² falloff (issue 40)
    PointLight(position=np.array([0.5, 2.0, -1.0]), range=3.0),
    SpotLight(position=np.array([0.0, 3.0, 0.5]), direction=np.array([0.0, -1.0, 0.0]), alpha=80.0, beta=50.0,
              range=4.5),
    # glTF's lights (issue 41): inverse square without a range; KHR's squared cone ramp
    PointLight(position=np.array([0.5, 2.0, -1.0]), inverse_square=True),
    SpotLight(position=np.array([0.0, 3.0, 0.5]), direction=np.array([0.0, -1.0, 0.0]), alpha=80.0, beta=30.0,
              inverse_square=True, cone_falloff="squared"),
    SpotLight(position=np.array([0.0, 3.0, 0.5]), direction=np.array([0.2, -1.0, 0.0]) / np.linalg.norm([0.2, -1, 0]),
              alpha=70.0, beta=20.0, cone_falloff="squared", range=5.0),
]


def light_id(light) -> str:
    """A test id: the area shape, else the type, with ``_ranged`` for a light with a range."""
    return (getattr(light, "shape", light.type_name) + ("_ranged" if getattr(light, "range", 0) > 0 else "")
            + ("_inverse_square" if getattr(light, "inverse_square", False) else "")
            + ("_squared_cone" if getattr(light, "cone_falloff", "linear") == "squared" else ""))


def glsl_eval(ctx, light, points):
    prog = programs.program("light_probe.glsl", varyings=("out_footprint", "out_dir"))
    programs.set_uniforms(prog, light.uniforms())
    vbo = ctx.buffer(points.astype("f4").tobytes())
    out = ctx.buffer(reserve=len(points) * 16)
    vao = ctx.vertex_array(prog, [(vbo, "3f", "in_pos")])
    targets.park()  # EGL standalone contexts have no default framebuffer
    vao.transform(out, vertices=len(points))
    res = np.frombuffer(out.read(), "f4").reshape(-1, 4)
    for obj in (vao, vbo, out):  # prog: programs.program's cache keeps it
        obj.release()
    return res[:, 0], res[:, 1:]


def footprints_agree(lam_gl, lam_np) -> np.ndarray:
    """Bool per point: GLSL's float32 λ matches numpy's float64 λ to float32 precision — within
    1e-4, relative where λ > 1 (a ranged light's 1/d² near the light)."""
    return np.abs(lam_gl - lam_np) < 1e-4 * np.maximum(1.0, lam_np)


@pytest.mark.parametrize("light", LIGHTS, ids=light_id)
def test_glsl_and_numpy_agree(ctx, light, rng):
    pts = rng.uniform([-4, -1, -4], [4, 2.9, 4], size=(20000, 3))
    lam_gl, dir_gl = glsl_eval(ctx, light, pts)
    lam_np = light.footprint(pts)
    dir_np, _ = light.to_light(pts)
    # float32 GLSL vs float64 numpy: the ramp agrees to float32 precision; a point exactly on a
    # step edge may differ, so allow a handful of pixels of disagreement there only.
    close = footprints_agree(lam_gl, lam_np)
    assert close.mean() > 0.9995, np.abs(lam_gl - lam_np).max()
    assert np.allclose(dir_gl, dir_np, atol=1e-5)
    if getattr(light, "range", 0) > 0:  # the range bites: both zero beyond it, both positive well inside
        d = np.linalg.norm(pts - light.position, axis=1)
        assert (lam_gl[d >= light.range] == 0).all() and (lam_np[d >= light.range] == 0).all()
        assert 0.05 < (lam_np > 0).mean() < 0.95
        shape = light._shape_footprint(pts)
        inner = (d < 0.99 * light.range) & (shape > 0)
        assert (lam_gl[inner] > 0).all() and (lam_np[inner] > 0).all()


@pytest.mark.parametrize("light", [l for l in LIGHTS if getattr(l, "range", 0) > 0], ids=light_id)
def test_glsl_and_numpy_agree_near_a_ranged_light(ctx, light, rng):
    """Twins at every distance of a ranged light: from inside the d² guard (d < 0.01·range,
    where λ is held at its cap) through the 1/d² region to the window's edge at the range."""
    dirs = rng.normal(size=(20000, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    d = light.range * np.exp(rng.uniform(np.log(1e-3), np.log(1.2), 20000))  # log-uniform 0.001..1.2 range
    # the points as the GPU gets them (float32): near the light, rounding the points themselves
    # would move a spot's cos φ by more than the float32 arithmetic does
    pts = (light.position + dirs * d[:, None]).astype(np.float32).astype(np.float64)
    lam_gl, _ = glsl_eval(ctx, light, pts)
    lam_np = light.footprint(pts)
    assert footprints_agree(lam_gl, lam_np).mean() > 0.9995, np.abs(lam_gl - lam_np).max()
    cap = 1.0 / (0.01 * light.range) ** 2
    assert lam_np.max() == pytest.approx(cap) and (lam_np <= cap).all() and (lam_gl <= cap * (1 + 1e-6)).all()
    assert ((d < 0.01 * light.range) & (lam_np > 0)).sum() > 100  # the guard region was sampled


def test_range_attenuation_values():
    """The windowed inverse square of KHR_lights_punctual by hand: 1/d² well inside the range,
    the window (1 − (d/r)⁴)² at the edge, 0 at and past the range, the cap 1/(0.01 r)² at the light."""
    light = PointLight(position=np.zeros(3), range=10.0)
    at = lambda *ds: light.footprint(np.array([[x, 0.0, 0.0] for x in ds]))
    assert at(1.0)[0] == pytest.approx((1 - 1e-4) ** 2)          # colour = intensity at distance 1
    assert at(2.0)[0] == pytest.approx((1 - 16e-4) ** 2 / 4)
    assert at(5.0)[0] == pytest.approx((1 - 0.5 ** 4) ** 2 / 25)
    assert at(10.0, 10.5, 100.0).tolist() == [0.0, 0.0, 0.0]
    assert at(0.0)[0] == pytest.approx(1.0 / 0.1 ** 2) and at(0.05)[0] == pytest.approx(at(0.0)[0])  # guard: d < 0.1
    assert at(0.2)[0] == pytest.approx((1 - 0.02 ** 4) ** 2 / 0.04)
    spot = SpotLight(position=np.zeros(3), direction=np.array([0.0, -1.0, 0.0]), alpha=60.0, beta=40.0, range=4.0)
    unranged = SpotLight(position=np.zeros(3), direction=np.array([0.0, -1.0, 0.0]), alpha=60.0, beta=40.0)
    pts = np.array([[0.0, -2.0, 0.0], [np.sin(np.radians(25)) * 2, -np.cos(np.radians(25)) * 2, 0.0], [0.0, 2.0, 0.0]])
    window = (1 - (2.0 / 4.0) ** 4) ** 2 / 4.0
    assert spot.footprint(pts) == pytest.approx(unranged.footprint(pts) * window)
    assert spot.footprint(pts)[2] == 0.0  # behind the spot: the cone still rules


def test_inverse_square_and_squared_cone_values():
    """glTF's lights (issue 41): without a range, λ = shape / max(d², 1e-6), no window at any
    distance; KHR's spot cone is the lab's linear ramp squared; parse reads both keys and
    refuses a range together with inverse_square."""
    light = PointLight(position=np.zeros(3), inverse_square=True)
    at = lambda *ds: light.footprint(np.array([[x, 0.0, 0.0] for x in ds]))
    assert at(1.0, 2.0, 1e3).tolist() == [1.0, 0.25, 1e-6]
    assert at(0.0)[0] == pytest.approx(1e6) and at(1e-4)[0] == at(0.0)[0]  # the guard: d < 1 mm
    assert light.uniforms()["light_inverse_square_near"] == 1e-3 and light.describe()["inverse_square"] is True
    lin = SpotLight(position=np.zeros(3), direction=np.array([0.0, -1.0, 0.0]), alpha=60.0, beta=40.0)
    sq = SpotLight(position=np.zeros(3), direction=np.array([0.0, -1.0, 0.0]), alpha=60.0, beta=40.0,
                   cone_falloff="squared")
    pts = np.array([[np.sin(np.radians(a)), -np.cos(np.radians(a)), 0.0] for a in (0, 15, 22, 25, 28, 31)])
    assert np.array_equal(sq.footprint(pts), lin.footprint(pts) ** 2) and sq.footprint(pts)[3] < lin.footprint(pts)[3]
    assert sq.uniforms()["light_cone_squared"] == 1 and lin.uniforms()["light_cone_squared"] == 0
    assert "cone_falloff" not in lin.describe() and sq.describe()["cone_falloff"] == "squared"
    parsed = parse_light({"type": "spot", "position": [0, 0, 0], "direction": [0, -1, 0], "alpha": 60, "beta": 40,
                          "inverse_square": True, "cone_falloff": "squared"}, "lights[0]", "x.toml")
    assert parsed.inverse_square and parsed.cone_falloff == "squared"
    with pytest.raises(SceneError, match=r"lights\[0\]\.inverse_square: .*not both"):
        parse_light({"type": "point", "position": [0, 0, 0], "range": 3.0, "inverse_square": True}, "lights[0]", "x.toml")
    with pytest.raises(SceneError, match="cone_falloff.*did you mean 'squared'"):
        parse_light({"type": "spot", "position": [0, 0, 0], "direction": [0, -1, 0], "alpha": 60, "beta": 40,
                     "cone_falloff": "square"}, "lights[0]", "x.toml")


def test_no_range_is_the_old_footprint_bit_for_bit(rng):
    """range = 0 (absent) leaves λ the shape factor alone, bit for bit, and sends light_range 0."""
    pts = rng.uniform(-3, 3, size=(5000, 3))
    spot = SpotLight(position=np.array([0.0, 3.0, 0.0]), direction=np.array([0.0, -1.0, 0.0]), alpha=70.0, beta=40.0)
    assert np.array_equal(spot.footprint(pts), spot._shape_footprint(pts))
    assert np.array_equal(PointLight(position=np.ones(3)).footprint(pts), np.ones(len(pts)))
    for light in LIGHTS:
        assert light.uniforms()["light_range"] == float(getattr(light, "range", 0.0))
        assert ("range" in light.describe()) == (getattr(light, "range", 0.0) > 0)
        plain = not getattr(light, "inverse_square", False)
        assert (light.uniforms()["light_inverse_square_near"] == 0.0) == plain
        assert ("inverse_square" in light.describe()) == (not plain)


def test_type_ids_match_glsl():
    src = glsl.shader_source("lights.glsl")
    assert set(LIGHT_TYPE_IDS) == {"point", "directional", "spot", "target_direct", "area"}
    for name, idx in LIGHT_TYPE_IDS.items():
        assert re.search(rf"#define LIGHT_{name.upper()} {idx}\b", src), name
    # every area shape sends the area id, which the shaders light as a point at the centre
    for cls in AREA_SHAPES.values():
        assert cls.type_name == "area" and cls.type_id == LIGHT_TYPE_IDS["area"]
    assert {l.uniforms()["light_type"] for l in LIGHTS if l.type_name == "area"} == {LIGHT_TYPE_IDS["area"]}


def test_spot_footprint_values():
    spot = SpotLight(position=np.zeros(3), direction=np.array([0.0, -1.0, 0.0]), alpha=60.0, beta=40.0)
    def at(deg):
        return spot.footprint(np.array([[np.sin(np.radians(deg)), -np.cos(np.radians(deg)), 0.0]]))[0]
    assert at(0) == 1.0 and at(19.9) == 1.0
    assert at(30.1) == 0.0
    c_o, c_i = np.cos(np.radians(30)), np.cos(np.radians(20))
    assert at(25) == pytest.approx((np.cos(np.radians(25)) - c_o) / (c_i - c_o))


def test_target_direct_footprint_values():
    td = TargetDirectLight(position=np.zeros(3), direction=np.array([0.0, -1.0, 0.0]), R=2.0, r=1.0)
    pts = np.array([[0.5, -1, 0], [1.5, -1, 0], [2.5, -1, 0], [0.0, 1.0, 0.0]])
    assert td.footprint(pts).tolist() == [1.0, 0.5, 0.0, 0.0]  # last: behind the light


@pytest.mark.parametrize("light", LIGHTS, ids=light_id)
def test_shadow_rays_end_at_the_light(light, rng):
    """origin + tfar · direction is the light (point, spot), a point of the light's plane
    (target-direct), or unbounded (directional)."""
    pts = rng.uniform([-2, -0.5, -2], [2, 0.5, 2], size=(500, 3))
    origins = pts.astype(np.float32)
    dirs, tfar = light.shadow_rays(origins, pts)
    assert dirs.dtype == np.float32 and tfar.dtype == np.float32 and dirs.shape == origins.shape
    end = origins.astype(np.float64) + tfar[:, None].astype(np.float64) * dirs
    if light.type_name in ("point", "spot", "area"):  # an area light's hard shadow rays end at its centre
        assert np.allclose(end, light.position, atol=1e-5 * np.linalg.norm(light.position - pts, axis=1).max())
    elif light.type_name == "target_direct":
        assert np.allclose((end - light.position) @ light.direction, 0, atol=1e-5)
    else:
        assert (tfar > 1e20).all()
    to_light, _ = light.to_light(pts)
    assert (np.einsum("ij,ij->i", dirs, to_light) > 0).all()


def near_plane(proj: np.ndarray) -> float:
    """The near distance of an OpenGL perspective or orthographic projection matrix."""
    if proj[3, 3] == 1.0:  # orthographic: m22 = -2/(f-n), m23 = -(f+n)/(f-n)
        return (proj[2, 3] + 1.0) / proj[2, 2]
    return proj[2, 3] / (proj[2, 2] - 1.0)  # perspective: m22 = (f+n)/(n-f), m23 = 2fn/(n-f)


@pytest.mark.parametrize("light", LIGHTS, ids=light_id)
@pytest.mark.parametrize("projection", ["auto", "cube"])
def test_shadow_views_cover_the_points_and_keep_casters_past_near(light, projection, rng):
    """Every point to cover inside the light's footprint lands in the clip volume of one of the
    light's views, and no caster point a view can see lies in front of its near plane (it would
    be clipped and lose its shadow)."""
    pts = rng.uniform([-2, -0.3, -2], [2, 0.0, 2], size=(2000, 3))
    casters = np.array([[[-0.5, 0.2, -0.5], [0.5, 1.0, 0.5]], [[1.0, 0.1, 1.0], [1.4, 0.6, 1.6]]])
    tris = np.concatenate([trimesh.creation.box(bounds=b).triangles for b in casters])
    views, _ = light.shadow_views(pts, Casters(casters, tris), 512, projection=projection)
    lit = light.footprint(pts) > 0
    assert lit.sum() > 100
    inside = np.zeros(len(pts), bool)
    for v in views:
        c = np.c_[pts, np.ones(len(pts))] @ v.view_proj.T
        inside |= (c[:, 3] > 0) & np.all(np.abs(c[:, :3]) <= c[:, 3:], axis=1)
    assert inside[lit].all()
    g = np.linspace(0, 1, 9)
    box_pts = np.concatenate([lo + (hi - lo) * np.stack(np.meshgrid(g, g, g), -1).reshape(-1, 3) for lo, hi in casters])
    for v in views:
        c = np.c_[box_pts, np.ones(len(box_pts))] @ v.view_proj.T
        sideways = (c[:, 3] > 0) & np.all(np.abs(c[:, :2]) <= c[:, 3:], axis=1)  # within the view's sides
        depth = -(np.c_[box_pts, np.ones(len(box_pts))] @ v.view.T)[:, 2]
        assert (depth[sideways] >= near_plane(v.proj) * (1 - 1e-12)).all()


RECT = {"type": "area", "shape": "rect", "position": [0.0, 3.0, 0.0], "u": [1.0, 0.0, 0.0], "v": [0.0, 0.0, 1.0]}
DISC = {"type": "area", "shape": "disc", "position": [0.0, 3.0, 0.0], "direction": [0.0, -2.0, 0.0], "radius": 0.5}
SPHERE = {"type": "area", "shape": "sphere", "position": [0.0, 3.0, 0.0], "radius": 0.25}


def test_area_lights_parse():
    rect, disc, sphere = (parse_light(t, "lights[0]", "s.toml") for t in (RECT, DISC, SPHERE))
    assert isinstance(rect, RectLight) and rect.area == pytest.approx(1.0)
    assert rect.normal.tolist() == pytest.approx([0.0, -1.0, 0.0])  # u × v
    assert isinstance(disc, DiscLight) and disc.direction.tolist() == pytest.approx([0.0, -1.0, 0.0])  # unit
    assert disc.area == pytest.approx(np.pi * 0.25)
    assert isinstance(sphere, SphereLight) and sphere.area == pytest.approx(4 * np.pi * 0.0625)
    assert {rect.type_name, disc.type_name, sphere.type_name} == {"area"}


@pytest.mark.parametrize("base,change,key,reason", [
    (RECT, {"v": [2.0, 0.0, 0.0]}, "lights[0].v", "zero area"),               # u ∥ v
    (RECT, {"u": [0.0, 0.0, 0.0]}, "lights[0].u", "zero vector"),
    (RECT, {"position": [0.0, float("nan"), 0.0]}, "lights[0].position", "finite"),
    (RECT, {"u": [1.0, float("inf"), 0.0]}, "lights[0].u", "finite"),
    (RECT, {"radius": 1.0}, "lights[0].radius", "unknown key"),               # a disc's key on a rect
    (RECT, {"v": None}, "lights[0].v", "missing"),
    (DISC, {"direction": [0.0, 0.0, 0.0]}, "lights[0].direction", "zero vector"),
    (DISC, {"radius": 0.0}, "lights[0].radius", "> 0"),
    (DISC, {"u": [1.0, 0.0, 0.0]}, "lights[0].u", "unknown key"),
    (SPHERE, {"radius": float("nan")}, "lights[0].radius", "finite"),
    (SPHERE, {"radius": -1.0}, "lights[0].radius", "> 0"),
    (SPHERE, {"direction": [0.0, -1.0, 0.0]}, "lights[0].direction", "unknown key"),
    (SPHERE, {"shape": "triangle"}, "lights[0].shape", "must be one of rect, disc, sphere"),
    (SPHERE, {"shape": None}, "lights[0].shape", "missing"),
    # finite parameters whose area overflows to ∞ or underflows to 0 (radius 1e300 used to parse
    # and then raise OverflowError in describe(); perpendicular edges of 1e200 used to overflow
    # the cross product and be called parallel)
    (SPHERE, {"radius": 1e300}, "lights[0].radius", "must be finite and > 0"),
    (DISC, {"radius": 1e300}, "lights[0].radius", "must be finite and > 0"),
    (DISC, {"radius": 1e-200}, "lights[0].radius", "must be finite and > 0"),  # π r² underflows to 0
    (RECT, {"u": [1e200, 0.0, 0.0], "v": [0.0, 0.0, 1e200]}, "lights[0].u", "must be finite and > 0"),
    (RECT, {"u": [1e-160, 0.0, 0.0], "v": [0.0, 0.0, 1e-160]}, "lights[0].u", "must be finite and > 0"),
    (RECT, {"u": [1e200, 0.0, 0.0], "v": [-3e200, 0.0, 0.0]}, "lights[0].v", "parallel"),  # still parallel
])
def test_bad_area_lights_name_the_key(base, change, key, reason):
    table = {**base, **change}
    table = {k: v for k, v in table.items() if v is not None}
    with pytest.raises(SceneError) as exc:
        parse_light(table, "lights[0]", "s.toml")
    assert exc.value.key == key and reason in exc.value.reason, str(exc.value)
    assert str(exc.value).startswith(f"s.toml: {key}: ")


def test_extreme_but_finite_area_lights_parse():
    """Edges of very different magnitudes with a finite area parse (the parallel test works on
    unit vectors: |u| = 1e200 overflowed |u|·|v| to ∞ and was called parallel), and describe()
    gives finite JSON numbers."""
    rect = parse_light({**RECT, "u": [1e200, 0.0, 0.0], "v": [0.0, 0.0, 1e-140]}, "lights[0]", "s.toml")
    assert rect.area == pytest.approx(1e60, rel=1e-12)
    assert rect.normal.tolist() == pytest.approx([0.0, -1.0, 0.0])
    disc = parse_light({**DISC, "direction": [0.0, -1e300, 1e300], "radius": 1e150}, "lights[0]", "s.toml")
    assert disc.direction.tolist() == pytest.approx([0.0, -np.sqrt(0.5), np.sqrt(0.5)])
    sphere = parse_light({**SPHERE, "radius": 1e150}, "lights[0]", "s.toml")
    for light in (rect, disc, sphere):
        assert np.isfinite(json.loads(json.dumps(light.describe(), allow_nan=False))["area"])


POINT = {"type": "point", "position": [0.0, 3.0, 0.0]}
SPOT = {"type": "spot", "position": [0.0, 3.0, 0.0], "direction": [0.0, -1.0, 0.0], "alpha": 60.0, "beta": 40.0}
SUN = {"type": "directional", "direction": [0.0, -1.0, 0.0]}
TD = {"type": "target_direct", "position": [0.0, 3.0, 0.0], "direction": [0.0, -1.0, 0.0], "R": 2.0, "r": 1.0}


def test_range_parses_on_point_and_spot_lights():
    for table in (POINT, SPOT):
        assert parse_light({**table, "range": 5}, "lights[0]", "s.toml").range == 5.0
        assert parse_light(table, "lights[0]", "s.toml").range == 0.0  # absent: no falloff


@pytest.mark.parametrize("base,value,reason", [
    (POINT, 0.0, "must be > 0"), (SPOT, -2.0, "must be > 0"), (POINT, float("nan"), "finite"),
    (POINT, "far", "must be a number"), (SPOT, 1e300, "between 1e-15 and 1e+15"), (POINT, 1e-20, "between"),
    (SUN, 5.0, "unknown key"), (TD, 5.0, "unknown key"), (SPHERE, 5.0, "unknown key"), (RECT, 5.0, "unknown key"),
])
def test_bad_or_misplaced_range_names_the_key(base, value, reason):
    with pytest.raises(SceneError) as exc:
        parse_light({**base, "range": value}, "lights[0]", "s.toml")
    assert exc.value.key == "lights[0].range" and reason in exc.value.reason, str(exc.value)
    assert str(exc.value).startswith("s.toml: lights[0].range: ") and "\n" not in str(exc.value)


@pytest.fixture(scope="module")
def ranged_scene():
    """A box on a floor lit by a point light and a spot, each twice: with a range (lights 0, 2)
    and without (lights 1, 3), at the same place."""
    from helpers import make_scene

    point = {"type": "point", "position": [0.8, 2.2, 0.6]}
    spot = {"type": "spot", "position": [-1.5, 3.0, -0.5], "direction": [0.3, -1.0, 0.2], "alpha": 90.0, "beta": 60.0}
    objects = [{"mesh": "plane", "size": [12.0, 12.0], "name": "floor"},
               {"mesh": "box", "size": [1.0, 1.0, 1.0], "translate": [0.0, 0.5, 0.0], "name": "box"}]
    return make_scene(objects, [{**point, "range": 3.5}, point, {**spot, "range": 4.0}, spot], name="ranged")


@pytest.mark.parametrize("ranged,plain", [(0, 1), (2, 3)], ids=["point", "spot"])
def test_a_range_limits_the_evaluated_pixels_truth_and_map_fit(lab, ranged_scene, ranged, plain):
    """The evaluated pixels of a ranged light are its unranged twin's within the range (λ > 0
    is the one rule: the mask, the truth and the map fit all follow it); the truth agrees with
    the twin's there; and shadow_map's one frustum, fitted to those pixels (the point light's
    twin needs a cube), covers every one that can be shadowed (fit=shadowable, the default) or
    every one (fit=receivers): no pixel is read as lit for falling outside the map."""
    from helpers import SMALL, mismatches
    from shadowlab.techniques.maps.toolkit import fit_light_views, shadowable_mask

    frame = lab.frame(ranged_scene, SMALL)
    light = ranged_scene.lights[ranged]
    ev, ev_plain = frame.evaluated(ranged), frame.evaluated(plain)
    d = np.linalg.norm(frame.position - light.position, axis=-1)
    assert np.array_equal(ev, ev_plain & (d < light.range))
    assert 0.1 * ev_plain.sum() < ev.sum() < 0.8 * ev_plain.sum()
    assert np.array_equal(frame.evaluated_image(frame.slot(ranged)), ev)
    truth, truth_plain = lab.truth(ranged_scene, SMALL, ranged), lab.truth(ranged_scene, SMALL, plain)
    assert np.array_equal(truth[ev], truth_plain[ev]) and (truth[ev] < 0.5).sum() > 50  # shadow in range
    for fit, pts in (("shadowable", frame.compact_position[frame.slot(ranged).evaluated][
                          shadowable_mask(frame, frame.slot(ranged))]), ("receivers", frame.position[ev])):
        views, notes = fit_light_views(frame, frame.slot(ranged), 1024, fit=fit)
        assert len(views) == 1 and not notes and len(pts) > 50
        c = np.c_[pts, np.ones(len(pts))] @ views[0].view_proj.T
        assert ((c[:, 3] > 0) & np.all(np.abs(c[:, :3]) <= c[:, 3:], axis=1)).all(), fit
    if light.type_name == "point":  # the unranged twin's receivers span more than one frustum: a cube
        views_plain, _ = fit_light_views(frame, frame.slot(plain), 1024, fit="receivers")
        assert len(views_plain) == 6
    wrong, evaluated, m = mismatches(lab, ranged_scene, "shadow_map", SMALL, ranged)
    assert evaluated == ev.sum() and wrong <= 0.01 * evaluated
    assert not [n for n in m.notes if "outside" in n]
