"""Light sampling (shadowlab.measurement.light_sampling): every opted-in hard technique averaged over N points
of an area light, through the shared machinery (Technique.LIGHT_SAMPLED, Frame.stand_in,
pipeline.measure).

The expected images are built here from the definition (docs/metrics.md): over the area light's
evaluated pixels V(P) = [P on the emitting side] · mean_i vis_i(P) · [point i above P's tangent
plane], the indicator terms computed in this file from the rectangle's own numbers, not with
shadowlab.scene.area_lights' helpers."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.gpu.frame import Frame
from shadowlab.measurement.light_sampling import combined_stats, combined_timing
from shadowlab.scene.lights import PointLight
from shadowlab.measurement.pipeline import measure
from shadowlab.scene import parse_scene
from shadowlab.techniques import REGISTRY, Param, Technique, TechniqueError, from_spec
from shadowlab.techniques.base import FIRST, MAX, SUM
from shadowlab.techniques.rays.raytrace import RayTraced
from shadowlab.gpu.timing import Timing

from helpers import SMALL

SIZE = SMALL
CENTRE = np.array([-1.2, 3.0, -1.2])
U, V = np.array([1.6, 0.0, 0.0]), np.array([0.0, 0.0, 1.2])  # u × v = (0, -1.92, 0): emits down
SAMPLED = [name for name, cls in REGISTRY.items() if cls.LIGHT_SAMPLED]


def rect_scene():
    """A box on a plane under a 1.6 x 1.2 rectangle at height 3, and a wall (an open quad, facing
    the camera) that reaches above the light's plane, so part of it is evaluated (faces the
    centre) yet behind the one-sided light, and whose plane cuts the rectangle: the centre is in
    front of it, part of the light behind it (the horizon factor; an open surface, so no closed
    solid hides those points anyway)."""
    data = {
        "name": "rect_soft",
        "camera": {"eye": [3.5, 4.5, 5.0], "target": [0.0, 0.5, 0.0], "fov_y": 55.0},
        "lights": [{"type": "area", "shape": "rect", "position": CENTRE.tolist(), "u": U.tolist(),
                    "v": V.tolist()}],
        "objects": [
            {"name": "floor", "mesh": "plane", "size": [8.0, 8.0]},
            {"name": "crate", "mesh": "box", "size": [1.0, 1.0, 1.0], "translate": [0.0, 0.5, 0.0]},
            {"name": "wall", "mesh": "plane", "size": [1.2, 4.0], "rotate": [90.0, 0.0, 0.0],
             "translate": [-3.0, 2.0, -1.3]},
        ],
    }
    return parse_scene(data, "<rect_soft>")


@pytest.fixture(scope="module")
def frame(ctx):
    f = Frame(rect_scene(), *SIZE)
    yield f
    f.release()


def factors(frame, point):
    """Expected per-pixel factor (height, width) of one light point: [emitting side] ·
    [point above the tangent plane] on the area light's evaluated pixels, NaN elsewhere."""
    ev = frame.compact_evaluated(0)
    p, n = frame.compact_position, frame.compact_normal
    normal = np.cross(U, V) / np.linalg.norm(np.cross(U, V))
    front = (p - CENTRE) @ normal > 0
    above = np.einsum("ij,ij->i", point - p, n) > 0
    out = np.where(ev, (front & above).astype(np.float64), np.nan)
    return frame.to_image(out, fill=np.nan, dtype=np.float64)


def hard_average(frame, spec, points):
    """The definition's V from hard measurements of ``spec`` on point lights at ``points``,
    each standing in for the area light under its index; also the hard images."""
    total, images = 0.0, []
    for point in points:
        stand_in = frame.stand_in(frame.slot(0), PointLight(position=np.array(point, np.float64)))
        vis = measure(from_spec(spec), frame, stand_in, repeat=1, warmup=0).visibility
        images.append(vis)
        total = total + vis.astype(np.float64) * factors(frame, point)
    out = total / len(points)
    return np.where(np.isnan(out), 1.0, out), images


