"""The compiled and the batch clippers and the bulk pair culling of exact shadow polygons
(issue 11) against the one-pair clipper they replace: the same fragments, bit for bit, on
random convex polygons of mixed sizes, on the hard configurations, and on whole shipped scenes;
the same candidate pairs as the plain vertex test."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from shadowlab.gpu.frame import Frame
from shadowlab.geometry.clipping import batch as bc
from shadowlab.geometry.clipping import compiled as cc
from shadowlab.geometry.clipping import scalar as pc
from shadowlab.geometry.frusta import side_planes
from shadowlab.geometry.triangles import triangle_planes
from shadowlab.geometry.vectors import dot3
from shadowlab.scene import load_scene
from shadowlab.techniques import from_spec
from shadowlab.techniques.base import TechniqueError
from shadowlab.geometry.clipping import FragmentMemoryError, candidate_pairs, fragment_triangles

from test_polygon_clipping import configurations

EPS = 1e-12


def padded(polys):
    """Polygons of any sizes → PaddedPolygons (zeros in the padding)."""
    width = max(len(p) for p in polys)
    verts = np.zeros((len(polys), width, 3))
    for i, p in enumerate(polys):
        verts[i, :len(p)] = p
    return bc.PaddedPolygons(verts, np.array([len(p) for p in polys], np.int64))


def assert_batch_is_scalar(receivers, casters, light, eps):
    """Row by row, the batch fragment and the compiled clipper's have the scalar fragment's
    vertices, bit for bit."""
    out = bc.shadow_fragments(padded(receivers), padded(casters), light, eps)
    for i, (r, c) in enumerate(zip(receivers, casters)):
        want, _ = pc.shadow_fragment(r, c, light, eps)
        for got in (out.polygon(i), cc.shadow_fragment(r, c, light, eps)):
            assert got.shape == want.shape, (i, got.shape, want.shape)
            assert got.tobytes() == want.tobytes(), i
    return out


@pytest.mark.slow  # a long property run (60 examples)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(configurations(), min_size=1, max_size=6), st.booleans())
def test_batch_fragments_are_the_scalar_fragments_on_convex_polygons(configs, directional):
    """Receivers and casters of 3–7 vertices, padded together, every one tilted and moved: the
    batch gives each row the one-pair clipper's fragment (and so its area, which the property
    tests of test_polygon_clipping hold to the projected caster clipped by GEOS)."""
    receivers = [c[0] for c in configs]
    casters = [c[1] for c in configs]
    light = configs[-1 if directional else 0][2]
    out = assert_batch_is_scalar(receivers, casters, light, EPS)
    for i, (_, _, lt, expected, _, _) in enumerate(configs):
        if lt is light:
            got = pc.area(out.polygon(i))
            assert abs(got - expected) <= 1e-9 * pc.area(receivers[i])


def test_batch_fragments_on_the_hard_configurations():
    """No shadow where the caster is behind the receiver, edge-on to the light, degenerate, or
    where the light lies in the receiver's plane; a caster crossing the receiver's plane is
    cut; a receiver wholly on the caster's plane is not behind it — each row as the scalar."""
    receiver = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1.0]])
    light = np.array([0.2, 3.0, 0.1, 1.0])
    rows = [
        (receiver, receiver + [0, -0.5, 0]),                                     # caster below
        (receiver, np.array([[0, 1, -0.3], [0, 1.5, 0.3], [0.1 * 0.2 / 3, 2.0, 0.0]])),  # near edge-on
        (receiver, np.array([[0, 1, 0], [1, 1, 0], [2, 1, 0.0]])),               # collinear: no plane
        (receiver, np.array([[-0.5, -0.5, 0], [0.5, 0.5, 0], [0.5, 0.5, 0.6]])),  # crosses the receiver
        (receiver, receiver * 0.3),                                              # on the receiver's plane
        (np.array([[-1, 3, -1], [1, 3, -1], [0, 3, 1.0]]), receiver * 0.2 + [0, 1, 0]),  # light in plane
        (receiver, np.array([[-0.2, 1, -0.2], [0.2, 1, -0.2], [0.2, 1, 0.2], [-0.2, 1, 0.2]])),  # plain
    ]
    out = assert_batch_is_scalar([r for r, _ in rows], [c for _, c in rows], light, EPS)
    assert out.count[0] == 0 and out.count[2] == 0 and out.count[5] == 0
    assert out.count[3] > 0 and out.count[-1] == 4


@pytest.mark.slow  # a long property sweep: 2000 random pairs per light through the scalar Python clipper
@pytest.mark.parametrize("light", [np.array([0.3, 5.0, 0.2, 1.0]), np.array([0.2, 1.0, -0.1, 0.0])])
def test_batch_fragments_on_random_triangles(light):
    """Two thousand random receiver/caster triangle pairs around a point and a directional
    light, every relation between them (crossing, behind, beside): the scalar's fragments."""
    rng = np.random.default_rng(7)
    rec = rng.normal(size=(2000, 3, 3)) * 2.0
    rec[..., 1] *= 0.05
    cas = rng.normal(size=(2000, 3, 3)) * 0.7 + [0.0, 1.0, 0.0]
    out = assert_batch_is_scalar(list(rec), list(cas), light, 1e-9)
    assert 300 < np.count_nonzero(out.count) < 1900


