"""Lights: the numpy and GLSL definitions agree; footprints follow DESIGN §8."""
from __future__ import annotations

import re

import numpy as np
import pytest

from shadowlab import gl
from shadowlab.lights import (LIGHT_TYPE_IDS, DirectionalLight, PointLight, SpotLight, TargetDirectLight)

LIGHTS = [
    PointLight(position=np.array([0.5, 4.0, -1.0])),
    DirectionalLight(direction=np.array([-0.3, -1.0, 0.2]) / np.linalg.norm([-0.3, -1.0, 0.2])),
    SpotLight(position=np.array([0.0, 3.0, 0.0]), direction=np.array([0.0, -1.0, 0.0]), alpha=70.0, beta=40.0),
    SpotLight(position=np.array([1.0, 3.0, 0.0]), direction=np.array([0.0, -1.0, 0.0]), alpha=50.0, beta=50.0),
    TargetDirectLight(position=np.array([0.0, 3.0, 0.0]), direction=np.array([0.0, -1.0, 0.0]), R=2.0, r=1.0),
]


def glsl_eval(ctx, light, points):
    prog = gl.program("light_probe.glsl", varyings=("out_footprint", "out_dir"))
    gl.set_uniforms(prog, light.uniforms())
    vbo = ctx.buffer(points.astype("f4").tobytes())
    out = ctx.buffer(reserve=len(points) * 16)
    vao = ctx.vertex_array(prog, [(vbo, "3f", "in_pos")])
    gl.park()  # EGL standalone contexts have no default framebuffer
    vao.transform(out, vertices=len(points))
    res = np.frombuffer(out.read(), "f4").reshape(-1, 4)
    for obj in (vao, vbo, out, prog):
        obj.release()
    return res[:, 0], res[:, 1:]


@pytest.mark.parametrize("light", LIGHTS, ids=lambda l: l.type_name)
def test_glsl_and_numpy_agree(ctx, light, rng):
    pts = rng.uniform([-4, -1, -4], [4, 2.9, 4], size=(20000, 3))
    lam_gl, dir_gl = glsl_eval(ctx, light, pts)
    lam_np = light.footprint(pts)
    dir_np, _ = light.to_light(pts)
    # float32 GLSL vs float64 numpy: the ramp agrees to float32 precision; a point exactly on a
    # step edge may differ, so allow a handful of pixels of disagreement there only.
    close = np.abs(lam_gl - lam_np) < 1e-4
    assert close.mean() > 0.9995, np.abs(lam_gl - lam_np).max()
    assert np.allclose(dir_gl, dir_np, atol=1e-5)


def test_type_ids_match_glsl():
    src = gl.shader_source("lights.glsl")
    for name, idx in LIGHT_TYPE_IDS.items():
        assert re.search(rf"#define LIGHT_{name.upper()} {idx}\b", src), name


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


@pytest.mark.parametrize("light", LIGHTS, ids=lambda l: l.type_name)
def test_shadow_rays_end_at_the_light(light, rng):
    """origin + tfar · direction is the light (point, spot), a point of the light's plane
    (target-direct), or unbounded (directional)."""
    pts = rng.uniform([-2, -0.5, -2], [2, 0.5, 2], size=(500, 3))
    origins = pts.astype(np.float32)
    dirs, tfar = light.shadow_rays(origins, pts)
    assert dirs.dtype == np.float32 and tfar.dtype == np.float32 and dirs.shape == origins.shape
    end = origins.astype(np.float64) + tfar[:, None].astype(np.float64) * dirs
    if light.type_name in ("point", "spot"):
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


@pytest.mark.parametrize("light", LIGHTS, ids=lambda l: l.type_name)
@pytest.mark.parametrize("projection", ["auto", "cube"])
def test_shadow_views_cover_the_points_and_keep_casters_past_near(light, projection, rng):
    """Every point to cover inside the light's footprint lands in the clip volume of one of the
    light's views, and no caster point a view can see lies in front of its near plane (it would
    be clipped and lose its shadow)."""
    pts = rng.uniform([-2, -0.3, -2], [2, 0.0, 2], size=(2000, 3))
    casters = np.array([[[-0.5, 0.2, -0.5], [0.5, 1.0, 0.5]], [[1.0, 0.1, 1.0], [1.4, 0.6, 1.6]]])
    views, _ = light.shadow_views(pts, casters, 512, projection=projection)
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