def sampled(frame, spec, n):
    return measure(from_spec(f"{spec}:light_samples={n}"), frame, 0, repeat=1, warmup=0)


def test_the_scene_exercises_both_factors(frame):
    """The wall gives evaluated pixels behind the light (V = 0 by the one-sided factor), and
    the crate a hard shadow, so the comparisons below can fail."""
    fac = factors(frame, CENTRE)
    ev = frame.evaluated(0)
    assert ev.sum() > 5000
    assert np.sum(fac[ev] == 0) > 50
    hard, _ = hard_average(frame, "raytrace", [CENTRE])
    assert np.sum(hard[ev & (fac == 1)] == 0) > 300
    # the wall's plane cuts the rectangle: some of the 16 points are below it
    towards = frame.compact_position[frame.compact_evaluated(0)].mean(axis=0)
    below = np.zeros(ev.shape, bool)
    for point in frame.scene.lights[0].pattern(16, towards=towards):
        below |= ev & (fac == 1) & (factors(frame, point) == 0)
    assert below.sum() > 50


@pytest.mark.parametrize("name", SAMPLED)
def test_one_sample_is_the_hard_technique_at_the_centre(frame, name):
    """(a) light_samples=1: the technique's own hard image for a point light at the centre,
    masked by the one-sided and horizon factors; bit for bit, and 1 off the evaluated pixels."""
    m = sampled(frame, name, 1)
    want, (hard,) = hard_average(frame, name, [CENTRE])
    assert m.visibility.dtype == np.float32 and m.visibility.shape == (SIZE[1], SIZE[0])
    assert np.array_equal(m.visibility, want.astype(np.float32))
    assert np.all(m.visibility[~frame.evaluated(0)] == 1.0)
    assert m.stats["light_samples"] == 1
    # the masking matters: pixels the point light alone would call lit are dark here
    assert np.sum((hard == 1) & (m.visibility == 0)) > 50


def test_shadow_polygons_average_equals_ray_traced_average(frame):
    """(b) exact hard shadows: the 16-sample average of shadow_polygons equals the average of 16
    ray-traced hard visibilities from the same pattern points, within shadow_polygons' hard error
    (error_rate <= 0.001 against the truth, tests/techniques/geometric/test_shadow_polygons.py)."""
    n = 16
    light = frame.scene.lights[0]
    ev = frame.compact_evaluated(0)
    towards = frame.compact_position[ev].mean(axis=0)
    points = light.pattern(n, towards=towards)
    assert np.allclose(points.mean(axis=0), CENTRE)
    want, _ = hard_average(frame, "raytrace", points)
    got = sampled(frame, "shadow_polygons", n).visibility
    evaluated = frame.evaluated(0)
    diff = np.abs(got.astype(np.float64) - want)[evaluated]
    assert diff.mean() <= 1e-3
    assert np.mean(diff > 0) <= 16 * 1e-3  # at most the hard error rate on each of the 16 images
    penumbra = (want > 0) & (want < 1) & evaluated
    assert penumbra.sum() > 200  # the average is soft: many partial values
    assert len(np.unique(got[penumbra])) >= 8


@pytest.fixture(scope="module")
def reference(frame):
    """The 400-point ray-traced average of test_n_renders_and_error_falls_with_n (once for both
    techniques)."""
    light = frame.scene.lights[0]
    towards = frame.compact_position[frame.compact_evaluated(0)].mean(axis=0)
    return hard_average(frame, "raytrace", light.pattern(400, towards=towards))[0]