def test_fan_triangles_is_triangulate_in_order():
    polys = [np.random.default_rng(1).normal(size=(k, 3)) for k in (3, 5, 0, 4, 7)]
    tris, rows = bc.fan_triangles(padded([p if len(p) else np.zeros((0, 3)) for p in polys]))
    want = np.concatenate([pc.triangulate(p) for p in polys])
    assert tris.tobytes() == want.tobytes()
    assert rows.tolist() == sum(([i] * max(len(p) - 2, 0) for i, p in enumerate(polys)), [])


def vertex_test_pairs(rec, cas, light_h, eps):
    """The definition of a candidate pair, pair by pair over all pairs (the culling's oracle)."""
    n, d = triangle_planes(cas)
    sign = np.where(n @ light_h[:3] + d * light_h[3] >= 0, 1.0, -1.0)
    planes = side_planes(cas, light_h)
    front = np.concatenate([sign[:, None] * n, (sign * d)[:, None]], axis=1)  # light side positive
    dist = dot3(front[:, None, None, :3], rec[None]) + front[:, 3, None, None]
    side = dot3(planes[:, :, None, None, :3], rec[None, None]) + planes[..., 3][:, :, None, None]
    keep = (dist < eps).any(axis=2) & ~(side < -eps).all(axis=3).any(axis=1)
    ci, ri = np.nonzero(keep)
    return np.stack([ri, ci], axis=1)


# spot_scene and sv_directional (the most pairs through the all-pairs oracle) run with the slow tests
@pytest.mark.parametrize("name", [pytest.param("spot_scene", marks=pytest.mark.slow),
                                  pytest.param("sv_directional", marks=pytest.mark.slow), "sm_far_origin",
                                  "sv_light_close"])
def test_culling_keeps_exactly_the_vertex_test_pairs(name):
    """The sphere pre-tests (float32 in numpy, float64 in the compiled kernel) only drop pairs
    the vertex test drops: the pairs are the plain vertex test's, in the same caster-major
    order, also far from the origin (the kernel reports how many it clipped)."""
    frame = Frame(load_scene(name), 64, 48)
    try:
        rec, _, cas = from_spec("shadow_polygons").polygons(frame, 0)
        light_h = frame.scene.lights[0].homogeneous()
        eps = 1e-9 * frame.scene.extent()
        cas = cas[:400]  # the oracle holds (C, 3, R, 3) arrays
        want = vertex_test_pairs(rec, cas, light_h, eps)
        got = np.concatenate([candidate_pairs(rec, cas, light_h, eps, slice(c, c + 97)) for c in range(0, len(cas), 97)])
        assert len(want) > 100
        assert np.array_equal(got, want)
        compiled = fragment_triangles(rec, cas, light_h, eps, clipper="compiled")
        assert compiled.pairs == len(want)
    finally:
        frame.release()


# sv_light_close (the scalar loop's longest scene) runs with the slow tests
@pytest.mark.parametrize("name", [pytest.param("sv_light_close", marks=pytest.mark.slow), "multi_light"])
def test_scene_fragments_batch_equal_scalar(name):
    """Whole shipped scenes, every light: the compiled and the batch preprocessing yield the
    scalar loop's triangles and receivers, bit for bit, on one thread or several, and report
    progress to the end."""
    frame = Frame(load_scene(name), 64, 48)
    try:
        for li, light in enumerate(frame.scene.lights):
            rec, _, cas = from_spec("shadow_polygons").polygons(frame, li)
            eps = 1e-9 * frame.scene.extent()
            seen = []
            fast = fragment_triangles(rec, cas, light.homogeneous(), eps, progress=lambda d, t: seen.append((d, t)))
            slow = fragment_triangles(rec, cas, light.homogeneous(), eps, clipper="scalar")
            numpy = fragment_triangles(rec, cas, light.homogeneous(), eps, clipper="batch")
            for got in (fast, numpy):
                assert got.fragments == slow.fragments > 0 and got.pairs == slow.pairs
                assert got.triangles.tobytes() == slow.triangles.tobytes()
                assert np.array_equal(got.receiver, slow.receiver)
            assert seen and seen[-1] == (len(cas), len(cas))
            single = fragment_triangles(rec, cas, light.homogeneous(), eps, threads=1)
            several = fragment_triangles(rec, cas, light.homogeneous(), eps, threads=3)
            assert single.triangles.tobytes() == several.triangles.tobytes() == fast.triangles.tobytes()
    finally:
        frame.release()


def test_fragments_beyond_the_memory_limit_are_a_clear_error(monkeypatch):
    frame = Frame(load_scene("box_on_plane"), 64, 48)
    try:
        rec, _, cas = from_spec("shadow_polygons").polygons(frame, 0)
        with pytest.raises(FragmentMemoryError, match="outgrew"):
            fragment_triangles(rec, cas, frame.scene.lights[0].homogeneous(), 1e-9, memory_limit=1000)
        # the technique gives it a share of the memory available at its setup, and says so
        from shadowlab.gpu import memory
        from shadowlab.measurement.pipeline import measure

        monkeypatch.setattr(memory, "available_bytes", lambda: 2000)
        with pytest.raises(TechniqueError, match="shadow_polygons: the exact shadow fragments outgrew .* of the memory available"):
            measure(from_spec("shadow_polygons"), frame, 0, repeat=1, warmup=0)
    finally:
        frame.release()