@pytest.mark.parametrize("name", ["shadow_polygons", "shadow_volume"])
def test_n_renders_and_error_falls_with_n(frame, reference, name):
    """(c) light_samples=N sets up N times and renders each sample warmup + repeat times plus once
    for its work counters (shadowlab.gpu.work; counted, not timed), the timing is the
    samples' sum, and visibility_mae against a 400-point ray-traced average falls from N=1 to
    N=16 (and the 16-sample one is within 0.01)."""
    evaluated = frame.evaluated(0)
    mae = {}
    for n in (1, 4, 16):
        tech = from_spec(f"{name}:light_samples={n}")
        calls = {"setup": 0, "render": 0}

        def counted(method, key):
            def wrapper(*a, **k):
                calls[key] += 1
                return method(*a, **k)
            return wrapper

        tech.setup, tech.render = counted(tech.setup, "setup"), counted(tech.render, "render")
        m = measure(tech, frame, 0, repeat=2, warmup=1)
        assert calls == {"setup": n, "render": (1 + 2 + 1) * n}
        assert m.stats["light_samples"] == n
        assert len(m.timing.samples_ms) == 2
        assert m.timing.median_ms > 0
        mae[n] = float(np.abs(m.visibility.astype(np.float64) - reference)[evaluated].mean())
    assert mae[1] > mae[4] > mae[16]
    assert mae[16] < 0.5 * mae[1] and mae[16] < 0.01


@pytest.mark.parametrize("light", [
    {"type": "area", "shape": "disc", "position": [-1.2, 3.0, -1.2], "direction": [0.2, -1.0, 0.1], "radius": 0.7},
    {"type": "area", "shape": "sphere", "position": [-1.2, 3.0, -1.2], "radius": 0.5},
])
def test_disc_and_sphere_lights(ctx, light):
    """The other shapes go through the same path: 9 samples equal the definition computed here
    from the pattern points (the disc's one-sided factor from its direction; the sphere emits
    towards every point outside it; its points lie on the cap seen from the receivers' centre),
    bit for bit, with a visible penumbra."""
    data = {"name": "shapes", "camera": {"eye": [3.5, 4.5, 5.0], "target": [0.0, 0.5, 0.0], "fov_y": 55.0},
            "lights": [light],
            "objects": [{"mesh": "plane", "size": [8.0, 8.0]},
                        {"mesh": "box", "size": [1.0, 1.0, 1.0], "translate": [0.0, 0.5, 0.0]}]}
    frame = Frame(parse_scene(data, "<shapes>"), *SIZE)
    try:
        area = frame.scene.lights[0]
        ev = frame.compact_evaluated(0)
        p, nrm = frame.compact_position, frame.compact_normal
        towards = p[ev].mean(axis=0)
        points = area.pattern(9, towards=towards)
        if light["shape"] == "disc":
            direction = np.array(light["direction"]) / np.linalg.norm(light["direction"])
            front = (p - light["position"]) @ direction > 0
            assert np.allclose((points - light["position"]) @ direction, 0.0)
        else:
            front = np.linalg.norm(p - light["position"], axis=1) > light["radius"]
            offset = towards - np.array(light["position"])
            dist = np.linalg.norm(offset)
            r = light["radius"]
            assert np.allclose(np.linalg.norm(points - light["position"], axis=1), r)  # on the sphere
            assert np.all((points - light["position"]) @ (offset / dist) >= r * r / dist - 1e-12)  # on the cap seen from there
        total = np.zeros(len(p))
        for point in points:
            stand_in = frame.stand_in(frame.slot(0), PointLight(position=point))
            vis = measure(from_spec("shadow_volume"), frame, stand_in, repeat=1, warmup=0).visibility
            above = np.einsum("ij,ij->i", point - p, nrm) > 0
            total += vis.reshape(-1)[frame.pixel_index] * above
        want = frame.to_image(np.where(ev, front * total / 9, 1.0), fill=1.0, dtype=np.float64)
        got = measure(from_spec("shadow_volume:light_samples=9"), frame, 0, repeat=1, warmup=0).visibility
        assert np.array_equal(got, want.astype(np.float32))
        assert np.sum((got > 0) & (got < 1)) > 100
    finally:
        frame.release()


def test_combined_timing_and_stats():
    """Sums of medians and run-by-run sums; each stat combined by its declared rule (summed,
    maxima for sizes, first for views); a stat without a rule is an error."""
    t = combined_timing([Timing(2.0, 0.5, [1.0, 2.0, 3.0]), Timing(4.0, 1.0, [4.0, 4.0, 5.0], 1.0)])
    assert (t.median_ms, t.iqr_ms, t.samples_ms, t.gpu_median_ms) == (6.0, 1.5, [5.0, 6.0, 8.0], None)
    rules = {"passes": SUM, "memory_bytes": MAX, "texel_world": FIRST, "mode": FIRST, "faces": FIRST}
    s = combined_stats([{"passes": 2, "memory_bytes": 10, "texel_world": 0.5, "mode": "a", "faces": 6},
                        {"passes": 3, "memory_bytes": 30, "texel_world": 0.7, "mode": "b", "faces": 6}], rules)
    assert s == {"passes": 5, "memory_bytes": 30, "texel_world": 0.5, "mode": "a", "faces": 6}
    with pytest.raises(KeyError, match="declare it in STATS"):
        combined_stats([{"passes": 1, "mystery": 2}], {"passes": SUM}, "demo")
    with pytest.raises(ValueError, match="no timing"):
        combined_timing([])
    # the quartiles (the repeat interval the verdicts compare) are summed too, when every sample has them
    q = combined_timing([Timing(2.0, 0.5, [1.0, 2.0, 3.0], None, 1.5, 2.0),
                         Timing(4.0, 1.0, [4.0, 4.0, 5.0], None, 3.5, 4.5)])
    assert (q.q25_ms, q.q75_ms) == (5.0, 6.5)
    assert q.columns()["time_ms_q25"] == 5.0 and q.columns()["time_ms_q75"] == 6.5
    assert "time_ms_q25" not in t.columns()  # one sample without them: none


def test_a_timing_reports_its_quartiles(monkeypatch):
    """time_passes' quartiles: the first and third quartile of the timed runs, whose difference is the IQR."""
    import shadowlab.gpu.timing as timing_module

    clock = iter([0.0, 0.001, 0.0, 0.003, 0.0, 0.002, 0.0, 0.005, 0.0, 0.004])  # runs of 1, 3, 2, 5, 4 ms
    monkeypatch.setattr(timing_module.time, "perf_counter", lambda: next(clock))
    t = timing_module.time_passes(lambda: None, repeat=5, warmup=0, gpu=False)
    assert t.samples_ms == pytest.approx([1.0, 3.0, 2.0, 5.0, 4.0])
    assert (t.q25_ms, t.median_ms, t.q75_ms) == pytest.approx((2.0, 3.0, 4.0))
    assert t.iqr_ms == pytest.approx(t.q75_ms - t.q25_ms)
    assert t.columns()["time_ms_q25"] == pytest.approx(2.0)


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
@pytest.mark.parametrize("name", SAMPLED)
def test_every_stat_has_a_rule_and_a_cube_map_keeps_six_faces(frame, name):
    """Every sampled technique's stats combine by declared rules; four samples of a cube map
    still report faces = 6 (a description, not work: the bug of summing every number)."""
    spec = f"{name}:light_samples=4" + (",projection=cube" if name == "shadow_map" else "")
    m = measure(from_spec(spec), frame, 0, repeat=1, warmup=0)
    one = measure(from_spec(spec.replace("light_samples=4", "light_samples=1")), frame, 0, repeat=1, warmup=0)
    assert set(m.stats) - {"light_samples", "texel_footprint_p50", "texel_footprint_p95", "texel_footprint_max"} \
        <= set(from_spec(name).STATS)
    if name == "shadow_map":
        assert one.stats["faces"] == m.stats["faces"] == 6
        assert m.stats["passes"] == 4 * one.stats["passes"]


def test_light_samples_parameter():
    """(d) the shared parameter: last in every opted-in spec, round-trips, validated; raytrace has
    none and unknown parameters still error (naming light_samples among the known ones)."""
    assert set(SAMPLED) == {"shadow_map", "shadow_volume", "planar", "shadow_polygons", "projective",
                            "irregular_zbuffer", "virtual_map", "cc_volume", "hierarchical_volume",
                            "per_triangle_volume", "partitioned_volume", "imperfect_map"}
    for name in SAMPLED:
        t = from_spec(f"{name}:light_samples=9")
        assert t.spec().endswith(",light_samples=9") and t.light_samples == 9
        assert from_spec(t.spec()).params() == t.params()
        assert from_spec(name).spec().endswith(",light_samples=1")
        assert t.short_label() == f"{name}:light_samples=9"
    assert "light_samples" not in RayTraced.PARAMS
    for spec, match in [("raytrace:light_samples=4", "unknown parameter 'light_samples'"),
                        ("shadow_map:light_sample=4", r"unknown parameter 'light_sample'.*light_samples"),
                        ("shadow_map:light_samples=0", "light_samples must be >= 1"),
                        ("shadow_map:light_samples=4097", "light_samples must be <= 4096"),
                        ("shadow_map:light_samples=2.5", "light_samples must be int")]:
        with pytest.raises(TechniqueError, match=match):
            from_spec(spec)


def test_opting_in_and_out_in_subclasses(registry_snapshot):
    """A subclass of an opted-in class that opts out loses the parameter; declaring it by hand
    is refused (it is the shared one)."""
    class Hard(Technique):
        name = "hard_test"
        PARAMS = {"k": Param(1, "k")}
        LIGHT_SAMPLED = True

    class Soft(Hard):
        name = "soft_test"
        LIGHT_SAMPLED = False

    assert list(Hard.PARAMS) == ["k", "light_samples"] and list(Soft.PARAMS) == ["k"]
    with pytest.raises(TypeError, match="LIGHT_SAMPLED"):
        class Bad(Technique):
            PARAMS = {"light_samples": Param(1, "mine")}


def test_hard_light_says_light_samples_is_ignored(lab):
    """(e) on a point light, light_samples > 1 renders once, the same image as light_samples=1,
    and the run says so; the param column carries the value asked for."""
    frame = lab.frame("box_on_plane", SIZE)
    one = measure(from_spec("shadow_map"), frame, 0, repeat=1, warmup=0)
    many = measure(from_spec("shadow_map:light_samples=8"), frame, 0, repeat=1, warmup=0)
    assert np.array_equal(one.visibility, many.visibility)
    assert many.notes[0] == "light_samples=8 ignored: light 0 is a point light"
    assert not any("ignored" in n for n in one.notes)
    assert one.stats["light_samples"] == many.stats["light_samples"] == 1
    rows = lab.rows("box_on_plane", ["shadow_map:light_samples=8"], SIZE)
    assert rows["param_light_samples"].tolist() == [8]
    assert "light_samples=8 ignored: light 0 is a point light" in rows["notes"].iloc[0]


def test_stand_in_slots_leave_the_scene_alone(frame):
    """A stand-in slot carries its own light, mask and light list; the scene, its light and the
    area light's own slot are untouched (light sampling never mutates shared state)."""
    area_slot = frame.slot(0)
    area, mask = frame.scene.lights[0], area_slot.evaluated.copy()
    stand_in = PointLight(position=np.array([0.0, -5.0, 0.0]))  # below the floor: sees its underside
    sample = frame.stand_in(area_slot, stand_in)
    assert sample.light is stand_in and sample.index == 0 and sample.stands_in_for is area
    assert sample.scene_lights[0] is stand_in and frame.scene.lights[0] is area
    assert not np.array_equal(sample.evaluated, mask)
    assert frame.slot(0) is area_slot and np.array_equal(frame.compact_evaluated(0), mask)
    with pytest.raises(IndexError):
        frame.slot(1)
